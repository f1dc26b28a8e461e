"""bench.store: the SQLite run store (runs, provenance, calibrations, raw samples), its schema versions, the
sample descriptors, and the tidy-table export; ``bench.store.lab`` is the PostgreSQL lab store (psycopg 3)."""

from bench.store.database import (
    INTERRUPTED,
    RUN_STATUSES,
    CalibrationRecord,
    DuplicateSample,
    RunRecord,
    SampleRecord,
    Store,
    software_git_sha,
)
from bench.store.descriptors import SAMPLE_KINDS, SampleMismatch, validate_sample
from bench.store.export import EXPORT_FORMATS, TIDY_COLUMNS, default_kind, export_run, series_table, tidy_table
from bench.store.ownership import RunOwned
from bench.store.sample_checksum import DamagedSample
from bench.store.schema import SCHEMA_VERSION, StoreSchemaError

__all__ = [
    "EXPORT_FORMATS",
    "INTERRUPTED",
    "RUN_STATUSES",
    "SAMPLE_KINDS",
    "SCHEMA_VERSION",
    "TIDY_COLUMNS",
    "CalibrationRecord",
    "DamagedSample",
    "DuplicateSample",
    "RunOwned",
    "RunRecord",
    "SampleMismatch",
    "SampleRecord",
    "Store",
    "StoreSchemaError",
    "default_kind",
    "export_run",
    "software_git_sha",
    "series_table",
    "tidy_table",
    "validate_sample",
]
