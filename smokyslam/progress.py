"""Progress for long commands, kept out of the library cores: a rich bar at a terminal, a
plain line every few seconds when output is piped or logged.

Cores accept an optional ``on_progress(done, total)`` callback; the CLI passes one of these.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

console = Console(stderr=True)

PLAIN_PERIOD_S = 5.0
"""Seconds between plain progress lines (output not on a terminal)."""


@contextmanager
def progress_bar(description: str, total: float, unit: str = "s") -> Iterator[Callable[..., None]]:
    """Progress on stderr; yields ``update(done, total=None, status="")``. At a terminal a
    rich bar; otherwise (CI, scripts, logs) a plain text line every :data:`PLAIN_PERIOD_S`
    seconds, and one at the end of a command that printed any."""
    if not console.is_terminal:
        with _plain_progress(description, total, unit) as update:
            yield update
        return
    columns = [
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        MofNCompleteColumn() if unit == "items" else TextColumn(f"{{task.completed:.0f}}{unit}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        TextColumn("{task.fields[status]}"),
    ]
    with Progress(*columns, console=console) as progress:
        task = progress.add_task(description, total=total, status="")

        def update(done: float, total: float | None = None, status: str = "") -> None:
            progress.update(task, completed=done, total=total, status=status)

        yield update
        progress.update(task, completed=progress.tasks[0].total)


def progress_line(
    description: str, done: float, total: float, unit: str, elapsed_s: float, status: str = ""
) -> str:
    """``description: 3/12 items (25%), 18 s elapsed, status`` (seconds: ``12/60 s``)."""
    amount = f"{done:.0f}/{total:.0f} {unit}" if total else f"{done:.0f} {unit}"
    percent = f" ({100.0 * done / total:.0f}%)" if total else ""
    line = f"{description}: {amount}{percent}, {elapsed_s:.0f} s elapsed"
    return f"{line}, {status}" if status else line


@contextmanager
def _plain_progress(description: str, total: float, unit: str) -> Iterator[Callable[..., None]]:
    """Quiet for the first period (a quick command, or one that fails at once, prints only
    its own lines), then a line every period, and a last one when it finishes."""
    started = time.monotonic()
    state = {"total": float(total), "done": 0.0, "printed": started, "status": "", "lines": 0}

    def say() -> None:
        elapsed = time.monotonic() - started
        text = progress_line(
            description, state["done"], state["total"], unit, elapsed, state["status"]
        )
        console.print(text, markup=False, highlight=False, soft_wrap=True)
        state["printed"], state["lines"] = time.monotonic(), state["lines"] + 1

    def update(done: float, total: float | None = None, status: str = "") -> None:
        state["done"], state["status"] = float(done), str(status)
        if total is not None:
            state["total"] = float(total)
        if time.monotonic() - state["printed"] >= PLAIN_PERIOD_S:
            say()

    yield update
    if state["lines"]:
        state["done"] = state["total"]
        say()
