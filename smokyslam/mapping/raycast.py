"""Bresenham ray casting on integer grid cells: a vectorized caster and a per-ray reference.

Both casters trace exactly the same cells. A ray from cell ``o`` to cell ``e`` (``d = e - o``)
takes ``n = max(|dx|, |dy|)`` steps; at step ``i`` it visits the cell nearest to
``o + i * d / n``, with halves rounded towards +infinity: ``o + floor((2 i d + n) / (2 n))``
per axis. The free cells of a ray are steps ``0 .. n-1`` (the origin cell included, the
endpoint cell excluded); the endpoint cell holds the return. A max-range ray (nothing was
hit within range) carries its free cells only. A zero-length ray has no free cells and,
unless it is max-range, hits its own origin cell.
"""

from __future__ import annotations

import numpy as np

# Fixed-point arithmetic of the vectorized caster: FRAC fractional bits, exact integer maths.
# The per-step slope error is below 2**-FRAC cells, so with a nudge of 2**-20 cells every
# rounding is exact for rays shorter than 2**18 cells; spans below 2**21 cells avoid overflow.
_FRAC = 40
_HALF_PLUS_NUDGE = (1 << (_FRAC - 1)) + (1 << (_FRAC - 20))
_MAX_RAY_CELLS = 1 << 18
_MAX_SPAN_CELLS = 1 << 21
_CHUNK_CELLS = 1 << 16  # cells traced per vectorized pass: 1 MiB of output stays in cache


