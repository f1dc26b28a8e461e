"""Whether a report's second process would get a core of its own now (the figures drawn in a fork,
:func:`bench.reports.plots.draw_all`; a long run's raw-data CSV, :mod:`bench.reports.rawdata_child`)."""

from __future__ import annotations

import os

__all__ = ["core_time_free", "spare_core"]


def spare_core() -> bool:
    """Whether another process would get a core of its own now (the 1-minute load, this process included, leaves
    one free): on the shared 2-core bench PC under load a second process only competes with the first, and its own
    start and reading cost more than it saves. False where the system gives no load average."""
    return hasattr(os, "getloadavg") and os.getloadavg()[0] <= (os.cpu_count() or 1) - 1


def core_time_free() -> bool:
    """Whether the 1-minute load leaves some core time free (below the core count). The load counts processes that
    just ended (a benchmark's, the user's previous command) for a minute, so :func:`spare_core` refuses a second
    process on 2 cores just after any work; the raw-data CSV's writer process, measured on the 2-core machine,
    took 1.2 s off a long path report at load 0.9-1.3 and added 2.9 s at load 4.8-6.5 (docs/reports.md)."""
    return hasattr(os, "getloadavg") and os.getloadavg()[0] < (os.cpu_count() or 1)
