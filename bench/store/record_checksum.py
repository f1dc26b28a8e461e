"""A checksum on every stored run and calibration record, as on every sample (:mod:`bench.store.sample_checksum`).

A run's configuration and settings (the protocol's parameters, the instruments' registrations, the abort and resume
history) and a calibration's parameters decide what later runs command and how a report reads the samples: one
changed digit in a stored ``params_json`` would move every run commanded by that calibration, silently. Each
``runs`` and ``calibrations`` row therefore carries ``checksum``: the SHA-256 (hex) of the columns bench writes
(:data:`RUN_CHECKED_COLUMNS`, :data:`CALIBRATION_CHECKED_COLUMNS`), hashed as a sample's are (columns joined by
U+001F, NULL as U+0000). A run's row is re-sealed in the same transaction as each change bench makes to it (its
status, its settings' history and registrations); a calibration never changes once stored.

Reading a run or a calibration through :class:`bench.store.Store` recomputes it and refuses the record in one line
(:class:`DamagedRecord`) naming it and ``bench store check``, which lists every damaged record. A store older than
schema version 4 gets its records' checksums when it is migrated (they vouch for the rows from then on).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Sequence
from typing import Any

from bench.errors import BenchError
from bench.store.sample_checksum import CHANGED, NO_CHECKSUM, hash_fields

__all__ = [
    "CALIBRATION_CHECKED_COLUMNS",
    "RUN_CHECKED_COLUMNS",
    "DamagedRecord",
    "checked_columns_sql",
    "damaged_record_lines",
    "record_checksum",
    "record_problem",
    "refuse",
    "refuse_damaged",
    "seal_run",
    "seal_all",
    "stored_records",
]

#: The ``runs`` columns the checksum covers, in the order hashed: every column bench writes.
RUN_CHECKED_COLUMNS = (
    "uuid",
    "bench",
    "campaign",  # the campaign's name (the runs row holds its local id): a copy elsewhere can be checked alike
    "protocol_name",
    "protocol_version",
    "robot",
    "config_json",
    "settings_json",
    "calibration_ids_json",
    "software_version",
    "git_sha",
    "status",
    "reason",
    "started_utc",
    "ended_utc",
)
#: The ``calibrations`` columns the checksum covers, in the order hashed.
CALIBRATION_CHECKED_COLUMNS = ("uuid", "name", "version", "created_utc", "params_json", "source_run_id", "notes")
_TABLE_COLUMNS = {"runs": RUN_CHECKED_COLUMNS, "calibrations": CALIBRATION_CHECKED_COLUMNS}
_SINGULAR = {"runs": "run", "calibrations": "calibration"}


class DamagedRecord(BenchError):
    """A stored run or calibration whose bytes no longer match their checksum: it is refused."""


def record_checksum(*fields: object) -> str:
    """SHA-256 (hex) of one record's checked columns, in their order: integers in decimal, text as stored, NULL as
    U+0000, joined by U+001F (as :func:`bench.store.sample_checksum.sample_checksum`)."""
    return hash_fields(None if f is None else str(f) for f in fields)


def record_problem(fields: Sequence[Any], checksum: str | None) -> str | None:
    """Why a record's checked ``fields`` fail their ``checksum``, or None when they match."""
    if checksum is None:
        return NO_CHECKSUM
    if record_checksum(*fields) != checksum:
        return CHANGED
    return None


def refuse(table: str, record_id: int | str, problem: str | None, path: str) -> None:
    """Raise :class:`DamagedRecord` in one line naming the ``table`` record ``record_id`` (an id, or ``BENCH/ID``
    in the lab store) and its ``problem``, when there is one."""
    if problem is not None:
        raise DamagedRecord(
            f"store {path}: {_SINGULAR[table]} {record_id} is damaged: {problem}; it is refused, nothing computed "
            f"from it: list the damage with `bench store check {path}` and read a backup copy"
        )


def refuse_damaged(table: str, record_id: int | str, fields: Sequence[Any], checksum: str | None, path: str) -> None:
    """Raise :class:`DamagedRecord` in one line when the ``table`` row ``record_id`` (its checked ``fields``, in
    the order of its columns above) fails its ``checksum``."""
    refuse(table, record_id, record_problem(fields, checksum), path)


def checked_columns_sql(table: str, alias: str) -> str:
    """The select list of ``table``'s checked columns, the row aliased ``alias`` (a run's campaign by its name)."""
    return ", ".join(
        f"(SELECT c.name FROM campaigns c WHERE c.id = {alias}.campaign_id)"
        if column == "campaign"
        else f"{alias}.{column}"
        for column in _TABLE_COLUMNS[table]
    )


def _select(table: str, where: str = "") -> str:
    return f"SELECT t.id, {checked_columns_sql(table, 't')}, t.checksum FROM {table} t {where}"


def seal_run(db: Any, run_id: int) -> None:
    """Store the checksum of run ``run_id`` as it now stands (inside the transaction that changed it)."""
    row = db.execute(_select("runs", "WHERE t.id = ?"), (int(run_id),)).fetchone()
    db.execute("UPDATE runs SET checksum = ? WHERE id = ?", (record_checksum(*row[1:-1]), int(run_id)))


def seal_all(db: sqlite3.Connection) -> None:
    """Give every run and calibration its checksum (the migration to schema version 4)."""
    for table in _TABLE_COLUMNS:
        rows = db.execute(_select(table)).fetchall()
        db.executemany(
            f"UPDATE {table} SET checksum = ? WHERE id = ?", [(record_checksum(*r[1:-1]), r[0]) for r in rows]
        )


def stored_records(db: Any, table: str, path: str) -> list[tuple[int, tuple[Any, ...], str]]:
    """Every ``table`` record exactly as stored, by id: ``(id, checked fields, checksum)``, each checked first
    (:class:`DamagedRecord` for a damaged one): what the lab sync sends with its checksum, so that the lab's copy is
    checked against the bytes this store sealed."""
    records = []
    for record_id, *fields, checksum in db.execute(_select(table, "ORDER BY t.id")).fetchall():
        refuse_damaged(table, record_id, fields, checksum, path)
        records.append((record_id, tuple(fields), checksum))
    return records


def damaged_record_lines(db: sqlite3.Connection, path: str) -> Iterable[str]:
    """One line per damaged run or calibration of the store behind ``db`` (for ``bench store check``); nothing for
    a store older than schema version 4 (opening it with bench migrates it)."""
    for table in _TABLE_COLUMNS:
        if "checksum" not in {row[1] for row in db.execute(f"PRAGMA table_info({table})")}:
            continue
        for record_id, *fields, checksum in db.execute(_select(table, "ORDER BY t.id")):
            problem = record_problem(fields, checksum)
            if problem is not None:
                yield f"{path}: {_SINGULAR[table]} {record_id} ({table} row {record_id}): {problem}"