def _as_rays(
    origin_cells_ixy: np.ndarray, end_cells_ixy: np.ndarray, max_range: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    ends = np.asarray(end_cells_ixy, dtype=np.int64).reshape(-1, 2)
    origins = np.broadcast_to(np.asarray(origin_cells_ixy, dtype=np.int64), ends.shape)
    if max_range is None:
        hit = np.ones(len(ends), dtype=bool)
    else:
        hit = ~np.asarray(max_range, dtype=bool).reshape(len(ends))
    return origins, ends, hit


def ray_lengths(origin_cells_ixy: np.ndarray, end_cells_ixy: np.ndarray) -> np.ndarray:
    """(N,) int64: number of free cells each ray traces (its Chebyshev length in cells)."""
    ends = np.asarray(end_cells_ixy, dtype=np.int64).reshape(-1, 2)
    return np.abs(ends - np.asarray(origin_cells_ixy, dtype=np.int64)).max(axis=1)


def _trace_chunk(
    origins: np.ndarray, delta: np.ndarray, steps: np.ndarray, out: np.ndarray
) -> None:
    """Write the ``sum(steps)`` free cells of rays into ``out``, an (M, 2) int64 block."""
    n = np.maximum(steps, 1)[:, None]
    slope = ((delta << _FRAC) + np.sign(delta) * (n >> 1)) // n  # d / n, rounded, fixed point
    first = np.cumsum(steps) - steps
    # Cell k of the chunk sits at floor(k * slope + offset) on each axis of its ray. The maths
    # runs on flat (2M,) views: numpy is slow at broadcasting over a trailing axis of 2.
    offset = (origins << _FRAC) + _HALF_PLUS_NUDGE - first[:, None] * slope
    flat = out.reshape(-1)
    index = np.arange(len(flat), dtype=np.int64)
    index >>= 1
    np.multiply(np.repeat(slope, steps, axis=0).reshape(-1), index, out=flat)
    flat += np.repeat(offset, steps, axis=0).reshape(-1)
    flat >>= _FRAC


def raycast(
    origin_cells_ixy: np.ndarray,
    end_cells_ixy: np.ndarray,
    max_range: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Trace many rays at once, with no Python loop over rays or cells.

    origin_cells_ixy: (2,) or (N, 2) int cells ``[ix, iy]`` the rays start from.
    end_cells_ixy: (N, 2) int cells ``[ix, iy]`` of the returns.
    max_range: (N,) bool, True for rays that hit nothing (free space only); None = all hit.
    Returns ``(free_cells, hit_cells)``: (M, 2) and (K, 2) int64 ``[ix, iy]``, in ray order
    and, within a ray, from the origin outwards. Cells repeat when rays overlap.
    Rays must be shorter than 2**18 cells and one call must span fewer than 2**21 cells.
    """
    origins, ends, hit = _as_rays(origin_cells_ixy, end_cells_ixy, max_range)
    if len(ends) == 0:
        return np.zeros((0, 2), dtype=np.int64), ends.copy()
    # Far from cell 0 the fixed-point maths would overflow: work relative to a corner there.
    corner = np.zeros(2, dtype=np.int64)
    if max(np.abs(origins).max(), np.abs(ends).max()) >= _MAX_SPAN_CELLS // 2:
        corner = np.minimum(origins.min(axis=0), ends.min(axis=0))
        span = np.maximum(origins.max(axis=0), ends.max(axis=0)) - corner
        if span.max() >= _MAX_SPAN_CELLS:
            raise ValueError(f"rays span {span.max()} cells; at most {_MAX_SPAN_CELLS - 1}")
    local_origins = origins - corner
    delta = ends - origins
    steps = np.abs(delta).max(axis=1)
    if steps.max() >= _MAX_RAY_CELLS:
        raise ValueError(f"a ray has {steps.max()} cells; at most {_MAX_RAY_CELLS - 1} allowed")

    # Chunks of about _CHUNK_CELLS traced cells stay in cache (a loop over chunks only).
    cumulative = np.cumsum(steps)
    total = int(cumulative[-1])
    free = np.empty((total, 2), dtype=np.int64)
    if total <= _CHUNK_CELLS:
        _trace_chunk(local_origins, delta, steps, free)
    else:
        splits = np.searchsorted(cumulative, np.arange(_CHUNK_CELLS, total, _CHUNK_CELLS))
        rays = np.unique(np.concatenate([[0], splits + 1, [len(ends)]]).clip(0, len(ends)))
        cells = np.concatenate([[0], cumulative])[rays]
        for a, b, c0, c1 in zip(rays[:-1], rays[1:], cells[:-1], cells[1:], strict=True):
            _trace_chunk(local_origins[a:b], delta[a:b], steps[a:b], free[c0:c1])
    if np.any(corner):
        free += corner
    return free, ends[hit].copy()


def naive_raycast(
    origin_cells_ixy: np.ndarray,
    end_cells_ixy: np.ndarray,
    max_range: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Reference caster: the textbook incremental Bresenham, one Python loop per ray and cell.

    Same arguments and result as :func:`raycast`; it is the brute-force check in tests and
    the baseline of the ray-casting benchmark (what a per-ray pure-Python mapper does).
    """
    origins, ends, hit = _as_rays(origin_cells_ixy, end_cells_ixy, max_range)
    free: list[tuple[int, int]] = []
    for (x0, y0), (x1, y1) in zip(origins.tolist(), ends.tolist(), strict=True):
        dx, dy = abs(x1 - x0), abs(y1 - y0)
        sx = 1 if x1 > x0 else -1
        sy = 1 if y1 > y0 else -1
        x, y = x0, y0
        if dx >= dy:
            err, threshold = 2 * dy - dx, 0 if sy > 0 else 1  # ties step towards +infinity
            for _ in range(dx):
                free.append((x, y))
                if err >= threshold:
                    y += sy
                    err -= 2 * dx
                err += 2 * dy
                x += sx
        else:
            err, threshold = 2 * dx - dy, 0 if sx > 0 else 1
            for _ in range(dy):
                free.append((x, y))
                if err >= threshold:
                    x += sx
                    err -= 2 * dy
                err += 2 * dx
                y += sy
    free_cells = np.array(free, dtype=np.int64).reshape(-1, 2)
    return free_cells, ends[hit].copy()
