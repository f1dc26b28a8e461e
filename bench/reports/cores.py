"""Whether a report's second process would get a core of its own now (the figures drawn in a fork,
:func:`bench.reports.plots.draw_all`; a long run's raw-data CSV, :mod:`bench.reports.rawdata_child`)."""

from __future__ import annotations

import os

__all__ = ["spare_core"]


def spare_core() -> bool:
    """Whether another process would get a core of its own now (the 1-minute load, this process included, leaves
    one free): on the shared 2-core bench PC under load a second process only competes with the first, and its own
    start and reading cost more than it saves. False where the system gives no load average."""
    return hasattr(os, "getloadavg") and os.getloadavg()[0] <= (os.cpu_count() or 1) - 1
