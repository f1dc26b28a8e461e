"""The window's heavy numeric work (reports, comparisons) in a separate worker process.

Why a process and not only a thread: a report is seconds of Python and matplotlib holding the interpreter lock.
On a loaded 2-core bench PC the operating system deschedules a thread while it holds that lock, and the GUI
thread then waits for it however short its own work is: the event loop (the emergency stop, the live view) answered
only after 0.6 s during a report under load. A worker process shares no lock with the window, so the GUI thread
only needs a core.

One worker, started on first use and kept (the second report starts at once), forked from a clean ``forkserver``
process that has already imported the report code: no fork of the threaded Qt process, and no per-report import
cost. A :class:`bench.errors.BenchError` in the worker arrives as a BenchError with the same one line; a worker that
dies is replaced at the next call. Call :func:`in_worker_process` from a background thread (:mod:`bench.gui.tasks`),
never from the GUI thread: it waits for the result.
"""

from __future__ import annotations

import multiprocessing
import os
import threading
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from bench.errors import BenchError

__all__ = [
    "WorkerProcess",
    "in_worker_process",
    "one_worker_pool",
    "shutdown_worker_process",
    "write_comparison_html",
    "write_report_html",
]

#: What the worker processes' parent (one ``forkserver`` per application) imports once, so that every worker
#: starts with it loaded: the reports' code, and the live view's plots (its render process, bench.gui.live_view).
_PRELOAD = ["bench.reports", "bench.store", "bench.gui.live_plots", "matplotlib.backends.backend_agg"]
#: How much lower than the window's the worker processes' priority is (``nice`` increment; raising it needs no
#: privilege).
WORKER_NICENESS = 10


def one_worker_pool() -> ProcessPoolExecutor:
    """A pool of one worker process, forked from the application's clean ``forkserver`` process (no fork of the
    threaded Qt process), which has imported :data:`_PRELOAD`. The worker runs at a lower priority (nice
    :data:`WORKER_NICENESS`): on a loaded PC the window's thread and its emergency stop go first."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(_PRELOAD)
    return ProcessPoolExecutor(max_workers=1, mp_context=context, initializer=os.nice, initargs=(WORKER_NICENESS,))


def _call(function: Callable[..., Any], args: tuple) -> Any:  # in the worker process
    try:
        return function(*args)
    except BenchError as exc:  # the one line, in a class that always pickles (subclasses may take other arguments)
        raise BenchError(str(exc)) from None


class WorkerProcess:
    """One worker process (:func:`one_worker_pool`), started on first use and kept; one that dies is replaced at
    the next call. ``what`` names it in the error of a call it did not finish."""

    def __init__(self, what: str) -> None:
        self.what = what
        self.executor: ProcessPoolExecutor | None = None
        self._lock = threading.Lock()

    def call(self, function: Callable[..., Any], *args: Any) -> Any:
        """``function(*args)`` run in the worker process (a module-level function, picklable arguments); its
        result. Call it from a background thread: it waits.

        Raises
        ------
        BenchError
            What the function raised, or that the worker process died (the next call starts a new one).
        """
        with self._lock:
            if self.executor is None:
                self.executor = one_worker_pool()
            pool = self.executor
        try:
            return pool.submit(_call, function, args).result()
        except BrokenProcessPool:
            with self._lock:
                if self.executor is pool:
                    self.executor = None
            pool.shutdown(wait=False, cancel_futures=True)
            raise BenchError(f"the {self.what} ended unexpectedly (out of memory or killed); try again") from None

    def shutdown(self) -> None:
        """Stop the worker; a later call starts a new one."""
        with self._lock:
            pool, self.executor = self.executor, None
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)


_reports = WorkerProcess("report process")


def in_worker_process(function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)`` in the report worker process (see :meth:`WorkerProcess.call`)."""
    return _reports.call(function, *args)


def shutdown_worker_process() -> None:
    """Stop the report worker (the window closes); a later call starts a new one."""
    _reports.shutdown()


def write_report_html(store_path: str, run_id: int, report_dir: Path) -> Path:
    """``bench report RUN_ID``: the run's report (HTML and PDF) in ``report_dir``; the HTML's path."""
    from bench.reports import write_report

    return write_report(store_path, run_id, report_dir).html


def write_comparison_html(store_path: str, first_id: int, second_id: int, report_dir: Path) -> Path:
    """``bench report FIRST --compare SECOND``; the HTML's path."""
    from bench.reports import write_comparison

    return write_comparison(store_path, first_id, second_id, report_dir).html
