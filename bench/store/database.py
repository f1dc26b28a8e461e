"""The run store: one SQLite file (WAL) holding campaigns, runs, calibrations and every raw sample.

A run is self-describing: its row carries the protocol name and version, the fully resolved configuration, the
robot settings, the software version, the git SHA and the ids of the calibrations in force, so the stored run is
enough to re-run or re-analyse it. Every sample is committed in its own transaction the moment it is taken
(``synchronous=FULL``), so killing the writer, even with SIGKILL, loses no sample that ``add_sample`` returned
from. The runner starts each commit the moment its sample is taken on a writer thread and moves the robot on
meanwhile (:mod:`bench.store.sample_writer`: the same commit, reported only once durable). A sample carries the
index of the protocol step that produced it; resuming a run skips the stored indices.

The status of a run is ``running`` from before its first sample and is settled by the runner in ``finally``:
``completed``, ``failed`` or ``aborted``, with the reason. A run is owned by the one live process that drives it
(:mod:`bench.store.ownership`); a stored ``running`` run whose owner is gone (killed outright, power lost) reads
as ``interrupted``, with ``bench resume ID`` as the next step, until it is resumed.
"""

from __future__ import annotations

import logging
import sqlite3
import subprocess
import uuid
from collections.abc import Callable, Iterable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any, Self

from bench import __version__
from bench.errors import BenchError, ConfigError
from bench.store.connection import GuardedConnection, open_connection, store_error
from bench.store.ownership import RunLease, owner_of
from bench.store.record_checksum import checked_columns_sql, refuse_damaged, seal_run, stored_records
from bench.store.records import (
    INTERRUPTED,
    RUN_STATUSES,
    CalibrationRecord,
    DuplicateSample,
    RunRecord,
    SampleRecord,
    from_json,
    to_json,
    utc_now,
)
from bench.store.recovery import refuse_if_damaged
from bench.store.sample_rows import CHECKPOINT_RETRY_S, checkpoint_wal, encode_sample, insert_sample_row
from bench.store.schema import SCHEMA_VERSION, StoreSchemaError, default_bench_name, open_schema
from bench.store.store_calibrations import StoreCalibrations
from bench.store.store_samples import StoreSamples

__all__ = [
    "INTERRUPTED",
    "RUN_STATUSES",
    "CalibrationRecord",
    "DuplicateSample",
    "RunRecord",
    "SampleRecord",
    "Store",
    "CHECKPOINT_RETRY_S",
    "checkpoint_wal",
    "encode_sample",
    "insert_sample_row",
    "software_git_sha",
]

_log = logging.getLogger(__name__)


def software_git_sha() -> str:
    """The git commit of the source tree bench runs from, with ``-dirty`` when it has local changes."""
    root = Path(__file__).resolve().parents[2]
    try:
        sha = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5, check=False
        )
        if sha.returncode != 0:
            return "unknown"
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=5,
            check=False,
        )
        return sha.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


