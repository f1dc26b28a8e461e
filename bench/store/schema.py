"""Schema versions of the SQLite run store and the migrations between them.

The version lives in SQLite's ``PRAGMA user_version``. Version 0 is the first release's schema (``CREATE TABLE IF
NOT EXISTS`` only, no version recorded). A new store is created at version 0 and migrated forward like any old
file, so a fresh store and a migrated one have the same schema by construction. Opening a file:

- with a version older than :data:`SCHEMA_VERSION`: a backup copy is written next to it first
  (``bench.db.schema-v0.bak``, made with SQLite's online backup, so it is consistent even with a WAL), then each
  migration runs in its own transaction (all of it or none of it);
- with a newer version: refused with :class:`StoreSchemaError`, the file untouched.

Migrations only add (columns, tables, indices); no migration drops or rewrites stored samples. See docs/store.md.
"""

from __future__ import annotations

import socket
import sqlite3
import uuid
from collections.abc import Callable
from pathlib import Path

from bench.errors import ConfigError

__all__ = ["SCHEMA_VERSION", "StoreSchemaError", "backup_path", "default_bench_name", "open_schema"]

#: The schema version this bench writes.
SCHEMA_VERSION = 4

#: Version 0: the tables of the first release, exactly as it created them.
_SCHEMA_V0 = """
CREATE TABLE IF NOT EXISTS campaigns (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE,
    created_utc TEXT NOT NULL,
    notes TEXT NOT NULL DEFAULT ''
);
CREATE TABLE IF NOT EXISTS runs (
    id INTEGER PRIMARY KEY,
    campaign_id INTEGER REFERENCES campaigns(id),
    protocol_name TEXT NOT NULL,
    protocol_version TEXT NOT NULL,
    robot TEXT NOT NULL,
    config_json TEXT NOT NULL,
    settings_json TEXT NOT NULL,
    calibration_ids_json TEXT NOT NULL,
    software_version TEXT NOT NULL,
    git_sha TEXT NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('running', 'completed', 'failed', 'aborted')),
    reason TEXT,
    started_utc TEXT NOT NULL,
    ended_utc TEXT
);
CREATE TABLE IF NOT EXISTS samples (
    id INTEGER PRIMARY KEY,
    run_id INTEGER NOT NULL REFERENCES runs(id),
    step_index INTEGER NOT NULL,
    kind TEXT NOT NULL,
    pose TEXT,
    cycle INTEGER,
    t_s REAL NOT NULL,
    wall_utc TEXT NOT NULL,
    values_json TEXT NOT NULL,
    raw_json TEXT,
    UNIQUE (run_id, step_index)
);
CREATE TABLE IF NOT EXISTS calibrations (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL,
    version INTEGER NOT NULL,
    created_utc TEXT NOT NULL,
    params_json TEXT NOT NULL,
    source_run_id INTEGER REFERENCES runs(id),
    notes TEXT NOT NULL DEFAULT '',
    UNIQUE (name, version)
);
"""


class StoreSchemaError(ConfigError):
    """A store file whose schema this bench cannot use (newer than it, or a failed migration)."""


def default_bench_name() -> str:
    """The bench's name when none is given: the host name of the computer (``socket.gethostname()``)."""
    return socket.gethostname() or "bench"


def _v0_to_v1(db: sqlite3.Connection, bench: str) -> None:
    """Global identity: a UUID and the bench's name on every run, a UUID on every calibration.

    Runs stored before the migration get a fresh UUID each and the name of the bench that migrates the file (the
    file has always lived on one bench).
    """
    db.execute("ALTER TABLE runs ADD COLUMN uuid TEXT")
    db.execute("ALTER TABLE runs ADD COLUMN bench TEXT NOT NULL DEFAULT ''")
    db.execute("ALTER TABLE calibrations ADD COLUMN uuid TEXT")
    for table in ("runs", "calibrations"):
        ids = [row[0] for row in db.execute(f"SELECT id FROM {table} WHERE uuid IS NULL")]
        db.executemany(f"UPDATE {table} SET uuid = ? WHERE id = ?", [(str(uuid.uuid4()), i) for i in ids])
        db.execute(f"CREATE UNIQUE INDEX {table}_uuid ON {table}(uuid)")
    db.execute("UPDATE runs SET bench = ? WHERE bench = ''", (bench,))


