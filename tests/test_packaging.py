"""frontends/ and backends/ install as smokyslam.frontends / smokyslam.backends, never top level."""

import subprocess
import sys
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_mapped_packages_import_and_no_top_level_leak(tmp_path):
    code = (
        "import importlib.util as u, smokyslam.frontends, smokyslam.backends;"
        "print(u.find_spec('frontends') is None, u.find_spec('backends') is None)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["True", "True"]


def test_wheel_holds_only_the_smokyslam_namespace(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
            str(REPO),
        ],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("smokyslam-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    code = [n for n in names if n.endswith(".py")]
    assert "smokyslam/frontends/__init__.py" in code
    assert "smokyslam/backends/__init__.py" in code
    assert "smokyslam/frontends/readers/base.py" in code
    assert all(n.startswith("smokyslam/") for n in code), [n for n in code if "smokyslam/" not in n]
