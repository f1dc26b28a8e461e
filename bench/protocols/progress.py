"""The runner's progress bar: samples stored and the time left, on stderr (Rich), or nothing."""

from __future__ import annotations

from typing import Self

__all__ = ["ProgressBar"]


class ProgressBar:
    """A Rich progress bar (samples stored, ETA) on stderr, or nothing."""

    def __init__(self, enabled: bool, *, total: int, done: int, label: str) -> None:
        self.enabled = enabled
        if enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("ETA"),
                TimeRemainingColumn(),
                console=Console(stderr=True),
                transient=False,
            )
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
