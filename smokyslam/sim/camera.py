"""Simulated forward-looking mono camera: a textured 2.5D ray caster (Wolfenstein style).

The camera looks horizontally from ``camera_height_m`` above the floor. Each image column
casts one 2D ray through the World's grid; walls are ``world.wall_height_m`` tall columns,
floor and ceiling pixels are found by intersecting the pixel ray with their planes.

Pixel convention (OpenCV): integer pixel coordinates (u, v) are pixel centres, so the
principal point of a centred camera is ``cx = (width - 1) / 2``, ``cy = (height - 1) / 2``.

Textures are a pure function of the world point and the seed, so a wall corner looks the
same from every viewpoint and features track between frames:
- walls: staggered 0.30 x 0.15 m bricks with a random grey each, dark mortar and a fine 5 cm
  grain, plus posters (grids of random grey blocks) on half of the 1.6 m wall panels; keyed
  by the face line (grid line, axis, facing side), the position along the wall and the height;
- floor: 0.5 m tiles of random grey with dark grout; ceiling: 0.6 m tiles, some of them lamps.
Fine detail fades to the mean grey with distance, standing in for mip-mapping, so far surfaces
do not alias into flicker. Each pixel averages ``supersample`` x ``supersample`` samples (a box
filter over the pixel's footprint): point samples at pixel centres snap texture edges to the
pixel grid, which biases sub-pixel feature tracking towards zero motion. A 3x3 Gaussian blur
then stands in for the lens.
"""

from __future__ import annotations

import cv2
import numpy as np

from smokyslam.config import CameraModelConfig
from smokyslam.errors import ConfigError
from smokyslam.sim.raycast2d import RayCaster, RayHits
from smokyslam.sim.world import World
from smokyslam.types import CameraIntrinsics

MAX_RANGE_M = 60.0
BRICK_W_M, BRICK_H_M, MORTAR_M, GRAIN_M = 0.30, 0.15, 0.02, 0.05
PANEL_W_M, POSTER_BOTTOM_M, POSTER_TOP_M = 1.6, 0.9, 1.8
FLOOR_TILE_M, CEILING_TILE_M, GROUT_M = 0.5, 0.6, 0.02
FLOOR_GREY, CEILING_GREY, LAMP_GREY = 115.0, 180.0, 245.0
_TABLE_SIZE = 4096
_PRIMES = (73856093, 19349663, 83492791, 2654435761)


def _hash(seed_mix: int, *keys: np.ndarray) -> np.ndarray:
    """Integer hash of integer-valued key arrays (broadcast), as indices into a random table."""
    h = np.int64(seed_mix)
    for key, prime in zip(keys, _PRIMES, strict=False):
        h = h ^ (np.asarray(key).astype(np.int64) * prime)
    h = h ^ (h >> 15)
    h = h * 0x2C1B3C6D
    h = h ^ (h >> 12)
    return h & (_TABLE_SIZE - 1)


def _fade(z_m: np.ndarray, near_m: float, far_m: float) -> np.ndarray:
    """Texture contrast weight: 1 up to ``near_m``, 0 beyond ``far_m``, linear in between."""
    return np.clip((far_m - z_m) / (far_m - near_m), 0.0, 1.0).astype(np.float32)


