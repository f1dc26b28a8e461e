"""bench.store: the SQLite run store (runs, provenance, calibrations, raw samples) and the tidy-table export."""

from bench.store.database import (
    RUN_STATUSES,
    CalibrationRecord,
    DuplicateSample,
    RunRecord,
    SampleRecord,
    Store,
    software_git_sha,
)
from bench.store.export import EXPORT_FORMATS, TIDY_COLUMNS, export_run, series_table, tidy_table

__all__ = [
    "EXPORT_FORMATS",
    "RUN_STATUSES",
    "TIDY_COLUMNS",
    "CalibrationRecord",
    "DuplicateSample",
    "RunRecord",
    "SampleRecord",
    "Store",
    "export_run",
    "software_git_sha",
    "series_table",
    "tidy_table",
]
