"""A run as a Rerun recording (``.rrd``, or a spawned viewer), logged as the run goes.

Entity paths follow the frame tree. ``world`` is the ground-truth frame (the estimate's own
frame without ground truth). ``world/map`` is the run's map frame: anchored at the true start
pose while the run goes (when the log has truth), placed by the run's alignment at the end.
``world/map/rig`` moves with base_link; ``world/map/rig/radar`` (levelled mount) holds each
radar frame's points coloured by Doppler; ``world/map/rig/camera`` (mount) holds the pinhole
and the smoked image with its tracked features; ``camera/clean`` the preprocessed image.
``world/map/trajectory/<source>``, ``world/map/keyframes``, ``world/map/loop_closures`` and
``world/map/maps/<name>`` (grid maps) grow at the configured rates. Time series live under
``health/``, ``smoke/``, ``trust/`` and ``error/``. Timelines: ``sensor_time`` (the log's own
clock) and ``frame`` (primary frame index), set once per frame.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from smokyslam.config import RecordingConfig
from smokyslam.frontends.camera.result import CameraOdometryResult
from smokyslam.geometry import GridSpec, se3_from_se2
from smokyslam.viz.colors import doppler_colors, map_rgba, source_color, truth_rgba
from smokyslam.viz.layout import run_blueprint
from smokyslam.viz.recorder import Due, FrameRecord, RecordingSetup, RunSnapshot
from smokyslam.viz.rerun_stream import grid_map, level_mount, open_stream, path_3d, transform
from smokyslam.viz.series import SeriesBuffer
from smokyslam.viz.truth_anchor import TruthAnchor

MAP_HEIGHT_M = -0.02
"""Grid maps lie just below the floor, so paths and points stay visible on them."""


class RerunRecorder:
    """The recorder stage writing Rerun: see the module docstring for what goes where."""

    def __init__(
        self, path: Path | str | None, config: RecordingConfig, spawn: bool = False
    ) -> None:
        import rerun as rr

        self._rr = rr
        self.path = None if path is None else Path(path)
        self._config = config
        self._rec = open_stream(self.path, spawn, run_blueprint())
        self._source = "run"
        self._anchor: TruthAnchor | None = None
        self._log_time = None
        self._next_path_s = 0.0
        self._next_maps_s = config.maps_period_s
        self._camera_frames = 0
        self._frame = 0
        self._time_s = 0.0
        self._series = SeriesBuffer()
        self.keeps_camera_views = True

    # ------------------------------------------------------------------ once

    def start(self, setup: RecordingSetup) -> None:
        rr, rec = self._rr, self._rec
        self._source = setup.source
        self._log_time = setup.log_time_s
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("world/map/rig/radar", transform(rr, level_mount(setup.extrinsics)), static=True)
        rec.log("world/map/rig/camera", transform(rr, setup.extrinsics.T_base_camera), static=True)
        if (k := setup.intrinsics) is not None:
            pinhole = rr.Pinhole(
                focal_length=[k.fx, k.fy],
                principal_point=[k.cx, k.cy],
                width=k.width,
                height=k.height,
                camera_xyz=rr.ViewCoordinates.RDF,
                image_plane_distance=0.5,
            )
            rec.log("world/map/rig/camera/image", pinhole, static=True)
        if setup.gt_map is not None:
            spec = setup.gt_map.spec
            rec.log(
                "world/ground_truth/map",
                grid_map(rr, truth_rgba(setup.gt_map.cells), spec, MAP_HEIGHT_M / 2),
                static=True,
            )
        if setup.truth is not None and len(setup.truth):
            self._anchor = TruthAnchor(setup.truth)
            rec.log(
                "world/ground_truth/path",
                rr.LineStrips3D(
                    [path_3d(setup.truth.poses_world_base)],
                    colors=[source_color("ground_truth")],
                    radii=0.02,
                ),
                static=True,
            )
        for name in ("radar_inliers", "camera_tracked", "camera_weight", "loop_closures"):
            rec.log(f"health/{name}", rr.SeriesLines(names=name), static=True)

    # ------------------------------------------------------------------ per frame

    def _set_time(self, stamp_s: float, frame: int) -> None:
        self._time_s = float(self._log_time(np.array([stamp_s]))[0])
        self._rec.set_time("sensor_time", timestamp=self._time_s)
        self._rec.set_time("frame", sequence=frame)

    def _scalar(self, entity: str, value: float) -> None:
        """A time-series sample at the current time (sent in columns with the snapshots)."""
        self._series.add(entity, self._time_s, self._frame, value)

    def log_frame(self, record: FrameRecord) -> None:
        rr, rec = self._rr, self._rec
        self._frame = record.index
        self._set_time(record.stamp_s, record.index)
        if record.index == 0 and self._anchor is not None:
            rec.log("world/map", transform(rr, self._anchor.start(record.stamp_s)))
        rec.log("world/map/rig", transform(rr, se3_from_se2(record.pose_map_base)))
        if record.scan is not None:
            rec.log(
                "world/map/rig/radar/points",
                rr.Points3D(
                    record.scan.points_xyz_m,
                    colors=doppler_colors(record.scan.doppler_mps),
                    radii=0.05,
                ),
            )
        status = record.status
        self._scalar("health/radar_inliers", status.inliers)
        self._scalar("health/lost", status.lost)
        self._scalar("health/loop_closures", status.loop_closures)
        if status.camera_frames:
            self._scalar("health/camera_weight", status.camera_weight)
        if self._anchor is not None:
            error_m = self._anchor.error_m(record.stamp_s, record.pose_map_base)
            if np.isfinite(error_m):
                self._scalar(f"error/{self._source}/position_m", error_m)

    def log_camera(self, result: CameraOdometryResult, trust_index: float) -> None:
        rr, rec = self._rr, self._rec
        self._set_time(result.stamp_s, self._frame)
        quality = result.quality
        self._scalar("smoke/impulse_fraction", quality.impulse_fraction)
        self._scalar("smoke/rms_contrast", quality.rms_contrast)
        self._scalar("smoke/dark_level", quality.dark_level)
        self._scalar("trust/t", trust_index)
        self._scalar("health/camera_tracked", 0.0 if result.lost else result.health.tracked)
        self._camera_frames += 1
        view = result.view
        if view is None or (self._camera_frames - 1) % self._config.camera_every:
            return
        quality_jpeg = [int(cv2.IMWRITE_JPEG_QUALITY), self._config.jpeg_quality]
        for entity, image in (
            ("world/map/rig/camera/image", view.raw),
            ("camera/clean", view.clean),
        ):
            ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(image), quality_jpeg)
            if ok:
                rec.log(entity, rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))
            colors = np.where(view.has_landmark[:, None], [40, 220, 40], [250, 200, 0])
            rec.log(
                f"{entity}/features",
                rr.Points2D(view.features_px, colors=colors.astype(np.uint8), radii=1.5),
            )

    # ------------------------------------------------------------------ over the run

    def due(self, stamp_s: float) -> Due:
        due = Due(path=bool(stamp_s >= self._next_path_s), maps=bool(stamp_s >= self._next_maps_s))
        if due.path:
            self._next_path_s = stamp_s + self._config.path_period_s
        if due.maps:
            self._next_maps_s = stamp_s + self._config.maps_period_s
        return due

    def log_snapshot(self, snapshot: RunSnapshot) -> None:
        rr, rec = self._rr, self._rec
        self._series.flush(rec)
        self._set_time(snapshot.stamp_s, self._frame)
        self._log_path(snapshot.poses_map_base)
        keyframes = np.asarray(snapshot.keyframe_poses).reshape(-1, 3)
        rec.log(
            "world/map/keyframes",
            rr.Points3D(path_3d(keyframes), radii=0.06, colors=[255, 160, 0]),
        )
        edges = np.asarray(snapshot.loop_edges, dtype=int).reshape(-1, 2)
        if len(edges):
            strips = [path_3d(keyframes[list(edge)]) for edge in edges]
            rec.log("world/map/loop_closures", rr.LineStrips3D(strips, colors=[255, 0, 255]))
        for name, (cells, spec) in snapshot.maps.items():
            self._log_map(name, cells, spec)

    def _log_path(self, poses_map_base: np.ndarray) -> None:
        self._rec.log(
            f"world/map/trajectory/{self._source}",
            self._rr.LineStrips3D(
                [path_3d(poses_map_base)], colors=[source_color(self._source)], radii=0.03
            ),
        )

    def _log_map(self, name: str, cells: np.ndarray, spec: GridSpec) -> None:
        self._rec.log(f"world/map/maps/{name}", grid_map(self._rr, map_rgba(cells), spec, 0.0))

    # ------------------------------------------------------------------ the end

    def log_result(
        self, pose_world_map: np.ndarray, stamps_s: np.ndarray, poses_map_base: np.ndarray
    ) -> None:
        """The run's alignment (static: the whole run is then seen in the truth frame) and its
        final path at the last stamp."""
        self._rec.log("world/map", transform(self._rr, se3_from_se2(pose_world_map)), static=True)
        if len(stamps_s):
            self._set_time(float(stamps_s[-1]), self._frame)
            self._log_path(poses_map_base)

    def close(self) -> None:
        self._series.flush(self._rec)
        self._rec.flush()
        if self.path is not None:
            self._rec.disconnect()
