"""Parsing CARMEN laser logs (``.log``, ``.clf``, plain or gzip) into one array per quantity.

Two kinds of laser line carry a scan and the pose it was taken at:

- ``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta timestamp [host logger_timestamp]``:
  n beams over 180° (the bearings follow from n, ``carmen_emulation.beam_bearings``); the
  ``x y theta`` pose is that of the robot (base_link); the laser sits ``PARAM
  robot_frontlaser_offset`` metres ahead of it.
- ``ROBOTLASER1 type start_angle fov resolution max_range accuracy remission_mode n r_1 .. r_n
  m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y robot_theta tv rv forward_safety
  side_safety turn_axis timestamp [host logger_timestamp]``: the newer format, with its own
  bearings (``start_angle + i * resolution``) and the laser's pose beside the robot's, which
  give the laser's mount on the robot.

A log is read as the kind most of its lines are (a log may repeat its scans in both). Other
lines (``ODOM``, ``RAWLASER``, ``NEFF``...) are ignored. In a corrected log the poses are the
SLAM-corrected ground truth.
"""

from __future__ import annotations

import gzip
import logging
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from smokyslam.errors import LogError
from smokyslam.geometry import se2_between, wrap_angle

logger = logging.getLogger(__name__)

MAX_RANGE_M = 1000.0
"""Beams longer than this (or negative) are no laser's reading: counted and left out."""


@dataclass
class LaserLog:
    """The laser lines of one log, all of one kind and with the same beam count n.

    ranges_m: (S, n) metres. poses_world_base: (S, 3) [x, y, theta]. timestamps_s: (S,) the
    lines' own timestamps (NaN where unreadable). laser_mount: (3,) [x, y, yaw] of the laser on
    base_link. bearings_rad: (n,) the beams' bearings where the lines give them
    (``ROBOTLASER1``), None where they follow from n (``FLASER``). skipped_lines: malformed
    laser lines. kind: the lines' kind.
    """

    ranges_m: np.ndarray
    poses_world_base: np.ndarray
    timestamps_s: np.ndarray
    laser_mount: np.ndarray
    bearings_rad: np.ndarray | None
    skipped_lines: int
    kind: str


@dataclass(frozen=True)
class _Record:
    ranges: np.ndarray  # (n,)
    pose: np.ndarray  # (3,) robot
    stamp: float
    laser_pose: np.ndarray | None = None  # (3,) ROBOTLASER1 only
    fan: tuple[float, float] | None = None  # (start, resolution) rad, ROBOTLASER1 only


def _float_or(token: str, default: float) -> float:
    try:
        return float(token)
    except ValueError:
        return default


def _parse_flaser(tokens: list[str]) -> _Record | None:
    """One split ``FLASER`` line (module docstring; its timestamp NaN if unreadable), or None
    when malformed."""
    try:
        n = int(tokens[1])
        if n <= 0 or len(tokens) < 2 + n + 7:
            return None
        values = np.array(tokens[2 : 2 + n + 3], dtype=float)
    except (ValueError, IndexError):
        return None
    if not np.all(np.isfinite(values)):
        return None
    return _Record(values[:n], values[n:], _float_or(tokens[2 + n + 6], float("nan")))


def _parse_robotlaser(tokens: list[str]) -> _Record | None:
    """One split ``ROBOTLASER1`` line (module docstring), or None when malformed."""
    try:
        fan = np.array(tokens[2:5], dtype=float)  # start, fov, resolution
        n = int(tokens[8])
        if n <= 0 or len(tokens) < 9 + n + 1:
            return None
        m = int(tokens[9 + n])
        tail = 10 + n + m  # laser pose, robot pose, 5 values, timestamp
        if m < 0 or len(tokens) < tail + 12:
            return None
        ranges = np.array(tokens[9 : 9 + n], dtype=float)
        poses = np.array(tokens[tail : tail + 6], dtype=float)
    except (ValueError, IndexError):
        return None
    if not (np.all(np.isfinite(ranges)) and np.all(np.isfinite(poses)) and np.isfinite(fan).all()):
        return None
    if fan[2] <= 0.0:
        return None
    stamp = _float_or(tokens[tail + 11], float("nan"))
    return _Record(ranges, poses[3:], stamp, poses[:3], (float(fan[0]), float(fan[2])))


