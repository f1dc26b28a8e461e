"""Opening the store's SQLite file, and every database error as one line naming the file and what to do.

- :func:`open_connection` opens a store for writing (WAL, created when missing) or, for the commands that only
  read (``bench runs``, ``bench report``, ``bench export``, the results browser), read-only: such a command never
  creates a file, a table or a journal, and an archive on read-only media can be read.
- A SQLite file that holds tables but no ``runs`` table belongs to another application: it is refused before
  anything is written to it (not even the switch to WAL).
- :class:`GuardedConnection` turns each ``sqlite3.Error`` of a query into :class:`StoreError` (one line: the
  file, SQLite's words, what to do); ``IntegrityError`` passes through for the store to name (a duplicate sample).
- :func:`check_store` runs ``PRAGMA integrity_check`` and ``PRAGMA foreign_key_check`` (``bench store check``),
  then checks every sample against its checksum (:mod:`bench.store.sample_checksum`: a flipped bit in a digit).
"""

from __future__ import annotations

import sqlite3
import time
from pathlib import Path
from typing import Any

from bench.errors import BenchError, ConfigError
from bench.store.record_checksum import damaged_record_lines
from bench.store.sample_checksum import damaged_sample_lines

__all__ = [
    "BUSY_TIMEOUT_S",
    "GuardedConnection",
    "GuardedCursor",
    "StoreError",
    "check_store",
    "open_connection",
    "store_error",
]

#: How long a connection waits for another process that holds the store (SQLite's busy timeout).
BUSY_TIMEOUT_S = 10.0


class StoreError(BenchError):
    """The store file could not be read or written (damaged, locked, read-only, disk full); the message says what
    to do."""


def _advice(path: str, message: str) -> str:
    text = message.lower()
    if "malformed" in text or "not a database" in text or "disk i/o" in text or "corrupt" in text:
        return f"the file is damaged: check it with `bench store check {path}` and work on a backup copy"
    if "locked" in text or "busy" in text:
        return f"another process held it longer than {BUSY_TIMEOUT_S:g} s: retry when it is done"
    if "readonly" in text or "read-only" in text:
        return "the file or its folder is read-only: make it writable or work on a copy"
    if "full" in text:
        return "the disk is full: free space, then resume the run"
    return f"check it with `bench store check {path}`"


def store_error(path: str, exc: sqlite3.Error) -> StoreError:
    """One line for ``exc`` met on the store at ``path``: SQLite's words and what to do."""
    return StoreError(f"store {path}: {exc}; {_advice(path, str(exc))}")


class GuardedCursor:
    """A ``sqlite3.Cursor`` whose errors are :class:`StoreError` lines, as :class:`GuardedConnection`'s."""

    def __init__(self, cursor: sqlite3.Cursor, path: str) -> None:
        self._cursor, self._path = cursor, path

    @property
    def lastrowid(self) -> int | None:
        return self._cursor.lastrowid

    def inserted_id(self) -> int:
        """The rowid of the row this cursor's ``INSERT`` stored."""
        if self._cursor.lastrowid is None:
            raise StoreError(f"store {self._path}: an insert stored no row")
        return self._cursor.lastrowid

    def _guard(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self._cursor, method)(*args)
        except sqlite3.IntegrityError:
            raise
        except sqlite3.Error as exc:
            raise store_error(self._path, exc) from None

    def fetchone(self) -> Any:
        return self._guard("fetchone")

    def fetchall(self) -> list[Any]:
        return self._guard("fetchall")

    def fetchmany(self, size: int) -> list[Any]:
        return self._guard("fetchmany", size)

    def __iter__(self) -> GuardedCursor:
        return self

    def __next__(self) -> Any:
        return self._guard("__next__")


class GuardedConnection:
    """A ``sqlite3.Connection`` whose query errors are :class:`StoreError` naming ``path`` (see the module)."""

    def __init__(self, db: sqlite3.Connection, path: str) -> None:
        self.raw, self.path = db, path

    def execute(self, sql: str, args: Any = ()) -> GuardedCursor:
        try:
            return GuardedCursor(self.raw.execute(sql, args), self.path)
        except sqlite3.IntegrityError:
            raise
        except sqlite3.Error as exc:
            raise store_error(self.path, exc) from None

    def backup(self, target: sqlite3.Connection) -> None:
        self.raw.backup(target)

    def close(self) -> None:
        self.raw.close()


