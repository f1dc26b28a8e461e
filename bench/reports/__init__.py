"""bench.reports: turn stored runs into reports a customer would accept (HTML, PDF, raw data, comparisons).

The report reads the run store (never hardware) and takes every number from :mod:`bench.metrology`
(:mod:`bench.reports.content` for pose runs; :mod:`~bench.reports.actuator`, :mod:`~bench.reports.ladder`,
:mod:`~bench.reports.lasergrid`, :mod:`~bench.reports.positioning` and :mod:`~bench.reports.stabilisation` for the
actuator, payload-ladder, laser-grid hit, delta positioning and stabilisation runs, see :data:`LAYOUTS`);
:mod:`~bench.reports.deviations` lists every departure from ISO 9283 (and the documents' methods) computed from
the stored configuration; :mod:`~bench.reports.document` lays the report out once and :mod:`~bench.reports.html`
and :mod:`~bench.reports.pdf` print that one layout. The raw data is written next to the report as CSV and cited
with its SHA-256.

Examples
--------
>>> paths = write_report("bench.db", 3, "reports/")          # doctest: +SKIP
>>> paths.html, paths.pdf, paths.csv                          # doctest: +SKIP

Importing :mod:`bench.reports` is cheap: its public names are loaded from :mod:`bench.reports.writing` when first
used (PEP 562), so a command that needs one analysis module of the package (``bench analyze path-run`` reads
:mod:`bench.reports.path_run`) does not load matplotlib and every layout with it.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bench.reports.writing import (
        ALL_CRITERIA,
        CRITERIA,
        FORMATS,
        LAYOUTS,
        SIMULATED_BANNER,
        ActuatorReport,
        Deviation,
        GridHitReport,
        GridPositioningReport,
        LadderReport,
        Layout,
        ReportBase,
        ReportPaths,
        RunReport,
        StabilisationReport,
        collect,
        iso_deviations,
        own_layout,
        write_comparison,
        write_report,
        write_trend,
    )

#: bench.reports.writing.__all__, listed here so that naming them imports nothing (a test holds the two equal)
__all__ = [
    "ALL_CRITERIA",
    "CRITERIA",
    "FORMATS",
    "LAYOUTS",
    "ActuatorReport",
    "Deviation",
    "GridHitReport",
    "GridPositioningReport",
    "LadderReport",
    "Layout",
    "ReportBase",
    "ReportPaths",
    "RunReport",
    "SIMULATED_BANNER",
    "StabilisationReport",
    "collect",
    "iso_deviations",
    "own_layout",
    "write_comparison",
    "write_report",
    "write_trend",
]


def __getattr__(name: str) -> Any:
    if name in __all__:
        value = getattr(import_module("bench.reports.writing"), name)
        globals()[name] = value  # once: later lookups find it without this function
        return value
    raise AttributeError(f"module 'bench.reports' has no attribute {name!r}")