class Store(StoreSamples, StoreCalibrations):
    """A SQLite run store (WAL journal, every write committed at once).

    Parameters
    ----------
    path : str or Path
        Database file; created with its tables when missing (``bench.db`` in the working folder by default). An
        older file is migrated after a backup copy is written next to it (``backup``); a newer one is refused
        (see ``bench.store.schema``).
    bench : str, optional
        This bench's name, recorded on every run it starts (default: the host name).
    read_only : bool
        Open for reading only (``bench runs``, ``report``, ``export``, the results browser): the file must exist and
        nothing is created or written (an older schema is still migrated first, with its backup). Opened for
        writing, a store that was not closed cleanly (a run left ``running`` by a process that is gone) is checked
        first and refused when damaged (:mod:`bench.store.recovery`). Another
        application's SQLite file is refused in either mode, untouched; every database error of a query is one
        :class:`bench.store.connection.StoreError` line naming the file and what to do.

    Examples
    --------
    >>> with Store(":memory:") as store:
    ...     run_id = store.start_run(protocol_name="demo", protocol_version="1", robot="pkm5", config={})
    ...     store.add_sample(run_id, 0, values={"x_mm": 1.0}, pose="P1", cycle=1, t_s=0.0)
    ...     store.stored_steps(run_id)
    {0}
    """

    def __init__(self, path: str | Path = "bench.db", *, bench: str | None = None, read_only: bool = False) -> None:
        self.path = str(path)
        self.read_only = read_only
        self._leases: dict[int, RunLease] = {}
        #: the run being resumed (``bench resume``): no new calibration version is written while it is set
        self.resuming: int | None = None
        #: the wall clock a sample's ``wall_utc`` is read from (ISO UTC text); replaceable, e.g. by a clock that jumps
        self.wall_clock: Callable[[], str] = utc_now
        self.bench = bench or default_bench_name()
        self.backup = None
        try:
            raw = open_connection(self.path, read_only=read_only)
        except sqlite3.DatabaseError as exc:
            raise ConfigError(f"--store {self.path}: not a usable bench store ({exc})") from None
        try:
            if read_only:
                (version,) = raw.execute("PRAGMA user_version").fetchone()
                if version > SCHEMA_VERSION:
                    raise StoreSchemaError(
                        f"--store {self.path}: schema version {version} is newer than this "
                        f"bench's ({SCHEMA_VERSION}); upgrade bench to open it"
                    )
                if version < SCHEMA_VERSION:  # an old store is migrated (with its backup) before it is read
                    raw.close()
                    raw = self._migrated()
            else:
                if self.path != ":memory:":  # before anything is written: a damaged store is refused untouched
                    refuse_if_damaged(raw, self.path)
                self.backup = open_schema(raw, self.path, self.bench)
        except sqlite3.DatabaseError as exc:
            raw.close()
            raise ConfigError(f"--store {self.path}: not a usable bench store ({exc})") from None
        except BaseException:
            raw.close()
            raise
        self._db = GuardedConnection(raw, self.path)
        if self.backup is not None:
            _log.warning("store %s migrated to the current schema; the old file is kept as %s", self.path, self.backup)

    def _migrated(self) -> sqlite3.Connection:
        """Migrate the old store at ``self.path`` for a reader; then reopen it read-only."""
        try:
            with Store(self.path, bench=self.bench) as writer:
                self.backup = writer.backup
        except sqlite3.Error as exc:
            raise store_error(self.path, exc) from None
        return open_connection(self.path, read_only=True)

    def __repr__(self) -> str:
        return f"Store({self.path!r})"

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        for run_id in list(self._leases):
            self.release(run_id)
        self._db.close()

    # ---- ownership -------------------------------------------------------------------------------------------

    def claim(self, run_id: int) -> RunLease | None:
        """Own run ``run_id`` from now until :meth:`release` (or :meth:`close`); raises
        :class:`bench.store.ownership.RunOwned`, naming the owner, when another live process owns it. Claiming a run
        this store already owns returns its lease. A store in memory is owned by its process alone (None)."""
        run_id = int(run_id)
        if self.path == ":memory:":
            return None
        if run_id not in self._leases:
            self._leases[run_id] = RunLease(self.path, run_id)
        return self._leases[run_id]

    def release(self, run_id: int) -> None:
        """Give up the ownership of run ``run_id`` (nothing when this store does not own it)."""
        lease = self._leases.pop(int(run_id), None)
        if lease is not None:
            lease.release()

    def reads_as(self, run_id: int, status: str, reason: str | None) -> tuple[str, str | None]:
        """The status and reason run ``run_id`` reads as, given those stored: a stored ``running`` run without a live
        owner reads as interrupted, naming the owner and the next step."""
        if status != "running" or self.path == ":memory:" or run_id in self._leases:
            return status, reason
        owner = owner_of(self.path, run_id)
        if owner is not None and owner.alive:
            return status, reason or f"owned by {owner.describe()}"
        gone = f"its owner ({owner.describe()}) is gone" if owner else "no process owns it"
        return INTERRUPTED, f"{gone}; next: bench resume {run_id}"

    def checkpoint(self) -> None:
        """Copy the write-ahead log into the database file, so that the ``.db`` file alone (a backup of "the store
        file", a copy taken after a crash) holds every committed sample. The runner calls it at every checkpoint
        step and at the end of every run segment.

        SQLite's PASSIVE mode blocks nothing, but it cannot copy the log past the snapshot of a reader that began
        before the last commit (``bench runs``, the results browser, a test's poll): it then copies part of the
        log. Such readers last milliseconds, so the checkpoint is retried until the whole log is in the file or
        :data:`CHECKPOINT_RETRY_S` has passed (then a warning: the next checkpoint copies the rest)."""
        checkpoint_wal(self._db)

    def backup_to(self, destination: str | Path) -> Path:
        """A consistent copy of the whole store at ``destination``, taken with SQLite's online backup API (safe
        while a run is writing); refuses to overwrite an existing file."""
        destination = Path(destination)
        if destination.exists():
            raise ConfigError(f"backup: {destination} exists, expected a new file name")
        if not destination.parent.is_dir():
            raise ConfigError(f"backup: folder {destination.parent} does not exist, expected an existing folder")
        target = sqlite3.connect(destination)
        try:
            self._db.backup(target)
        except sqlite3.Error as exc:
            target.close()
            destination.unlink(missing_ok=True)
            raise BenchError(f"{self.path}: backup to {destination} failed ({exc})") from None
        target.close()
        return destination

    # ---- campaigns -------------------------------------------------------------------------------------------

    def campaign_id(self, name: str, notes: str = "") -> int:
        """The id of campaign ``name``, created on first use."""
        self._db.execute(
            "INSERT OR IGNORE INTO campaigns (name, created_utc, notes) VALUES (?, ?, ?)", (name, utc_now(), notes)
        )
        return int(self._db.execute("SELECT id FROM campaigns WHERE name = ?", (name,)).fetchone()[0])

    # ---- runs ------------------------------------------------------------------------------------------------

    def start_run(
        self,
        *,
        protocol_name: str,
        protocol_version: str,
        robot: str,
        config: Mapping[str, Any],
        settings: Mapping[str, Any] | None = None,
        calibration_ids: Iterable[int] = (),
        campaign: str | None = None,
    ) -> int:
        """Create a run with status ``running``, its full provenance, a new UUID and this bench's name; returns the
        run id (an integer local to this file; the UUID is the run's name everywhere else)."""
        campaign_id = self.campaign_id(campaign) if campaign else None
        row = (
            str(uuid.uuid4()),
            self.bench,
            campaign_id,
            protocol_name,
            str(protocol_version),
            robot,
            to_json(dict(config), "config"),
            to_json(dict(settings or {}), "settings"),
            to_json(sorted(int(i) for i in calibration_ids), "calibration_ids"),
            __version__,
            software_git_sha(),
            utc_now(),
        )
        # owned before anyone can read it: the run and its lock appear together (the commit comes after the lock)
        run_id = None
        self._db.execute("BEGIN IMMEDIATE")
        try:
            cursor = self._db.execute(
                "INSERT INTO runs (uuid, bench, campaign_id, protocol_name, protocol_version, robot, config_json,"
                " settings_json, calibration_ids_json, software_version, git_sha, status, started_utc)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 'running', ?)",
                row,
            )
            run_id = cursor.inserted_id()
            seal_run(self._db, run_id)
            self.claim(run_id)
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            if run_id is not None:
                self.release(run_id)
            raise
        self.checkpoint()  # from its first moment, a copy of the .db file alone is a store holding the run
        return run_id

    def set_status(self, run_id: int, status: str, reason: str | None = None) -> None:
        """Settle (or reopen, with ``running``) the status of a run; ``reason`` says why it failed or stopped."""
        if status not in RUN_STATUSES:
            raise ConfigError(f"store: status = {status!r}, expected one of {', '.join(RUN_STATUSES)}")
        record = self.run(run_id)
        now = utc_now()
        ended = None if status == "running" else now
        # every settle and every reopening is kept in the run's history (the report lists each abort and resume)
        event = {
            "utc": now,
            "event": "resumed" if status == "running" else status,
            **({"reason": reason} if reason else {}),
        }
        settings = {**record.settings, "history": [*record.settings.get("history", ()), event]}
        self._db.execute("BEGIN IMMEDIATE")
        try:
            self._db.execute(
                "UPDATE runs SET status = ?, reason = ?, ended_utc = ?, settings_json = ? WHERE id = ?",
                (status, reason, ended, to_json(settings, "settings"), run_id),
            )
            seal_run(self._db, run_id)
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise

    def add_registration(self, run_id: int, registration: Mapping[str, Any]) -> int:
        """Append one registration of the run's instruments (a run segment, :mod:`bench.rigs.registration`) to its
        settings' ``registrations`` list, in one transaction; returns its number (1 for the first). It records
        ``after_t_s``, the largest ``t_s`` stored so far: the samples after it are the new segment's, whatever the
        wall clock says (:mod:`bench.store.registrations`)."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            row = self._db.execute("SELECT settings_json FROM runs WHERE id = ?", (int(run_id),)).fetchone()
            if row is None:
                raise ConfigError(f"run {run_id}: no such run in {self.path}")
            settings = from_json(row[0])
            entries = settings.setdefault("registrations", [])
            (after_t_s,) = self._db.execute("SELECT MAX(t_s) FROM samples WHERE run_id = ?", (int(run_id),)).fetchone()
            entries.append(
                {**registration, "segment": len(entries) + 1, **({} if after_t_s is None else {"after_t_s": after_t_s})}
            )
            self._db.execute(
                "UPDATE runs SET settings_json = ? WHERE id = ?", (to_json(settings, "settings"), int(run_id))
            )
            seal_run(self._db, run_id)
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        return len(entries)

    def run(self, run_id: int) -> RunRecord:
        """The stored run ``run_id``; ``ConfigError`` names the id when there is none."""
        rows = self._select_runs("WHERE r.id = ?", (int(run_id),))
        if not rows:
            raise ConfigError(f"run {run_id}: no such run in {self.path}")
        return rows[0]

    def runs(self, *, bench: str | None = None, robot: str | None = None, since: str | None = None) -> list[RunRecord]:
        """Every run, oldest first; optionally only those of one bench, of one robot, started on or after ``since``
        (an ISO date or UTC time, e.g. ``2026-11-01``)."""
        clauses, args = [], []
        for column, value in (("r.bench = ?", bench), ("r.robot = ?", robot), ("r.started_utc >= ?", since)):
            if value is not None:
                clauses.append(column)
                args.append(value)
        return self._select_runs("WHERE " + " AND ".join(clauses) if clauses else "", tuple(args))

    def stored_records(self, table: str) -> list[tuple[int, tuple[Any, ...], str]]:
        """The ``runs`` or ``calibrations`` records exactly as stored, each checked against its checksum first:
        ``(id, checked fields, checksum)`` (:func:`bench.store.record_checksum.stored_records`; what the lab sync
        sends)."""
        return stored_records(self._db, table, self.path)

    def _select_runs(self, where: str, args: tuple[Any, ...]) -> list[RunRecord]:
        query = (
            "SELECT r.id, r.uuid, r.bench, c.name, r.protocol_name, r.protocol_version, r.robot, r.config_json,"
            " r.settings_json,"
            " r.calibration_ids_json, r.software_version, r.git_sha, r.status, r.reason, r.started_utc,"
            " r.ended_utc, (SELECT COUNT(*) FROM samples s WHERE s.run_id = r.id),"
            f" {checked_columns_sql('runs', 'r')}, r.checksum"
            f" FROM runs r LEFT JOIN campaigns c ON c.id = r.campaign_id {where} ORDER BY r.id"
        )
        records = []
        for row in self._db.execute(query, args).fetchall():
            # the record is checked before its JSON is read: a changed byte is refused, never parsed as something else
            refuse_damaged("runs", row[0], row[17:-1], row[-1], self.path)
            status, reason = self.reads_as(row[0], row[12], row[13])
            record = RunRecord.from_row(row, run_id=row[0], calibration_ids=tuple(from_json(row[9])))
            records.append(replace(record, status=status, reason=reason))
        return records
