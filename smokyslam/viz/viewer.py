"""Opening recordings in the Rerun viewer: ``smokyslam view`` and ``--rerun-spawn``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from smokyslam.errors import ViewerError

RECORDING_NAMES = ("run.rrd", "compare.rrd", "paper_table.rrd")
"""What a folder's recording is called, in the order they are looked for."""


def has_display() -> bool:
    """Whether a viewer window can open here (X11 or Wayland on Linux; always elsewhere)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


NO_DISPLAY = "no display here (DISPLAY and WAYLAND_DISPLAY are unset)"


def require_display(what: str, hint: str | None = None) -> None:
    """ViewerError with a hint when no window can open here."""
    if not has_display():
        hint = hint or (
            "write the recording with --rerun FILE.rrd instead and open it where there is "
            "one: `smokyslam view FILE.rrd`"
        )
        raise ViewerError(f"{what}: {NO_DISPLAY}; {hint}")


def find_recording(path: Path | str) -> Path:
    """The ``.rrd`` at ``path``: the file itself, or a folder's recording (``run.rrd``, then
    any single ``.rrd`` in it)."""
    path = Path(path)
    if path.is_file():
        if path.suffix != ".rrd":
            raise ViewerError(f"{path}: not a Rerun recording (.rrd)")
        return path
    if not path.is_dir():
        raise ViewerError(f"{path}: no such recording or folder")
    for name in RECORDING_NAMES:
        if (path / name).is_file():
            return path / name
    found = sorted(path.glob("*.rrd"))
    if len(found) == 1:
        return found[0]
    if not found:
        raise ViewerError(
            f"{path}: no recording in this folder (make one with `smokyslam run ... --rerun "
            f"{path}/run.rrd`)"
        )
    raise ViewerError(f"{path}: {len(found)} recordings; name one: {', '.join(map(str, found))}")


def view(path: Path | str) -> Path:
    """Open the recording at ``path`` in the Rerun viewer (waits until it is closed)."""
    recording = find_recording(path)
    require_display(
        f"view {recording}",
        f"open it on a machine with a display (`smokyslam view {recording.name}` or "
        f"`rerun {recording.name}`), or serve it to a browser: "
        f"`rerun {recording} --web-viewer`",
    )
    try:
        subprocess.run([sys.executable, "-m", "rerun", str(recording)], check=True)
    except (OSError, subprocess.CalledProcessError) as exc:
        raise ViewerError(f"{recording}: the Rerun viewer did not run ({exc})") from None
    return recording
