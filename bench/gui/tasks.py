"""Background tasks of the window: anything that may take longer than a frame (reports, comparisons, exports,
store scans) runs on Qt's global thread pool, never on the GUI thread.

A :class:`Task` runs one function in a pool thread and reports back through queued signals: ``done(result)`` or
``failed(message)`` (a :class:`bench.errors.BenchError` gives its one line; anything else its type and text, and
the traceback goes to the log). The window keeps the event loop free, so the emergency stop and the live view
answer while a report is being written.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from bench.errors import BenchError

__all__ = ["Task", "run_in_background"]

_log = logging.getLogger(__name__)


class Task(QObject):
    """One function run off the GUI thread; ``done(result)`` or ``failed(message)`` arrive in the GUI thread."""

    done = Signal(object)
    failed = Signal(str)
    ended = Signal()  #: after ``done`` or ``failed``

    def __init__(self, what: str, function: Callable[[], Any], parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.what = what
        self.function = function
        self.result: Any = None
        self.error: str | None = None
        self.finished = False  #: set in the pool thread once the outcome is known (``done``/``failed`` queued)

    def start(self) -> None:
        """Run on the global thread pool (connect to the signals before)."""
        self._runnable = _Runnable(self)
        self._runnable.setAutoDelete(False)  # kept by this task: the pool never runs a collected wrapper
        QThreadPool.globalInstance().start(self._runnable)

    def _run(self) -> None:  # in a pool thread
        try:
            result = self.function()
        except BenchError as exc:
            self.error = str(exc)
            self.failed.emit(self.error)
        except Exception as exc:  # noqa: BLE001 - shown to the operator, never a silent thread death
            _log.exception("%s failed", self.what)
            self.error = f"{self.what}: {type(exc).__name__}: {exc}"
            self.failed.emit(self.error)
        else:
            self.result = result
            self.done.emit(result)
        self.finished = True
        self.ended.emit()


class _Runnable(QRunnable):
    def __init__(self, task: Task) -> None:
        super().__init__()
        self.task = task

    def run(self) -> None:
        self.task._run()


def run_in_background(
    what: str,
    function: Callable[[], Any],
    parent: QObject | None = None,
    *,
    on_done: Callable[[Any], None] | None = None,
    on_failed: Callable[[str], None] | None = None,
    on_ended: Callable[[], None] | None = None,
) -> Task:
    """Start ``function`` on the global thread pool, its outcome connected first (a quick function could end before
    a later ``connect``)."""
    task = Task(what, function, parent)
    for signal, slot in ((task.done, on_done), (task.failed, on_failed), (task.ended, on_ended)):
        if slot is not None:
            signal.connect(slot)
    task.start()
    return task