PARSERS = {"FLASER": _parse_flaser, "ROBOTLASER1": _parse_robotlaser}
"""The laser lines a log is read from, by kind (``FLASER`` first: it wins a tie)."""


def _read_records(path: Path) -> tuple[dict[str, list[_Record]], dict[str, int], float]:
    """Every laser line of ``path`` by kind, the malformed ones counted by kind, and the
    front laser offset (``PARAM robot_frontlaser_offset``, 0 when absent)."""
    opener = gzip.open if path.suffix == ".gz" else open
    records: dict[str, list[_Record]] = {kind: [] for kind in PARSERS}
    skipped = dict.fromkeys(PARSERS, 0)
    offset = 0.0
    try:
        with opener(path, "rt", errors="replace") as stream:
            for number, line in enumerate(stream, start=1):
                tokens = line.split()
                if not tokens:
                    continue
                kind = tokens[0]
                if kind == "PARAM":
                    if len(tokens) >= 3 and tokens[1] == "robot_frontlaser_offset":
                        offset = _float_or(tokens[2], offset)
                    continue
                if kind not in PARSERS:
                    continue
                record = PARSERS[kind](tokens)
                if record is None:
                    skipped[kind] += 1
                    logger.debug("%s:%d: malformed %s line skipped", path, number, kind)
                else:
                    records[kind].append(record)
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error) as exc:
        raise LogError(f"{path}: cannot read CARMEN log ({exc})") from None
    return records, skipped, offset


def _laser_mount(records: list[_Record], front_offset_m: float) -> np.ndarray:
    """The laser's [x, y, yaw] on base_link: over ``ROBOTLASER1`` lines, the median position
    and the circular mean yaw of the laser pose in the robot's frame; ``FLASER`` lines: the
    front offset."""
    if records[0].laser_pose is None:
        return np.array([front_offset_m, 0.0, 0.0])
    robot = np.array([r.pose for r in records])
    laser = np.array([r.laser_pose for r in records])
    relative = se2_between(robot, laser)
    x, y = np.median(relative[:, :2], axis=0)
    yaw = np.arctan2(np.sin(relative[:, 2]).mean(), np.cos(relative[:, 2]).mean())
    return np.array([x, y, yaw])


def read_laser_log(path: Path, max_jump_m: float) -> LaserLog:
    """Parse the laser lines of a CARMEN log (plain or gzip text).

    The kind read is the one with the most lines (``FLASER`` on a tie). The beam count is the
    one most of its lines have (a damaged first line cannot decide it); lines with another
    count are skipped. Beams beyond ``MAX_RANGE_M`` or negative read as no return; a line of
    only such beams is dropped, and so is a line whose pose jumps more than ``max_jump_m``
    from the line before while the line after it does not (a single absurd pose). All are
    counted and warned.
    """
    by_kind, malformed, front_offset_m = _read_records(path)
    kind = max(PARSERS, key=lambda k: len(by_kind[k]))  # the first kind wins a tie
    records = by_kind[kind]
    if not records:
        raise LogError(f"{path}: no FLASER or ROBOTLASER1 lines")
    skipped = malformed[kind]
    sizes, counts = np.unique([r.ranges.size for r in records], return_counts=True)
    n_beams = int(sizes[np.argmax(counts)])
    same = [r for r in records if r.ranges.size == n_beams]
    skipped += len(records) - len(same)
    ranges_m = np.array([r.ranges for r in same])
    poses_m = np.array([r.pose for r in same])
    times_s = np.array([r.stamp for r in same])
    bearings = None
    if same[0].fan is not None:
        start, resolution = same[0].fan
        bearings = wrap_angle(start + resolution * np.arange(n_beams))
    absurd = (ranges_m < 0.0) | (ranges_m > MAX_RANGE_M)
    ranges_m[absurd] = np.inf
    keep = _without_pose_spikes(poses_m, max_jump_m) & ~absurd.all(axis=1)
    if skipped:
        logger.warning("%s: skipped %d malformed %s lines", path, skipped, kind)
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
        ranges_m[keep],
        poses_m[keep],
        times_s[keep],
        _laser_mount(same, front_offset_m),
        bearings,
        skipped + int((~keep).sum()),
        kind,
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
