"""Simulated TI IWR1443-like mmWave radar: sparse planar points with Doppler.

One frame: cast ``config.beams`` rays across the azimuth field of view, keep each wall hit
with a probability that falls with range and with the incidence angle (grazing walls are
rarely seen), then add noise, multipath ghosts and clutter. Points are in the radar frame
(x forward, y left, z = 0 exactly).

Points per frame: a target count is drawn from Poisson(mean_points) clipped to
[min_points, max_points] and split into wall / ghost / clutter shares. If more wall beams
fire than wanted, a random subset is kept; if fewer than ``min_points`` fire, more visible
beams are added (like an adaptive CFAR threshold). With no wall within range, the frame has
fewer points than ``min_points``.

Detection probability of a wall hit at range r and incidence angle theta:
``p = detection_max_prob * exp(-(r / detection_range_scale_m)^2) * cos(theta)^incidence_exponent``.

Multipath ghost: the signal bounces specularly off the first wall, reaches a second wall and
returns the same way. The radar places it on the first bearing at range ``r1 + r2``, i.e. at
the mirror image of the second hit behind the first wall. A mirror image of a static wall is
static in the world, so a ghost's Doppler is the static-world Doppler of its bearing.

Clutter: points uniform in bearing and range within the field of view, Doppler drawn from
N(0, clutter_doppler_sigma_mps) (people, fans, interference), low intensity.

Doppler convention: radial velocity of the target relative to the sensor, positive moving
away; for a static target ``doppler = -(v_radar_world · u_world)`` with u the unit bearing.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from smokyslam.config import RadarModelConfig
from smokyslam.sim.raycast2d import RayCaster, RayHits, directions_from_angles
from smokyslam.sim.world import World
from smokyslam.types import RadarScan


class RadarLabel(IntEnum):
    """What produced a simulated radar point."""

    WALL = 0
    GHOST = 1
    CLUTTER = 2


@dataclass
class RadarTruth:
    """Noise-free origin of every point of a simulated scan, indexed like the scan's points.

    labels: (N,) int8 RadarLabel values.
    range_m, azimuth_rad: (N,) noise-free polar position in the radar frame (for clutter,
        the drawn position; for ghosts, the mirror-image position on the first bearing).
    """

    labels: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray


class RadarModel:
    """Simulated radar measuring a World; one verb: ``measure``."""

    def __init__(self, config: RadarModelConfig, world: World) -> None:
        self.config = config
        self.world = world
        self._caster = RayCaster(world)
        half_fov = np.radians(config.fov_deg)
        self._beam_azimuths = np.linspace(-half_fov, half_fov, config.beams)

    def measure(
        self,
        stamp_s: float,
        pose_world_radar: np.ndarray,
        velocity_world_mps: np.ndarray,
        rng: np.random.Generator,
    ) -> RadarScan:
        """One scan from the radar pose ``[x_m, y_m, yaw_rad]`` moving at (2,) world velocity."""
        return self.measure_with_labels(stamp_s, pose_world_radar, velocity_world_mps, rng)[0]

    def measure_with_labels(
        self,
        stamp_s: float,
        pose_world_radar: np.ndarray,
        velocity_world_mps: np.ndarray,
        rng: np.random.Generator,
    ) -> tuple[RadarScan, RadarTruth]:
        """Like :meth:`measure`, plus where each point truly came from (for tests)."""
        cfg = self.config
        pose = np.asarray(pose_world_radar, dtype=float)
        velocity = np.asarray(velocity_world_mps, dtype=float)
        azimuths = self._beam_azimuths
        dirs = directions_from_angles(pose[2] + azimuths)
        hits = self._caster.cast(pose[:2], dirs, cfg.max_range_m)
        ranges = hits.distance_m
        cos_inc = hits.cos_incidence(dirs)
        seen = hits.hit & (ranges >= cfg.min_range_m)
        p_detect = np.where(
            seen,
            cfg.detection_max_prob
            * np.exp(-((ranges / cfg.detection_range_scale_m) ** 2))
            * cos_inc**cfg.incidence_exponent,
            0.0,
        )

        n_total = int(np.clip(rng.poisson(cfg.mean_points), cfg.min_points, cfg.max_points))
        share = [1.0 - cfg.ghost_fraction - cfg.clutter_fraction, cfg.ghost_fraction]
        n_wall, n_ghost, n_clutter = rng.multinomial(n_total, [*share, cfg.clutter_fraction])
        wall_beams = _pick_detections(p_detect, n_wall, cfg.min_points, rng)
        ghost_range, ghost_beams = self._ghosts(pose, dirs, hits, wall_beams, n_ghost, rng)

        clutter_az = rng.uniform(-azimuths[-1], azimuths[-1], n_clutter)
        clutter_range = rng.uniform(cfg.min_range_m, cfg.max_range_m, n_clutter)
        true_range = np.concatenate([ranges[wall_beams], ghost_range, clutter_range])
        true_az = np.concatenate([azimuths[wall_beams], azimuths[ghost_beams], clutter_az])
        labels = np.repeat(
            np.array([RadarLabel.WALL, RadarLabel.GHOST, RadarLabel.CLUTTER], dtype=np.int8),
            [len(wall_beams), len(ghost_beams), n_clutter],
        )

        incidence = np.concatenate(
            [cos_inc[wall_beams], 0.3 * cos_inc[ghost_beams], np.full(n_clutter, 0.1)]
        )
        scan = self._observe(stamp_s, pose, velocity, true_range, true_az, labels, incidence, rng)
        return scan, RadarTruth(labels=labels, range_m=true_range, azimuth_rad=true_az)

    def _observe(
        self,
        stamp_s: float,
        pose: np.ndarray,
        velocity: np.ndarray,
        range_m: np.ndarray,
        azimuth_rad: np.ndarray,
        labels: np.ndarray,
        cos_incidence: np.ndarray,
        rng: np.random.Generator,
    ) -> RadarScan:
        """Noisy points, Doppler and dB-like intensity of true (range, azimuth) returns."""
        cfg = self.config
        n = len(labels)
        static_doppler = -(directions_from_angles(pose[2] + azimuth_rad) @ velocity)
        doppler = np.where(
            labels == RadarLabel.CLUTTER,
            rng.normal(0.0, cfg.clutter_doppler_sigma_mps, n),
            static_doppler + rng.normal(0.0, cfg.doppler_sigma_mps, n),
        )
        meas_range = np.maximum(range_m + rng.normal(0.0, cfg.range_sigma_m, n), 0.0)
        meas_az = azimuth_rad + rng.normal(0.0, np.radians(cfg.azimuth_sigma_deg), n)
        points = np.zeros((n, 3))
        points[:, 0] = meas_range * np.cos(meas_az)
        points[:, 1] = meas_range * np.sin(meas_az)
        intensity = (
            45.0
            - 30.0 * np.log10(np.maximum(range_m, cfg.min_range_m))
            + 10.0 * np.log10(np.maximum(cos_incidence, 1e-3))
            + rng.normal(0.0, 2.0, n)
        )
        return RadarScan(
            stamp_s=float(stamp_s), points_xyz_m=points, intensity=intensity, doppler_mps=doppler
        )

    def _ghosts(
        self,
        pose: np.ndarray,
        dirs: np.ndarray,
        hits: RayHits,
        wall_beams: np.ndarray,
        n_ghost: int,
        rng: np.random.Generator,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Ranges (r1 + r2) and beam indices of up to ``n_ghost`` double-bounce ghosts."""
        if n_ghost == 0 or wall_beams.size == 0:
            return np.zeros(0), np.zeros(0, dtype=np.int64)
        cfg = self.config
        d = dirs[wall_beams]
        normal = hits.normal_xy[wall_beams]
        mirrored = d - 2.0 * np.sum(d * normal, axis=1, keepdims=True) * normal
        # Start just off the face so the bounce does not re-hit the first wall's own cell.
        start = hits.points_xy_m[wall_beams] + 1e-6 * normal
        r1 = hits.distance_m[wall_beams]
        second = self._caster.cast(start, mirrored, cfg.max_range_m)
        total = r1 + second.distance_m
        ok = np.flatnonzero(second.hit & (total <= cfg.max_range_m))
        chosen = rng.permutation(ok)[:n_ghost]
        return total[chosen], wall_beams[chosen]


def _pick_detections(
    p_detect: np.ndarray, n_wanted: int, n_min: int, rng: np.random.Generator
) -> np.ndarray:
    """Beam indices of this frame's wall detections.

    Each beam fires with its probability; when more fire than wanted, a random subset is kept;
    when fewer than ``n_min`` fire (adaptive CFAR threshold), more visible beams are added,
    favouring likely ones.
    """
    fired = np.flatnonzero(rng.uniform(size=p_detect.size) < p_detect)
    if fired.size > n_wanted:
        return np.sort(rng.choice(fired, n_wanted, replace=False))
    missing = min(n_wanted, n_min) - fired.size
    spare = np.flatnonzero(p_detect > 0)
    spare = spare[~np.isin(spare, fired)]
    if missing <= 0 or spare.size == 0:
        return fired
    weights = p_detect[spare] / p_detect[spare].sum()
    extra = rng.choice(spare, min(missing, spare.size), replace=False, p=weights)
    return np.sort(np.concatenate([fired, extra]))
