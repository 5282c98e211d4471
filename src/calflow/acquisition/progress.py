"""Progress of long steps on a terminal (rich), and silence in logs.

``with progress("nano1d-thesis training", total) as step: ... step(done, total)`` shows a
bar with the rate and the time left when standard error is a terminal; under Snakemake,
where standard error goes to a log file, ``step`` does nothing and the log stays clean.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TextIO


def _quiet(done: int, total: int) -> None:
    return None


@contextmanager
def progress(label: str, total: int, stream: TextIO | None = None) -> Iterator[Callable[[int, int], None]]:
    """A callable ``step(done, total)`` that advances a progress bar on a terminal."""
    stream = sys.stderr if stream is None else stream
    if not stream.isatty():
        yield _quiet
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TaskProgressColumn,
        TextColumn,
        TimeRemainingColumn,
    )

    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TaskProgressColumn(),
        TextColumn("[progress.data.speed]{task.fields[rate]}"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=Console(file=stream), transient=False) as bar:
        task = bar.add_task(label, total=total, rate="")

        def step(done: int, total: int) -> None:
            speed = bar.tasks[0].speed
            bar.update(task, completed=done, total=total, rate=f"{speed:.1f}/s" if speed else "")

        yield step
