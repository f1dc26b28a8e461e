"""The runner's progress bar: samples stored and the time left, on stderr (Rich), or nothing."""

from __future__ import annotations

from typing import TYPE_CHECKING, Self

if TYPE_CHECKING:
    from rich.progress import Progress

__all__ = ["ProgressBar", "rich_progress"]


def rich_progress() -> Progress:
    """The progress display of every long job (a run, a large kinematics batch): its label, a bar, done of total
    and the time left, on stderr (a ``rich.progress.Progress``, imported on first use)."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=Console(stderr=True),
    )


class ProgressBar:
    """A Rich progress bar (samples stored, ETA) on stderr, or nothing."""

    def __init__(self, enabled: bool, *, total: int, done: int, label: str) -> None:
        self.enabled = enabled
        if enabled:
            self._bar = rich_progress()
            self._task = self._bar.add_task(label, total=total, completed=done)

    def __enter__(self) -> Self:
        if self.enabled:
            self._bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self._bar.stop()

    def advance(self) -> None:
        if self.enabled:
            self._bar.advance(self._task)
