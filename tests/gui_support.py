"""Helpers for the desktop-window tests: a QApplication on the X server of ``DISPLAY`` (Xvfb in CI: real windows,
a window manager's events) or, without one, Qt's offscreen platform; bounded waits (never an endless loop) that
serve the window's events as its event loop does.

The waits run a ``QEventLoop``, not ``QTest.qWait``: PySide6's ``qWait`` holds the interpreter lock for its whole
duration, so while a test waited the window's threads (the campaign worker and its runner, the store's writer,
background tasks) ran only in the moments between two waits, about 50 times a second: a simulated run took 3-4 times
as long as under ``bench run`` or the application's own event loop, which lets the lock go while it is idle."""

from __future__ import annotations

import os
import time
from collections.abc import Callable

if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest
from PySide6.QtCore import QCoreApplication, QEvent, QEventLoop, QTimer
from PySide6.QtWidgets import QApplication

#: Longest wait for a simulated campaign (or the worker after a close); a stuck test fails instead of hanging.
RUN_TIMEOUT_S = 45.0


def application() -> QApplication:
    """The process's QApplication (created once)."""
    return QApplication.instance() or QApplication(["bench-tests"])


def real_display() -> bool:
    """True when the tests run on an X server (xcb), where window activation and input are the desktop's."""
    return application().platformName() == "xcb"


def serve_events(ms: int) -> None:
    """Run the event loop for ``ms`` milliseconds, as the application's own loop runs (the other threads run too),
    then delete what asked to be deleted meanwhile (``deleteLater``), as ``QTest.qWait`` does."""
    loop = QEventLoop()
    QTimer.singleShot(ms, loop.quit)
    loop.exec()
    QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)


def wait_for(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Process Qt events until ``predicate()`` is true; fail the test naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        serve_events(20)


def select_runs(browser, run_ids: list[int]) -> None:
    """Select ``run_ids`` in a results browser once its background scan lists them."""

    def listed() -> set[int]:
        return {int(browser.table.item(row, 0).text()) for row in range(browser.table.rowCount())}

    wait_for(lambda: set(run_ids) <= listed(), RUN_TIMEOUT_S, f"runs {run_ids} in the results table")
    browser.select_runs(run_ids)


@pytest.fixture
def window(tmp_path):
    """A shown main window on a fresh store; closing it during a run presses the emergency stop, and the question
    that follows is confirmed: the window closes once the run has ended."""
    from bench.gui.app import MainWindow

    application()
    main = MainWindow(tmp_path / "bench.db", tmp_path / "reports", open_files=False)
    main.show()
    yield main
    worker = main.campaign_panel.worker
    main.close()
    if worker is not None:
        main.confirm_close()
        assert worker.wait(int(RUN_TIMEOUT_S * 1000)), "campaign worker still running after the window closed"
        wait_for(lambda: not main.isVisible(), RUN_TIMEOUT_S, "the window to close after its stopped run")


class WireLog:
    """The command verbs a controller's link writes (``MOVE``, ``STOP``, ...), in wire order.

    Each verb is noted once its write has returned, i.e. once it is on the wire (the pty). The pkm5 driver writes
    MOVE and STOP under one lock, from whichever thread, and the note is taken inside the write: the list's order
    is the wire's. An observer of the real link, not a stand-in: the bytes go to the simulator as before."""

    def __init__(self, controller) -> None:
        self.verbs: list[str] = []
        link = controller.link
        write = link.write

        def recording(data: bytes, *, command: str, **options) -> None:
            write(data, command=command, **options)
            self.verbs.append(command)

        link.write = recording

    def mark(self) -> int:
        """Where the log stands now (before a press)."""
        return len(self.verbs)

    def moves_after_stop(self, mark: int) -> list[int]:
        """Positions of MOVEs written after the first STOP that follows ``mark`` (none, if the stop latched)."""
        after = self.verbs[mark:]
        if "STOP" not in after:
            return []
        first = after.index("STOP")
        return [mark + i for i, verb in enumerate(after) if verb == "MOVE" and i > first]

    def stopped_since(self, mark: int) -> bool:
        return "STOP" in self.verbs[mark:]
