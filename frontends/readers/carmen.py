"""CARMEN laser logs (``.log`` / ``.log.gz``) replayed as a radar rig.

``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp [host logger_timestamp]``:
n beams over 180° (180 at 1°, 360/361 at 0.5°, derived from n), the first looking right.
The ``x y theta`` pose on each line is the (SLAM-corrected) ground truth of ``base_link``.

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

Malformed ``FLASER`` lines are skipped, logged and counted in ``skipped_lines``. Other message
types (``ODOM``, ``PARAM``, ``NEFF``...) are ignored, except ``PARAM robot_frontlaser_offset``,
the laser's forward offset on the robot.
"""

from __future__ import annotations

import gzip
import logging
import zlib
from collections.abc import Collection, Iterator
from dataclasses import dataclass
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


@dataclass
class LaserLog:
    """The ``FLASER`` records of one log, all with the same beam count n.

    ranges_m: (S, n) metres. poses_world_base: (S, 3) [x, y, theta]. timestamps_s: (S,) the
    lines' own timestamps (NaN where unreadable). laser_offset_m: forward offset of the laser
    on the robot. skipped_lines: malformed ``FLASER`` lines.
    """

    ranges_m: np.ndarray
    poses_world_base: np.ndarray
    timestamps_s: np.ndarray
    laser_offset_m: float
    skipped_lines: int


def _parse_flaser(tokens: list[str]) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Ranges (n,), pose (3,) and timestamp (NaN if unreadable) of one split ``FLASER`` line,
    or None when malformed."""
    try:
        n = int(tokens[1])
        if n <= 0 or len(tokens) < 2 + n + 7:
            return None
        values = np.array(tokens[2 : 2 + n + 3], dtype=float)
    except (ValueError, IndexError):
        return None
    if not np.all(np.isfinite(values)):
        return None
    return values[:n], values[n:], _float_or(tokens[2 + n + 6], float("nan"))


MAX_RANGE_M = 1000.0
"""Beams longer than this (or negative) are no laser's reading: counted and left out."""


def read_laser_log(path: Path, max_jump_m: float) -> LaserLog:
    """Parse every ``FLASER`` line of a CARMEN log (plain or gzip text).

    The beam count is the one most lines have (a damaged first line cannot decide it); lines
    with another count are skipped. Beams beyond ``MAX_RANGE_M`` or negative read as no
    return; a line of only such beams is dropped, and so is a line whose pose jumps more than
    ``max_jump_m`` from the line before while the line after it does not (a single absurd
    pose). All are counted and warned.
    """
    opener = gzip.open if path.suffix == ".gz" else open
    ranges, poses, times, skipped, offset = [], [], [], 0, 0.0
    try:
        with opener(path, "rt", errors="replace") as stream:
            for number, line in enumerate(stream, start=1):
                tokens = line.split()
                if not tokens or tokens[0] not in ("FLASER", "PARAM"):
                    continue
                if tokens[0] == "PARAM":
                    if len(tokens) >= 3 and tokens[1] == "robot_frontlaser_offset":
                        offset = _float_or(tokens[2], offset)
                    continue
                record = _parse_flaser(tokens)
                if record is None:
                    skipped += 1
                    logger.debug("%s:%d: malformed FLASER line skipped", path, number)
                    continue
                ranges.append(record[0])
                poses.append(record[1])
                times.append(record[2])
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise LogError(f"{path}: cannot read CARMEN log ({exc})") from None
    if not ranges:
        raise LogError(f"{path}: no FLASER lines")
    sizes, counts = np.unique([r.size for r in ranges], return_counts=True)
    n_beams = int(sizes[np.argmax(counts)])
    same = [i for i, r in enumerate(ranges) if r.size == n_beams]
    skipped += len(ranges) - len(same)
    ranges_m = np.array([ranges[i] for i in same])
    poses_m = np.array([poses[i] for i in same])
    times_s = np.array([times[i] for i in same])
    absurd = (ranges_m < 0.0) | (ranges_m > MAX_RANGE_M)
    ranges_m[absurd] = np.inf
    keep = _without_pose_spikes(poses_m, max_jump_m) & ~absurd.all(axis=1)
    if skipped:
        logger.warning("%s: skipped %d malformed FLASER lines", path, skipped)
    if absurd.any():
        logger.warning(
            "%s: %d beams out of range (< 0 or > %g m) left out", path, absurd.sum(), MAX_RANGE_M
        )
    if not keep.all():
        logger.warning(
            "%s: %d lines with no usable beam or a pose jumping more than %g m and back dropped",
            path,
            (~keep).sum(),
            max_jump_m,
        )
    return LaserLog(
        ranges_m[keep], poses_m[keep], times_s[keep], offset, skipped + int((~keep).sum())
    )


def _without_pose_spikes(poses: np.ndarray, max_jump_m: float) -> np.ndarray:
    """(S,) bool: lines kept. A line is dropped when it is further than ``max_jump_m`` from
    the last kept line but the line after it is not (the walk did not really go there)."""
    keep = np.ones(len(poses), dtype=bool)
    last = 0
    for i in range(1, len(poses)):  # sequential by nature: one test per line
        jump = np.hypot(*(poses[i, :2] - poses[last, :2]))
        back = i + 1 < len(poses) and np.hypot(*(poses[i + 1, :2] - poses[last, :2])) <= max_jump_m
        if jump > max_jump_m and back:
            keep[i] = False
        else:
            last = i
    return keep


def _float_or(token: str, default: float) -> float:
    try:
        return float(token)
    except ValueError:
        return default


class CarmenReader:
    """A CARMEN laser log as a :class:`~smokyslam.frontends.readers.base.LogReader`."""

    def __init__(self, path: Path | str, config: SmokySlamConfig) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise LogError(f"{self.path}: no such log")
        self._config = config
        self._log = read_laser_log(self.path, config.carmen.max_jump_m)
        n_beams = self._log.ranges_m.shape[1]
        self.beams = BeamGeometry(beam_bearings(n_beams), detect_no_return(self._log.ranges_m))
        self.dt_s = 1.0 / config.carmen.nominal_rate_hz
        self._said_nominal = False
        logger.info(
            "%s: %d scans of %d beams, no-return %.2f m",
            self.path,
            len(self._log.ranges_m),
            n_beams,
            self.beams.no_return_m,
        )

    @property
    def skipped_lines(self) -> int:
        """Malformed ``FLASER`` lines that were skipped."""
        return self._log.skipped_lines

    @property
    def radar_mount(self) -> np.ndarray:
        """Planar pose ``[x, y, yaw]`` of the laser (emulated radar) on base_link."""
        return np.array([self._log.laser_offset_m, 0.0, 0.0])

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
        streams = [
            StreamSummary("FLASER", "carmen/FLASER as radar", count, rate),
            StreamSummary("gyro (emulated)", "ImuSample", max(count - 1, 0), rate),
            StreamSummary("FLASER pose", "ground-truth pose", count, rate),
        ]
        return LogSummary(self.path, "carmen", (count - 1) * self.dt_s, 0.0, streams)

    def frames(self, streams: Collection[str] | None = None) -> Iterator[Frame]:
        """Gyro sample and radar scan per ``FLASER`` line (same seed, same frames on every
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
        """The ``FLASER`` lines' poses at the scans' nominal stamps."""
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
