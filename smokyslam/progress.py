"""Progress bars for long commands (rich), kept out of the library cores.

Cores accept an optional ``on_progress(done, total)`` callback; the CLI passes one of these.
"""

from __future__ import annotations

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


@contextmanager
def progress_bar(description: str, total: float, unit: str = "s") -> Iterator[Callable[..., None]]:
    """A rich bar on stderr; yields ``update(done, total=None, status="")``."""
    columns = [
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        MofNCompleteColumn() if unit == "items" else TextColumn(f"{{task.completed:.0f}}{unit}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        TextColumn("{task.fields[status]}"),
    ]
    # Bars are for people at a terminal; piped output (CI, scripts) stays clean.
    with Progress(*columns, console=console, disable=not console.is_terminal) as progress:
        task = progress.add_task(description, total=total, status="")

        def update(done: float, total: float | None = None, status: str = "") -> None:
            progress.update(task, completed=done, total=total, status=status)

        yield update
        progress.update(task, completed=progress.tasks[0].total)
