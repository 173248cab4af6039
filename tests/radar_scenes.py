"""Small exact scenes for the radar odometry tests: a room of wall segments, ray-cast radar
frames with Doppler, and a gyro."""

from __future__ import annotations

import numpy as np

from smokyslam.frontends.readers.carmen_emulation import beam_bearings
from smokyslam.geometry import se2_between, se2_log, transform_points_2d
from smokyslam.types import ImuSample, RadarScan

# A 14 x 10 m room with a few boxes and a partition, as (S, 4) segments [x0, y0, x1, y1].
_ROOM = [(0, 0, 14, 0), (14, 0, 14, 10), (14, 10, 0, 10), (0, 10, 0, 0)]
_BOXES = [(2, 8, 3, 9), (9, 0.5, 10.5, 1.5), (11.5, 8, 12.5, 9)]
_PARTITION = [(6, 0, 6, 2), (7.5, 10, 7.5, 8.2)]


def room_segments() -> np.ndarray:
    segments = list(_ROOM) + list(_PARTITION)
    for x0, y0, x1, y1 in _BOXES:
        segments += [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]
    return np.array(segments, dtype=float)


def cast(pose: np.ndarray, bearings: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """(N,) ranges from ``pose`` along sensor bearings to the nearest segment (inf if none)."""
    angle = pose[2] + bearings
    d = np.stack([np.cos(angle), np.sin(angle)], axis=1)[:, None, :]  # (N, 1, 2)
    a, b = segments[None, :, :2], segments[None, :, 2:]
    e = b - a
    w = a - pose[:2]
    denom = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / denom
        u = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / denom
    hit = (np.abs(denom) > 1e-12) & (t > 1e-6) & (u >= 0) & (u <= 1)
    return np.where(hit, t, np.inf).min(axis=1)


def radar_points(
    pose: np.ndarray,
    rng: np.random.Generator,
    n: int = 40,
    range_sigma_m: float = 0.02,
    azimuth_sigma_deg: float = 0.5,
    fov_deg: float = 60.0,
) -> tuple[np.ndarray, np.ndarray]:
    """(M, 2) noisy sensor-frame points and their (M,) true bearings."""
    bearings = rng.uniform(-np.radians(fov_deg), np.radians(fov_deg), n)
    ranges = cast(pose, bearings, room_segments())
    ok = np.isfinite(ranges) & (ranges < 12.0)
    bearings, ranges = bearings[ok], ranges[ok] + range_sigma_m * rng.normal(size=ok.sum())
    measured = bearings + np.radians(azimuth_sigma_deg) * rng.normal(size=len(bearings))
    return np.stack([ranges * np.cos(measured), ranges * np.sin(measured)], axis=1), bearings


def dense_map_points(pose: np.ndarray) -> np.ndarray:
    """(M, 2) world points of a noise-free 360° scan, 0.5° apart."""
    bearings = np.radians(np.arange(-180.0, 180.0, 0.5))
    ranges = cast(pose, bearings, room_segments())
    ok = np.isfinite(ranges)
    local = np.stack([ranges[ok] * np.cos(bearings[ok]), ranges[ok] * np.sin(bearings[ok])], 1)
    return transform_points_2d(pose, local)


def loop_path(n: int, dt_s: float) -> np.ndarray:
    """(n, 3) sensor poses on an ellipse inside the room (about 20 m around), one every
    ``dt_s`` at about 0.8 m/s."""
    phase = 2.0 * np.pi * np.arange(n) * dt_s * 0.8 / 20.0
    x = 7.0 + 4.0 * np.cos(phase - np.pi / 2)
    y = 5.0 + 2.4 * np.sin(phase - np.pi / 2)
    yaw = np.arctan2(np.gradient(y), np.gradient(x))
    return np.column_stack([x, y, yaw])


def radar_log(
    poses: np.ndarray,
    dt_s: float,
    rng: np.random.Generator,
    gyro_bias_radps: float = 0.02,
    gyro_noise_radps: float = 0.01,
    doppler_sigma_mps: float = 0.05,
    outlier_fraction: float = 0.1,
) -> list[tuple[RadarScan, list[ImuSample]]]:
    """Radar frames (with Doppler of a constant-twist step and some moving-object outliers)
    and, per frame, one gyro sample holding the step's mean rate plus bias and noise."""
    frames = []
    for i, pose in enumerate(poses):
        points, bearings = radar_points(pose, rng)
        twist = np.zeros(3) if i == 0 else se2_log(se2_between(poses[i - 1], pose))
        velocity = twist[:2] / dt_s
        directions = np.stack([np.cos(bearings), np.sin(bearings)], axis=1)
        doppler = -directions @ velocity + doppler_sigma_mps * rng.normal(size=len(bearings))
        movers = rng.random(len(bearings)) < outlier_fraction
        doppler[movers] += rng.uniform(-2.0, 2.0, movers.sum())
        xyz = np.column_stack([points, np.zeros(len(points))])
        scan = RadarScan(i * dt_s, xyz, np.ones(len(points)), doppler)
        imu = []
        if i > 0:
            rate = twist[2] / dt_s + gyro_bias_radps + gyro_noise_radps * rng.normal()
            imu = [ImuSample(i * dt_s, np.array([0.0, 0.0, rate]), np.zeros(3))]
        frames.append((scan, imu))
    return frames


# ---------------------------------------------------------------- CARMEN logs

NO_RETURN = 81.83
ROOM_M = (12.0, 8.0)


def box_ranges(pose: np.ndarray, bearings: np.ndarray) -> np.ndarray:
    """Ranges from ``pose`` to the walls of the CARMEN test room [0, 12] x [0, 8]."""
    angle = pose[2] + bearings
    d = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    with np.errstate(divide="ignore"):
        tx = np.where(d[:, 0] > 0, ROOM_M[0] - pose[0], -pose[0]) / d[:, 0]
        ty = np.where(d[:, 1] > 0, ROOM_M[1] - pose[1], -pose[1]) / d[:, 1]
    return np.minimum(np.abs(tx), np.abs(ty))


def carmen_poses(n: int = 12) -> np.ndarray:
    """A circle of radius 2.5 m around the room's centre, 0.5 m and 11.5 degrees per scan
    (yaw unwrapped)."""
    yaw = 0.1 + 0.2 * np.arange(n)
    xy = np.array([6.0, 1.5]) + np.cumsum(0.5 * np.stack([np.cos(yaw), np.sin(yaw)], 1), 0)
    return np.column_stack([xy, yaw])


def _flaser(ranges: np.ndarray, pose: np.ndarray, stamp: float) -> str:
    values = " ".join(f"{r:.3f}" for r in ranges)
    pose_text = " ".join(f"{v:.6f}" for v in pose)
    return f"FLASER {len(ranges)} {values} {pose_text} {pose_text} {stamp:.2f} host {stamp:.2f}"


def write_carmen_log(path, poses, n_beams=180, malformed=True, opener=open):
    bearings = beam_bearings(n_beams)
    lines = ["# CARMEN log", "PARAM robot_frontlaser_offset 0.0 nohost 0", ""]
    for i, pose in enumerate(poses):
        ranges = box_ranges(pose, bearings)
        ranges[::17] = NO_RETURN  # a few beams see nothing in every scan
        lines.append("ODOM 0 0 0 0 0 0 0 host 0")
        # Irregular timestamps (0, 2, 4, 15, 17, ...): the run keeps its nominal rate; only
        # the trajectory files carry them.
        lines.append(_flaser(ranges, pose, stamp=5.0 * i - 3.0 * (i % 3)))
    if malformed:
        good = lines[4]
        lines[5:5] = [
            "FLASER 180 1.0 2.0 3.0",  # truncated
            good.replace("FLASER 180", "FLASER abc"),  # bad beam count
            good.rsplit(" ", 9)[0] + " nan 0 0 0 0 0 1.0 host 1.0",  # NaN pose
            _flaser(np.ones(360), poses[0], 0.0),  # beam count differs from the log's
        ]
    with opener(path, "wt") as stream:
        stream.write("\n".join(lines) + "\n")
    return path
