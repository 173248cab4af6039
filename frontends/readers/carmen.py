"""CARMEN laser logs (``.log``, ``.clf``, plain or gzip) replayed as a radar rig.

The log's ``FLASER`` or ``ROBOTLASER1`` lines (``carmen_parse.py``) give a laser scan and the
(SLAM-corrected) ground-truth pose of ``base_link`` per line.

Timestamps in these logs are often printed at low precision or go backwards, so they do not
drive the run: scan i is stamped ``i / carmen.nominal_rate_hz`` seconds, and all motion
(emulated Doppler and gyro) comes from pose differences. Trajectory files carry the log's own
timestamps where they increase through the whole log (``log_time_s``); where they do not, the
reader says so and files keep the nominal stamps. The logs are keyframe-subsampled: 0.1-0.9 m and
up to 78° between scans, far coarser than a 10 Hz radar.

Per scan, in this order and at one stamp: an :class:`ImuSample` whose gyro z is the emulated
yaw increment since the previous scan divided by the nominal interval (the rate held over that
interval; none for the first scan) and a :class:`RadarScan` (emulated radar points with
Doppler, or every valid beam when emulation is off). The line's pose is the ground truth
(``ground_truth_trajectory()``).

Malformed laser lines are skipped, logged and counted in ``skipped_lines``.
"""

from __future__ import annotations

import logging
from collections.abc import Collection, Iterator
from pathlib import Path

import numpy as np

from smokyslam.config import SmokySlamConfig
from smokyslam.errors import LogError
from smokyslam.frontends.readers.base import LogSummary, StreamSummary
from smokyslam.frontends.readers.carmen_emulation import (
    BeamGeometry,
    beam_bearings,
    detect_no_return,
    emulate_motion,
    emulate_radar_points,
)
from smokyslam.frontends.readers.carmen_parse import read_laser_log
from smokyslam.geometry import se2_compose, se3_from_se2
from smokyslam.types import (
    CameraIntrinsics,
    Extrinsics,
    Frame,
    GroundTruthMap,
    GroundTruthTrajectory,
    ImuSample,
    RadarScan,
)

logger = logging.getLogger(__name__)


class CarmenReader:
    """A CARMEN laser log as a :class:`~smokyslam.frontends.readers.base.LogReader`."""

    def __init__(self, path: Path | str, config: SmokySlamConfig) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise LogError(f"{self.path}: no such log")
        self._config = config
        self._log = read_laser_log(self.path, config.carmen.max_jump_m)
        n_beams = self._log.ranges_m.shape[1]
        bearings = self._log.bearings_rad
        self.beams = BeamGeometry(
            beam_bearings(n_beams) if bearings is None else bearings,
            detect_no_return(self._log.ranges_m),
        )
        self.dt_s = 1.0 / config.carmen.nominal_rate_hz
        self._said_nominal = False
        logger.info(
            "%s: %d %s scans of %d beams, no-return %.2f m",
            self.path,
            len(self._log.ranges_m),
            self._log.kind,
            n_beams,
            self.beams.no_return_m,
        )

    @property
    def skipped_lines(self) -> int:
        """Malformed laser lines that were skipped."""
        return self._log.skipped_lines

    @property
    def radar_mount(self) -> np.ndarray:
        """Planar pose ``[x, y, yaw]`` of the laser (emulated radar) on base_link."""
        return self._log.laser_mount.copy()

    @property
    def stamps_s(self) -> np.ndarray:
        """(S,) nominal scan stamps, seconds."""
        return np.arange(len(self._log.ranges_m)) * self.dt_s

    def log_time_s(self, stamps_s: np.ndarray) -> np.ndarray:
        """The lines' own timestamps (interpolated between lines) when they increase through
        the whole log; otherwise the nominal stamps, and the reader says so once."""
        stamps_s = np.asarray(stamps_s, dtype=float)
        own = self._log.timestamps_s
        steps = np.diff(own)
        if len(own) and np.all(np.isfinite(own)) and np.all(steps > 0):
            return np.interp(stamps_s / self.dt_s, np.arange(len(own)), own)
        if not self._said_nominal:
            self._said_nominal = True
            logger.warning(
                "%s: the log's timestamps do not increase (%d of %d steps); trajectory "
                "files are stamped by scan index at %g Hz",
                self.path,
                int(np.sum(~(steps > 0))),
                len(steps),
                1.0 / self.dt_s,
            )
        return stamps_s

    def summary(self) -> LogSummary:
        count = len(self._log.ranges_m)
        rate = self._config.carmen.nominal_rate_hz
        kind = self._log.kind
        streams = [
            StreamSummary(kind, f"carmen/{kind} as radar", count, rate),
            StreamSummary("gyro (emulated)", "ImuSample", max(count - 1, 0), rate),
            StreamSummary(f"{kind} pose", "ground-truth pose", count, rate),
        ]
        return LogSummary(self.path, "carmen", (count - 1) * self.dt_s, 0.0, streams)

    def frames(self, streams: Collection[str] | None = None) -> Iterator[Frame]:
        """Gyro sample and radar scan per laser line (same seed, same frames on every
        call). ``streams`` is accepted for the protocol; both are always emulated (the
        emulation draws them from one random stream)."""
        config = self._config
        rng = np.random.default_rng(config.carmen.seed)
        poses_base = self._log.poses_world_base
        poses_sensor = se2_compose(poses_base, self.radar_mount)
        motion = emulate_motion(poses_sensor, self.dt_s, config.carmen, rng)
        for i, stamp_s in enumerate(self.stamps_s):
            if i > 0:
                gyro = np.array([0.0, 0.0, motion.gyro_yaw_rad[i] / self.dt_s])
                yield ImuSample(float(stamp_s), gyro, np.zeros(3))
            points, doppler = emulate_radar_points(
                self._log.ranges_m[i],
                self.beams,
                motion.velocity_mps[i],
                config.simulation.radar,
                config.carmen,
                rng,
            )
            yield RadarScan(float(stamp_s), points, np.ones(len(points)), doppler)

    def ground_truth_trajectory(self) -> GroundTruthTrajectory | None:
        """The laser lines' poses at the scans' nominal stamps."""
        return GroundTruthTrajectory(self.stamps_s, self._log.poses_world_base.copy())

    def ground_truth_map(self) -> GroundTruthMap | None:
        return None

    def observed_ground_truth_map(self) -> GroundTruthMap | None:
        return None

    def extrinsics(self) -> Extrinsics:
        return Extrinsics(T_base_radar=se3_from_se2(self.radar_mount))

    def camera_intrinsics(self) -> CameraIntrinsics | None:
        return None

    def problems(self) -> dict[str, object]:
        return {"skipped_lines": self.skipped_lines} if self.skipped_lines else {}
