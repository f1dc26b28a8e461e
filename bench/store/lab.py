"""The lab store: one PostgreSQL database that many benches sync their local SQLite stores into (psycopg 3).

The local file stays the source of truth; the server holds copies, in the schema ``bench``:

- ``bench.runs``: one row per run, keyed by the run's UUID, with its bench, local id, campaign, protocol,
  configuration (``config_json``), robot settings (``settings_json``), calibrations, software version, status (as
  stored, and as its bench read it: ``read_status``), and its local record checksum (:mod:`bench.store.lab_records`);
- ``bench.calibrations``: one row per calibration version, keyed by its UUID, with its local record checksum;
- ``bench.samples``: one row per sample, keyed by ``(run_uuid, step_index)``, every stored column as the local file
  holds it (JSON as text, byte for byte), so :func:`rows_checksum` is equal on both sides, and one typed column per
  declared value column (``x_mm``, ``velocity_pct``, ...: :mod:`bench.store.lab_copy`) for lab-wide queries.

- ``bench.pose_keys``, ``bench.pose_point_sets``: the pose samples folded for the lab-wide summary, kept by a trigger
  as samples arrive (:mod:`bench.store.lab_summary`).

Schema versions: 1 had no typed columns, 2 no pose tables, 3 no checksums, 3 and 4 a pose-points row per sample, 1-4
no record checksums (runs and calibrations synced then carry none until their bench syncs again); a
bench of version 5 adds, fills or refolds what is missing when it first connects.

Sync is idempotent and resumable: runs and calibrations are upserted (the local file wins: a status, a reason, a
registration added by a resume travel on the next sync), and the samples the server lacks are sent in batches, each
one COPY straight into ``bench.samples`` in its own transaction (when another sync of the same file stored some of
its steps first: COPY into a temporary table, then ``INSERT ... ON CONFLICT DO NOTHING``). The runs to send are dealt
to two connections ("lanes", each its own runs, so their pose folds never touch the same keys); each lane has a
sender thread with one batch in flight while this thread reads and formats the next batches (for a large sync on
a machine of 4 cores or more, a producer process reads and formats one lane's: :mod:`bench.store.lab_batches`), so reading the
local file, the server's storing and its pose trigger overlap. A sync killed or cut off loses its open batches'
transactions only; the next sync asks the server which steps it holds and sends the rest, so every sample lands
exactly once. Sync never writes to the local file.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from typing import Any, Self

from bench.store.database import RunRecord, Store
from bench.store.lab_connection import (
    LabServerBusy,
    LabStoreError,
    LabURLError,
    check_lab_url,
    connect,
    is_lab_url,
    redacted,
)
from bench.store.lab_copy import SAMPLE_COLUMNS
from bench.store.lab_records import (
    READ_REASON_SQL,
    READ_STATUS_SQL,
    RUN_CHECK_SQL,
    check_lab_records,
    refuse_damaged_run,
)
from bench.store.lab_schema import LAB_SCHEMA_VERSION
from bench.store.lab_sync import SyncResult, sync_after_run, sync_store
from bench.store.records import from_json

__all__ = [
    "LAB_SCHEMA_VERSION",
    "LabServerBusy",
    "LabStore",
    "LabStoreError",
    "LabURLError",
    "SyncResult",
    "check_lab_url",
    "is_lab_url",
    "open_runs_store",
    "redacted",
    "rows_checksum",
    "sync_after_run",
    "sync_store",
]

_SAMPLE_COLUMNS = ", ".join(SAMPLE_COLUMNS)


def rows_checksum(rows: Iterable[tuple[Any, ...]]) -> str:
    """SHA-256 over a run's sample rows in step order (``Store.stored_rows`` layout), one JSON line per row.

    Equal on the local file and on the server exactly when every stored column of every sample is equal
    (floats compared through their shortest round-trip repr)."""
    digest = hashlib.sha256()
    for row in rows:
        digest.update(json.dumps(list(row), allow_nan=False).encode())
        digest.update(b"\n")
    return digest.hexdigest()


class LabStore:
    """Read-only access to the lab store's runs, the same records as :class:`Store` gives (``id`` is the run's id
    in its bench's file; ``n_samples`` counts the samples synced)."""

    def __init__(self, url: str) -> None:
        self.path = redacted(url)
        self._conn = connect(url)
        self._conn.read_only = True
        found = self._conn.execute("SELECT to_regclass('bench.runs')").fetchone()[0]
        if found is None:
            self._conn.close()
            raise LabStoreError(f"lab store {self.path}: no bench data yet (run bench sync first)")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self._conn.close()

    def runs(self, *, bench: str | None = None, robot: str | None = None, since: str | None = None) -> list[RunRecord]:
        """Every synced run, oldest first, optionally filtered as :meth:`Store.runs` is."""
        clauses, args = [], []
        for clause, value in (("r.bench = %s", bench), ("r.robot = %s", robot), ("r.started_utc >= %s", since)):
            if value is not None:
                clauses.append(clause)
                args.append(value)
        where = "WHERE " + " AND ".join(clauses) if clauses else ""
        rows = self._conn.execute(
            "SELECT r.local_id, r.uuid::text, r.bench, r.campaign, r.protocol_name, r.protocol_version, r.robot,"
            " r.config_json, r.settings_json, r.calibration_ids_json, r.software_version, r.git_sha,"
            f" {READ_STATUS_SQL}, {READ_REASON_SQL}, r.started_utc, r.ended_utc,"
            f" (SELECT count(*) FROM bench.samples s WHERE s.run_uuid = r.uuid), {RUN_CHECK_SQL}"
            f" FROM bench.runs r {where} ORDER BY r.started_utc, r.bench, r.local_id",
            args,
        ).fetchall()
        self._conn.rollback()
        for r in rows:  # each record checked before its JSON is read (as the local store's runs are)
            refuse_damaged_run(f"{r[2]}/{r[0]}", r[17:], self.path)
        return [RunRecord.from_row(r, run_id=r[0], calibration_ids=tuple(from_json(r[9]))) for r in rows]

    def checksum(self, run_uuid: str) -> str:
        """:func:`rows_checksum` of the samples the server holds for ``run_uuid``."""
        rows = self._conn.execute(
            f"SELECT {_SAMPLE_COLUMNS} FROM bench.samples WHERE run_uuid = %s ORDER BY step_index", (run_uuid,)
        )
        result = rows_checksum(rows)
        self._conn.rollback()
        return result

    def check_samples(self) -> tuple[list[str], list[str]]:
        """Every synced sample against its bench's checksum and its typed columns against its JSON
        (:func:`bench.store.lab_check.check_lab_samples`): the damaged samples' lines, and notes on unchecked runs."""
        from bench.store.lab_check import check_lab_samples

        return check_lab_samples(self._conn, self.path)

    def check_records(self) -> tuple[list[str], list[str]]:
        """Every synced run and calibration against its bench's checksum
        (:func:`bench.store.lab_records.check_lab_records`): the damaged records' lines, and notes on unchecked ones."""
        return check_lab_records(self._conn, self.path)

    def query(self, sql: str, args: Any = (), *, settings: Mapping[str, str] | None = None) -> list[tuple[Any, ...]]:
        """Rows of a read-only SQL query over the lab schema (for lab-wide analyses and benchmarks); ``settings``
        (e.g. ``{"work_mem": "256MB"}``) are server settings for this query's transaction only."""
        for name, value in (settings or {}).items():
            self._conn.execute("SELECT set_config(%s, %s, true)", (name, value))
        cursor = self._conn.execute(sql, args)
        rows = cursor.fetchall() if cursor.description else []
        self._conn.rollback()
        return rows


def open_runs_store(spec: str, **store_args: Any) -> Store | LabStore:
    """A :class:`LabStore` for a ``postgresql://`` address, else the SQLite :class:`Store` file."""
    return LabStore(spec) if is_lab_url(spec) else Store(spec, **store_args)
