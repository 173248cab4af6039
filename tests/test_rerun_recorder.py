"""The Rerun recording of a run holds the frame tree, the paths, the scans and the maps."""

import warnings

import numpy as np
import pytest

from smokyslam.geometry import GridSpec
from smokyslam.types import Extrinsics, GroundTruthMap, RadarScan
from smokyslam.viz.rerun_recorder import NullRecorder, open_recorder


@pytest.fixture(autouse=True)
def _no_rerun_files_in_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))


def test_a_run_recording_reads_back_with_every_entity(tmp_path):
    import rerun.chunk

    cells = np.zeros((20, 30), dtype=np.int8)
    cells[0, :] = 100
    spec = GridSpec((0.0, 0.0), 0.1, cells.shape)
    stamps = np.arange(5) * 0.1
    poses = np.column_stack([stamps, np.zeros(5), np.zeros(5)])
    scans = [RadarScan(t, np.array([[2.0, 0.0, 0.0]]), np.ones(1), np.zeros(1)) for t in stamps]
    recorder = open_recorder(tmp_path / "run.rrd")
    recorder.log_rig(Extrinsics())
    for stamp_s, pose, scan in zip(stamps, poses, scans, strict=True):  # as the run goes
        recorder.log_frame(stamp_s, pose, scan)
    recorder.log_alignment(np.array([1.0, 2.0, 0.5]))
    recorder.log_ground_truth(GroundTruthMap(0.0, cells, spec), stamps, poses)
    recorder.log_trajectory("radar", stamps, poses)
    recorder.log_map("radar_sparse", cells, spec)
    recorder.close()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chunks = list(rerun.chunk.RrdReader(tmp_path / "run.rrd").stream())
    rows = {}
    for chunk in chunks:
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    for entity in (
        "/world/ground_truth/map",
        "/world/ground_truth/path",
        "/world/estimate/radar",
        "/world/maps/radar_sparse",
        "/world/map",
        "/world/map/rig/radar",
    ):
        assert entity in rows, entity
    assert rows["/world/map/rig"] == 5  # one pose per frame on the sensor_time timeline
    assert rows["/world/map/rig/radar/points"] == 5


def test_no_path_means_the_null_recorder():
    assert isinstance(open_recorder(None), NullRecorder)
