"""Localization on a real building: the Intel Research Lab log, emulated as radar.

The map is made from the log's first half (455 scans; every laser beam, noise-free, on the
corrected poses), and the localizer tracks the second half's emulated radar (40 points
within +-60 deg a scan) from a start 1 m and 10 deg off. The second half walks stretches the
first half mapped poorly: there its scans fit the map 25-30 % worse than before, for about 30
scans. Measured with filter seeds 0-2: with injection from a 20 % fall of the fit the filter
searched the whole building there, settled in wrong places and stayed lost (17-21 % of the
scans more than 0.5 m off, the worst 23-25 m); with injection from a 35 % fall while
tracking (``INJECT_FLOOR_TRACKING``), 3.5-4.4 % (the cloud spreads there, and its heaviest
mode strays for a few scans), median error 0.12 m.
"""

import gzip

import numpy as np
import pytest

from smokyslam.config import SmokySlamConfig
from smokyslam.evaluation.trajectory_io import read_tum
from smokyslam.geometry import interpolate_se2
from smokyslam.pipelines.localize import StartRequest, localize_log
from smokyslam.pipelines.truth_mapping import run_truth_mapping


@pytest.fixture(scope="module")
def halves(real_data_dir, tmp_path_factory):
    """The log split into two CARMEN logs at its middle laser scan (header lines in both)."""
    path = real_data_dir / "intel-corrected.log.gz"
    if not path.is_file():
        pytest.skip(f"{path} not found")
    with gzip.open(path, "rt") as log:
        lines = log.read().splitlines(keepends=True)
    scans = np.cumsum([line.startswith("FLASER") for line in lines])
    data = np.array([line.split(" ", 1)[0] in ("FLASER", "NEFF", "ODOM") for line in lines])
    middle = scans[-1] // 2
    folder = tmp_path_factory.mktemp("intel")
    out = []
    for name, part in (("first", scans <= middle), ("second", scans > middle)):
        (folder / f"{name}.log").write_text(
            "".join(line for line, keep in zip(lines, ~data | part, strict=True) if keep)
        )
        out.append(folder / f"{name}.log")
    return out


def test_tracking_holds_through_stretches_the_map_knows_poorly(halves, tmp_path):
    first, second = halves
    mapping = SmokySlamConfig()
    mapping.carmen.emulate_radar = False  # the map: every beam, as a lidar made it
    run_truth_mapping(first, mapping, tmp_path / "map")
    start = StartRequest(init_offset=np.array([0.8, 0.6, np.radians(10.0)]))
    out = tmp_path / "localize"
    result = localize_log(
        tmp_path / "map/maps/radar_sparse.yaml", second, SmokySlamConfig(), out, start
    )
    assert result.metrics["localization"]["frames"] == 455
    stamps_s, poses = read_tum(out / "trajectory.tum")
    truth = interpolate_se2(*read_tum(out / "ground_truth.tum"), stamps_s)
    errors_m = np.hypot(*(poses[:, :2] - truth[:, :2]).T)
    assert np.median(errors_m) < 0.2
    assert np.mean(errors_m > 0.5) < 0.1
