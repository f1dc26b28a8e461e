"""Helpers for the desktop-window tests: an offscreen QApplication and bounded waits (never an endless loop)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication


def application() -> QApplication:
    """The process's QApplication (created once, offscreen)."""
    return QApplication.instance() or QApplication(["bench-tests"])


def wait_for(predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
    """Process Qt events until ``predicate()`` is true; fail the test naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        QTest.qWait(20)
