"""An output folder: results, the effective config, metrics and a run log, written as they come.

Each stage writes what it has as soon as it has it, so a run cut short keeps what it computed.
A folder that already holds a run's outputs is refused (one clear line) unless the caller
asks to overwrite it, which first removes those outputs, so no file of the earlier run (a map,
a metrics key) survives into the new one.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

from smokyslam.config import SmokySlamConfig, deep_update, write_config
from smokyslam.errors import OutputError, RunInterruptedError, SmokySlamError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import save_map
from smokyslam.mapping.render import render_map_png
from smokyslam.types import GroundTruthMap

logger = logging.getLogger(__name__)

METRICS_FILE = "metrics.json"
CONFIG_FILE = "config.yaml"
RUN_LOG_FILE = "run.log"
RUN_OUTPUTS = (
    METRICS_FILE,
    CONFIG_FILE,
    RUN_LOG_FILE,
    "trajectory.tum",
    "trajectory_kitti.txt",
    "ground_truth.tum",
    "trajectory.png",
    "error.png",
    "health.png",
    "run.rrd",
    "error.log",
    "maps",
)
"""What a run leaves in its folder; any of them there means the folder holds a run."""


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def writable_folder(root: Path | str, option: str = "--out") -> Path:
    """``root`` created if needed and checked writable before any work starts; OutputError
    (one line naming ``option``) for a file in the way or a place that cannot be written."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{option} {root}: exists and is not a folder")
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = root / f".smokyslam-write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise OutputError(f"{option} {root}: cannot write there ({exc.strerror or exc})") from None
    return root


def writable_file(path: Path | str, option: str) -> Path:
    """``path`` checked as a file that can be written (its folder created if needed) before
    any work starts; an existing file is left as it is. OutputError naming ``option``."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{option} {path}: is a folder, not a file")
    writable_folder(path.parent if str(path.parent) else Path("."), option)
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputError(f"{option} {path}: cannot be written (no permission)")
    return path


def claim_folder(
    root: Path,
    overwrite: bool,
    outputs: tuple[str, ...] = RUN_OUTPUTS,
    markers: tuple[str, ...] | None = None,
) -> None:
    """Make ``root`` ready for new outputs. If it holds any of ``markers`` (default: any of
    ``outputs``), an earlier run is there: refuse it (OutputError) unless ``overwrite``, which
    removes every one of ``outputs`` first. Nothing else in the folder is touched."""
    writable_folder(root)
    found = [name for name in (markers or outputs) if (root / name).exists()]
    if not found:
        return
    present = [root / name for name in outputs if (root / name).exists()]
    if not overwrite:
        raise OutputError(
            f"--out {root} holds an earlier run ({found[0]}); "
            "pass --overwrite to replace it, or choose another folder"
        )
    for path in present:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


class OutputFolder:
    """A results folder: ``config.yaml``, ``metrics.json``, ``run.log``, ``maps/``, plots."""

    def __init__(self, root: Path | str, overwrite: bool | None = None) -> None:
        """``overwrite``: None opens the folder as it is (to add to it); False refuses a
        folder holding an earlier run's outputs; True removes those outputs first."""
        self.root = Path(root)
        if overwrite is not None:
            claim_folder(self.root, overwrite)
        writable_folder(self.root)
        self.maps: dict[str, tuple[np.ndarray, GridSpec]] = {}
        """Every map written so far: name -> (trinary cells, grid spec)."""
        self.empty_maps: list[str] = []
        """Maps that had no cell at all, so no file."""
        self._log_handler: logging.Handler | None = None

    def path(self, *parts: str) -> Path:
        """A path inside the folder (parent folders created)."""
        target = self.root.joinpath(*parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def write_config(self, config: SmokySlamConfig) -> Path:
        return write_config(config, self.path(CONFIG_FILE))

    def update_metrics(self, metrics: dict[str, Any]) -> dict[str, Any]:
        """Merge ``metrics`` into ``metrics.json`` (nested keys merge) and return the whole."""
        target = self.path(METRICS_FILE)
        current = json.loads(target.read_text()) if target.is_file() else {}
        merged = _jsonable(deep_update(current, metrics))
        partial = target.with_name(f".{target.name}.partial")
        partial.write_text(json.dumps(merged, indent=2) + "\n")
        partial.replace(target)  # whole or not at all, even if the run is killed here
        return merged

    def write_map(
        self,
        name: str,
        cells: np.ndarray,
        spec: GridSpec,
        truth: GroundTruthMap | None = None,
        trajectory_xy_m: np.ndarray | None = None,
        caption: str = "",
    ) -> Path | None:
        """``maps/NAME.{pgm,yaml,png}`` and, with ground truth or a path, the picture
        ``maps/NAME_vs_truth.png``: metric axes, a legend, the path, and a title naming the
        map and ``caption`` (e.g. the source and the error index).

        A map without a single cell (e.g. every radar return lost) is a valid result with no
        file: it is named in ``metrics.json`` ``empty_maps`` and in ``run.log``; None.
        """
        if min(np.shape(cells)) == 0:
            logger.warning("map %s is empty (nothing was observed): no map file", name)
            self.empty_maps.append(name)
            self.update_metrics({"empty_maps": self.empty_maps})
            return None
        yaml_path = save_map(self.path("maps", f"{name}.yaml"), cells, spec, unknown="unobserved")
        self.maps[name] = (cells, spec)
        if truth is not None or trajectory_xy_m is not None:
            render_map_png(
                self.path("maps", f"{name}_vs_truth.png"),
                cells,
                spec,
                truth,
                trajectory_xy_m,
                f"{name}: {caption}" if caption else name,
            )
        return yaml_path

    @contextlib.contextmanager
    def interrupt_kept(self) -> Iterator[None]:
        """A Ctrl-C in this block keeps what was written: the metrics are marked
        ``interrupted`` and it becomes a RunInterruptedError naming the folder."""
        try:
            yield
        except KeyboardInterrupt:
            self.update_metrics({"interrupted": True})
            raise RunInterruptedError(self.root) from None

    def start_run_log(self, level: int = logging.INFO) -> None:
        """Copy smokyslam's log records into ``run.log`` until :meth:`close`."""
        handler = logging.FileHandler(self.path(RUN_LOG_FILE), mode="w")
        handler.setLevel(level)
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
        package_logger = logging.getLogger("smokyslam")
        package_logger.addHandler(handler)
        package_logger.setLevel(min(package_logger.level or logging.WARNING, level))
        self._log_handler = handler

    def close(self) -> None:
        if self._log_handler is not None:
            logging.getLogger("smokyslam").removeHandler(self._log_handler)
            self._log_handler.close()
            self._log_handler = None

    def __enter__(self) -> OutputFolder:
        self.start_run_log()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """Close the run log; a run that failed leaves its error in it (the console gets its
        one line from the command, not a second one from here)."""
        if exc is not None and self._log_handler is not None:
            if isinstance(exc, KeyboardInterrupt | RunInterruptedError):
                message, info = "run interrupted", None
            elif isinstance(exc, SmokySlamError):
                message, info = f"run failed: {exc}", None
            else:
                message, info = (
                    f"run failed: {type(exc).__name__}: {exc}",
                    (exc_type, exc, traceback),
                )
            record = logger.makeRecord(logger.name, logging.ERROR, __file__, 0, message, (), info)
            self._log_handler.handle(record)
        self.close()
