"""Progress when output is not a terminal: plain text lines, every few seconds."""

import io
import time

from rich.console import Console

from smokyslam import progress


def test_piped_progress_prints_plain_lines(monkeypatch):
    stream = io.StringIO()
    monkeypatch.setattr(progress, "console", Console(file=stream, force_terminal=False))
    monkeypatch.setattr(progress, "PLAIN_PERIOD_S", 0.0)  # a line at every update
    with progress.progress_bar("comparing 4 runs", 4, unit="items") as update:
        update(1, status="radar-r0-c0 ok")
        update(2, 4, status="fused-r0-c0 ok")
    lines = stream.getvalue().splitlines()
    assert lines[0] == "comparing 4 runs: 1/4 items (25%), 0 s elapsed, radar-r0-c0 ok"
    assert lines[1] == "comparing 4 runs: 2/4 items (50%), 0 s elapsed, fused-r0-c0 ok"
    assert lines[2].startswith("comparing 4 runs: 4/4 items (100%)") and len(lines) == 3
    assert not any("{" in line for line in lines)


def test_piped_progress_is_quiet_within_a_period(monkeypatch):
    stream = io.StringIO()
    monkeypatch.setattr(progress, "console", Console(file=stream, force_terminal=False))
    with progress.progress_bar("fused on office.mcap", 60.0) as update:
        for t in range(60):
            update(float(t), status="kf 3")
    # Less than a period: nothing (a quick command prints only its own lines).
    assert stream.getvalue() == ""
    monkeypatch.setattr(progress, "PLAIN_PERIOD_S", 0.05)
    with progress.progress_bar("fused on office.mcap", 60.0) as update:
        for t in range(5):
            time.sleep(0.03)
            update(float(t), status="kf 3")
    lines = stream.getvalue().splitlines()
    assert 2 <= len(lines) <= 4 and lines[-1].startswith("fused on office.mcap: 60/60 s (100%)")