class CameraRenderer:
    """Renders mono images and optical-axis depth of a World from planar camera poses."""

    def __init__(
        self, world: World, config: CameraModelConfig, camera_height_m: float, seed: int
    ) -> None:
        if not 0.0 < camera_height_m < world.wall_height_m:
            raise ConfigError(
                f"camera height {camera_height_m} m must lie between the floor and the "
                f"ceiling ({world.wall_height_m} m)"
            )
        self.world = world
        self.config = config
        self.camera_height_m = camera_height_m
        self._caster = RayCaster(world)
        self.intrinsics = CameraIntrinsics(
            width=config.width,
            height=config.height,
            fx=config.fx,
            fy=config.fy,
            cx=(config.width - 1) / 2.0,
            cy=(config.height - 1) / 2.0,
        )
        # Internal sample grid: k x k samples per pixel, centred on the pixel's footprint.
        self._k = k = config.supersample
        w, h = config.width * k, config.height * k
        fx, fy, cx, cy = config.fx * k, config.fy * k, (w - 1) / 2.0, (h - 1) / 2.0
        rng = np.random.default_rng(seed)
        self._seed_mix = int(rng.integers(0, 2**31))
        self._grey = rng.uniform(40.0, 220.0, _TABLE_SIZE).astype(np.float32)
        self._uniform = rng.uniform(0.0, 1.0, _TABLE_SIZE).astype(np.float32)
        self._noise_rng = np.random.default_rng(rng.integers(0, 2**63))

        # Per-column ray tables in the camera body frame (x forward, y left).
        a_u = (np.arange(w) - cx) / fx
        self._cos_u = 1.0 / np.sqrt(1.0 + a_u**2)
        self._dir_body = np.stack([self._cos_u, -a_u * self._cos_u], axis=-1)
        # Per-row plane depth: floor below the horizon, ceiling above (inf on the horizon).
        b_v = (np.arange(h) - cy) / fy
        with np.errstate(divide="ignore"):
            z_plane = np.where(
                b_v > 0, camera_height_m / b_v, (world.wall_height_m - camera_height_m) / -b_v
            )
        self._b_v = b_v[:, None].astype(np.float32)
        self._z_plane = z_plane[:, None].astype(np.float32)
        # Floor rows, then ceiling rows: body-frame plane points per pixel, rotated each frame.
        self._planes = []
        for rows, tile_m, key in ((b_v > 0, FLOOR_TILE_M, 1), (b_v < 0, CEILING_TILE_M, 2)):
            fwd = np.repeat(z_plane[rows, None], w, axis=1).astype(np.float32)
            left = (-a_u[None, :] * fwd).astype(np.float32)
            fade = _fade(fwd, 3.0, 9.0)
            self._planes.append((np.flatnonzero(rows), fwd, left, fade, tile_m, key))

    def render(
        self, pose_world_camera: np.ndarray, rng: np.random.Generator | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Render one frame.

        pose_world_camera: (3,) [x_m, y_m, yaw_rad] of the camera body (x forward) in the world.
        rng: pixel-noise generator; the renderer's own seeded one when None.
        Returns image (H, W) uint8 mono and depth_m (H, W) float32, metres along the optical
        axis (0 where nothing is hit, which only happens on an exact horizon row).
        """
        x, y, yaw = (float(v) for v in pose_world_camera)
        c, s = np.cos(yaw), np.sin(yaw)
        dirs = self._dir_body @ np.array([[c, s], [-s, c]])
        hits = self._caster.cast(np.array([x, y]), dirs, MAX_RANGE_M)
        z_wall = (hits.distance_m * self._cos_u).astype(np.float32)[None, :]

        is_wall = z_wall <= self._z_plane
        depth = np.where(is_wall, z_wall, self._z_plane)
        image = self._plane_texture(x, y, c, s)
        band = np.flatnonzero(is_wall.any(axis=1))
        if band.size:
            rows = slice(band[0], band[-1] + 1)
            wall = self._wall_texture(hits, z_wall, rows)
            image[rows] = np.where(is_wall[rows], wall, image[rows])
        image, depth = self._downsample(image, depth)
        image = cv2.GaussianBlur(image, (3, 3), 0.6)
        sigma = self.config.pixel_noise_sigma
        if sigma > 0:
            noise_rng = self._noise_rng if rng is None else rng
            image += sigma * noise_rng.standard_normal(image.shape, dtype=np.float32)
        depth[~np.isfinite(depth)] = 0.0
        return np.clip(image + 0.5, 0, 255).astype(np.uint8), depth

    def _downsample(self, image: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Samples to pixels: the mean grey of each k x k block, and the depth whose inverse is
        the mean inverse depth (exact on a plane, where 1/z is affine in the pixel)."""
        k = self._k
        if k == 1:
            return image, depth
        h, w = self.config.height, self.config.width
        image = image.reshape(h, k, w, k).mean(axis=(1, 3), dtype=np.float32)
        with np.errstate(divide="ignore"):
            inverse = np.where(depth > 0, 1.0 / depth, 0.0)
        inverse = inverse.reshape(h, k, w, k).mean(axis=(1, 3), dtype=np.float32)
        with np.errstate(divide="ignore"):
            return image, np.where(inverse > 0, 1.0 / inverse, np.inf).astype(np.float32)

    def _wall_texture(self, hits: RayHits, z_wall: np.ndarray, rows: slice) -> np.ndarray:
        """(R, W) float32 grey of the wall seen in each column, for image rows ``rows``."""
        spec = self.world.spec
        on_x_face = hits.face_axis[None, :] == 0
        facing_positive = hits.normal_xy.sum(axis=1)[None, :] > 0
        hit_xy = np.nan_to_num(hits.points_xy_m)
        x0, y0 = spec.origin_xy_m
        across = np.where(on_x_face, hit_xy[:, 0] - x0, hit_xy[:, 1] - y0)
        # Face line: the grid line the face lies on, its axis and its facing side.
        line = np.round(across / spec.resolution_m).astype(np.int64) * 4
        line += 2 * on_x_face + facing_positive
        along = np.where(on_x_face, hit_xy[:, 1], hit_xy[:, 0]).astype(np.float32)

        z = np.where(np.isfinite(z_wall), z_wall, 0.0)
        height = self.camera_height_m - self._b_v[rows] * z
        row_f = height / BRICK_H_M
        row = np.floor(row_f)
        col_f = along / BRICK_W_M + 0.5 * (row.astype(np.int64) & 1)
        col = np.floor(col_f)
        brick = self._grey[_hash(self._seed_mix, line, row, col)]
        mortar = np.minimum((row_f - row) * BRICK_H_M, (col_f - col) * BRICK_W_M) < MORTAR_M
        fade = _fade(z, 5.0, 12.0)
        grey = np.where(mortar, 40.0 + (1.0 - fade) * 90.0, 130.0 + (brick - 130.0) * fade)

        panel = np.floor(along / PANEL_W_M)
        u_in = along / PANEL_W_M - panel
        has_poster = self._uniform[_hash(self._seed_mix + 1, line, panel)] < 0.5
        in_poster = (
            (has_poster & (u_in > 0.15) & (u_in < 0.85))
            & (height > POSTER_BOTTOM_M)
            & (height < POSTER_TOP_M)
        )
        block_u = np.floor((u_in - 0.15) / 0.175)
        block_v = np.floor((height - POSTER_BOTTOM_M) / 0.3)
        poster = self._grey[_hash(self._seed_mix + 2, line, panel, block_u, block_v)]
        poster = 130.0 + (poster - 130.0) * np.sqrt(fade)
        grain = self._uniform[_hash(self._seed_mix + 4, line, along // GRAIN_M, height // GRAIN_M)]
        grain = (grain - 0.5) * 50.0 * _fade(z, 1.5, 3.5)
        return (np.where(in_poster, poster, grey) + grain).astype(np.float32)

    def _plane_texture(self, x: float, y: float, c: float, s: float) -> np.ndarray:
        """(H, W) float32 grey of the floor (below the horizon) and ceiling (above it)."""
        image = np.full(self._z_plane.shape[:1] + self._cos_u.shape, FLOOR_GREY, np.float32)
        for rows, fwd, left, fade, tile_m, key in self._planes:
            fx = (x + c * fwd - s * left) / tile_m
            fy = (y + s * fwd + c * left) / tile_m
            ix, iy = np.floor(fx), np.floor(fy)
            grout = np.minimum(fx - ix, fy - iy) * tile_m < GROUT_M
            h = _hash(self._seed_mix + 3, ix, iy, key)
            if key == 1:
                mean = FLOOR_GREY
                grey = 0.5 * self._grey[h] + 50.0
            else:
                mean = CEILING_GREY
                grey = np.where(self._uniform[h] < 0.12, LAMP_GREY, 0.25 * self._grey[h] + 150.0)
            grey = np.where(grout, mean - 60.0, grey)
            image[rows] = mean + (grey - mean) * fade
        return image