def _v1_to_v2(db: sqlite3.Connection, bench: str) -> None:
    """Streamed rows: the frames of a streaming sensor (mice during a move), one narrow row each, stored in
    batches (:meth:`bench.store.database.Store.add_stream_rows`). ``valid`` is 0 for the frame that closes a
    ``SYN_DROPPED`` gap (its counts were lost)."""
    db.execute(
        "CREATE TABLE stream_rows (run_id INTEGER NOT NULL REFERENCES runs(id), stream TEXT NOT NULL, "
        "t_s REAL NOT NULL, dx_counts INTEGER NOT NULL, dy_counts INTEGER NOT NULL, "
        "valid INTEGER NOT NULL CHECK (valid IN (0, 1)))"
    )
    db.execute("CREATE INDEX stream_rows_run ON stream_rows(run_id, stream)")


def _v2_to_v3(db: sqlite3.Connection, bench: str) -> None:
    """A checksum on every sample (:mod:`bench.store.sample_checksum`): the rows stored before get theirs now."""
    from bench.store.sample_checksum import CHECKED_COLUMNS, sample_checksum

    db.execute("ALTER TABLE samples ADD COLUMN checksum TEXT")
    db.create_function("bench_sample_checksum", len(CHECKED_COLUMNS), sample_checksum, deterministic=True)
    db.execute(f"UPDATE samples SET checksum = bench_sample_checksum({', '.join(CHECKED_COLUMNS)})")


def _v3_to_v4(db: sqlite3.Connection, bench: str) -> None:
    """A checksum on every run and calibration record (:mod:`bench.store.record_checksum`), given now to those
    stored before."""
    from bench.store.record_checksum import seal_all

    db.execute("ALTER TABLE runs ADD COLUMN checksum TEXT")
    db.execute("ALTER TABLE calibrations ADD COLUMN checksum TEXT")
    seal_all(db)


#: ``MIGRATIONS[v]`` takes a store from version ``v`` to ``v + 1``.
MIGRATIONS: tuple[Callable[[sqlite3.Connection, str], None], ...] = (_v0_to_v1, _v1_to_v2, _v2_to_v3, _v3_to_v4)
assert len(MIGRATIONS) == SCHEMA_VERSION


def backup_path(path: str | Path, version: int) -> Path:
    """Where the copy of a version-``version`` store is written before it is migrated (never overwritten)."""
    base = Path(f"{path}.schema-v{version}.bak")
    candidate, n = base, 1
    while candidate.exists():
        candidate, n = Path(f"{base}.{n}"), n + 1
    return candidate


def open_schema(db: sqlite3.Connection, path: str, bench: str) -> Path | None:
    """Bring the store behind ``db`` to :data:`SCHEMA_VERSION`; returns the backup written, if any.

    Raises
    ------
    StoreSchemaError
        When the file's version is newer than this bench's, or a migration fails (the file is left as it was).
    """
    (version,) = db.execute("PRAGMA user_version").fetchone()
    if version == SCHEMA_VERSION:
        return None
    # Decide and change under one write lock: two processes creating the same new file (a run starting while the
    # desktop app looks at the store) must not both create it, nor take the other's fresh tables for an old store.
    db.execute("BEGIN IMMEDIATE")
    backup = None
    try:
        (version,) = db.execute("PRAGMA user_version").fetchone()
        if version > SCHEMA_VERSION:
            raise StoreSchemaError(
                f"--store {path}: schema version {version} is newer than this bench's "
                f"({SCHEMA_VERSION}); upgrade bench to open it"
            )
        has_tables = db.execute("SELECT COUNT(*) FROM sqlite_master WHERE name = 'runs'").fetchone()[0] > 0
        if has_tables and version < SCHEMA_VERSION and path != ":memory:":
            backup = backup_path(path, version)
            # read through a second connection: the backup API waits forever on a source in a write transaction
            source, copy = sqlite3.connect(path), sqlite3.connect(backup)
            try:
                source.backup(copy)
            finally:
                source.close()
                copy.close()
        if not has_tables:
            for statement in _SCHEMA_V0.split(";"):
                if statement.strip():
                    db.execute(statement)
        for step in range(version, SCHEMA_VERSION):
            MIGRATIONS[step](db, bench)
            db.execute(f"PRAGMA user_version = {step + 1}")
        db.execute("COMMIT")
    except sqlite3.DatabaseError as exc:
        db.execute("ROLLBACK")
        raise StoreSchemaError(
            f"--store {path}: migration v{version} -> v{SCHEMA_VERSION} failed ({exc}); "
            f"the file is unchanged{f', a copy is in {backup}' if backup else ''}"
        ) from exc
    except BaseException:
        db.execute("ROLLBACK")
        raise
    return backup