def _use_write_ahead_log(db: sqlite3.Connection) -> None:
    """Switch ``db`` to WAL, waiting for other connections. SQLite answers a journal-mode change that meets another
    connection's lock with "database is locked" at once, without its busy handler (seen when the desktop app reads
    a new store while a run creates it), so the switch is retried here up to the busy timeout."""
    deadline = time.monotonic() + BUSY_TIMEOUT_S
    while True:
        try:
            db.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() > deadline:
                raise
            time.sleep(0.01)


def _refuse_foreign(db: sqlite3.Connection, path: str) -> None:
    """A file with tables but no ``runs`` table is another application's database: refused, untouched."""
    names = [row[0] for row in db.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
    if names and "runs" not in names:
        listed = ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")
        raise ConfigError(
            f"--store {path}: not a bench store (its tables are {listed}; no runs table); left "
            "untouched, expected a bench.db that bench wrote or a new file name"
        )


def open_connection(path: str, *, read_only: bool = False, option: str = "--store") -> sqlite3.Connection:
    """A connection to the store at ``path``: read-only (the file must exist; nothing is created) or for writing
    (WAL, ``synchronous=FULL``, foreign keys on; a missing file is created). Another application's SQLite file is
    refused in either mode before anything is written. ``option`` names where the path came from in a refusal."""
    if "://" in str(path):  # a lab store address where only a file will do (sync's --store, backup, resume, ...)
        from bench.store.lab_connection import redacted

        raise ConfigError(f"{option} {redacted(path)}: a URL, expected a run store file (bench.db) here")
    if path != ":memory:" and not Path(path).parent.is_dir():
        raise ConfigError(f"{option} {path}: folder {Path(path).parent} does not exist")
    if read_only:
        if not Path(path).is_file():
            raise ConfigError(f"{option} {path}: no run store there, expected the bench.db a run wrote (--store)")
        uri = Path(path).resolve().as_uri()
        db = sqlite3.connect(f"{uri}?mode=ro", uri=True, isolation_level=None, timeout=BUSY_TIMEOUT_S)
        try:
            db.execute("SELECT COUNT(*) FROM sqlite_master").fetchone()
        except sqlite3.OperationalError:  # a WAL file on read-only media: no shared-memory file can be made
            db.close()
            db = sqlite3.connect(f"{uri}?immutable=1", uri=True, isolation_level=None, timeout=BUSY_TIMEOUT_S)
    else:
        db = sqlite3.connect(path, isolation_level=None, timeout=BUSY_TIMEOUT_S)
    try:
        _refuse_foreign(db, path)
        if not read_only:
            _use_write_ahead_log(db)
            db.execute("PRAGMA synchronous=FULL")
            db.execute("PRAGMA foreign_keys=ON")
    except BaseException:
        db.close()
        raise
    return db


def check_store(path: str, option: str = "--store") -> list[str]:
    """The problems of the store at ``path``, one line each (empty when sound): SQLite's ``integrity_check``,
    every row whose foreign key names a missing parent (``foreign_key_check``), every run and calibration record that
    fails its checksum, and every sample that fails its checksum or holds JSON that does not parse. Opens read-only (``option``: as :func:`open_connection`)."""
    try:
        db = open_connection(path, read_only=True, option=option)
    except sqlite3.DatabaseError as exc:  # not SQLite, or its header damaged: the one problem there is to report
        return [f"{path}: not a usable bench store ({exc})"]
    # a flipped bit can leave bytes that are not UTF-8: read them as they are, for the checksum to name the row
    db.text_factory = lambda data: data.decode("utf-8", "surrogateescape")
    problems: list[str] = []
    try:
        # one row may hold many messages, one a line, the first under a "*** in database main ***" title
        problems += [
            f"{path}: integrity: {message}"
            for row in db.execute("PRAGMA integrity_check")
            for message in str(row[0]).splitlines()
            if message not in ("ok", "") and not message.startswith("*** in database")
        ]
        problems += [
            f"{path}: table {table} row {rowid}: {parent} id missing (foreign key {fk})"
            for table, rowid, parent, fk in db.execute("PRAGMA foreign_key_check")
        ]
        problems += damaged_record_lines(db, path)
        problems += damaged_sample_lines(db, path)
    except sqlite3.Error as exc:  # a page too damaged to walk: what was found so far, then SQLite's words
        problems.append(f"{path}: {exc}")
    finally:
        db.close()
    return problems
