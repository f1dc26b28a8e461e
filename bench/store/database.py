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

import json
import logging
import math
import sqlite3
import subprocess
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self

from bench import __version__
from bench.errors import BenchError, ConfigError
from bench.store.connection import GuardedConnection, open_connection, store_error
from bench.store.ownership import RunLease, owner_of
from bench.store.recovery import refuse_if_damaged
from bench.store.sample_checksum import CHECKED_COLUMNS, parse_sample, sample_checksum
from bench.store.schema import SCHEMA_VERSION, StoreSchemaError, default_bench_name, open_schema

__all__ = [
    "INTERRUPTED",
    "RUN_STATUSES",
    "CalibrationRecord",
    "DuplicateSample",
    "RunRecord",
    "SampleRecord",
    "Store",
    "checkpoint_wal",
    "encode_sample",
    "insert_sample_row",
    "software_git_sha",
]

_log = logging.getLogger(__name__)

#: The closed set of stored run statuses.
RUN_STATUSES = ("running", "completed", "failed", "aborted")
#: The status a stored ``running`` run reads as when no live process owns it (derived when read, never stored).
INTERRUPTED = "interrupted"
#: How long a checkpoint retries while a reader's older snapshot keeps part of the log out of the file, s.
CHECKPOINT_RETRY_S = 0.5


class DuplicateSample(BenchError):
    """A sample for a step that already has one: resuming must skip stored steps, never store them twice."""


@dataclass(frozen=True)
class RunRecord:
    """One stored run, as read back from the ``runs`` table."""

    id: int
    uuid: str
    bench: str
    campaign: str | None
    protocol_name: str
    protocol_version: str
    robot: str
    config: dict[str, Any]
    settings: dict[str, Any]
    calibration_ids: tuple[int, ...]
    software_version: str
    git_sha: str
    status: str
    reason: str | None
    started_utc: str
    ended_utc: str | None
    n_samples: int

    @property
    def simulated(self) -> bool:
        """True for a run on simulators (the simulated rig or a station's rehearsal): its settings name the
        simulator it ran on."""
        return "simulator" in self.settings

    def as_dict(self) -> dict[str, Any]:
        """Plain, JSON-ready form (used by ``bench runs --json``), with ``simulated``."""
        out = dict(self.__dict__)
        out["calibration_ids"] = list(self.calibration_ids)
        out["simulated"] = self.simulated
        return out


@dataclass(frozen=True)
class SampleRecord:
    """One raw sample: the step that produced it, where and when, its values (unit in every key) and raw data."""

    run_id: int
    step_index: int
    kind: str
    pose: str | None
    cycle: int | None
    t_s: float
    wall_utc: str
    values: dict[str, float]
    raw: Any


@dataclass(frozen=True)
class CalibrationRecord:
    """One version of a named calibration (e.g. ``mouse_xy``), with its parameters and the run it came from."""

    id: int
    uuid: str
    name: str
    version: int
    created_utc: str
    params: dict[str, Any]
    source_run_id: int | None
    notes: str


def _utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


def _to_json(value: Any, field: str) -> str:
    try:
        return json.dumps(value, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"store: {field} = {value!r:.80}, expected JSON-serialisable finite values ({exc})") from exc


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


def encode_sample(
    run_id: int,
    step_index: int,
    *,
    values: Mapping[str, float],
    kind: str,
    pose: str | None,
    cycle: int | None,
    t_s: float,
    raw: Any,
    wall_clock: Callable[[], str] = _utc_now,
) -> tuple:
    """The ``samples`` row of one sample, its ``wall_utc`` now by ``wall_clock`` (when it was taken); a value that
    is not a finite number, or raw data that is not JSON, raises ``ConfigError`` here, before anything is
    written."""
    for key, value in values.items():
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"run {run_id} step {step_index}: {key} = {value!r}, expected a finite number")
    columns = (
        int(step_index),
        kind,
        pose,
        cycle,
        float(t_s),
        wall_clock(),
        _to_json({k: float(v) for k, v in values.items()}, "values"),
        None if raw is None else _to_json(raw, "raw"),
    )
    return (int(run_id), *columns, sample_checksum(*columns))


def checkpoint_wal(db: GuardedConnection) -> None:
    """:meth:`Store.checkpoint` on the connection ``db`` (any connection to the store copies the shared log)."""
    deadline = time.monotonic() + CHECKPOINT_RETRY_S
    try:
        while True:
            _busy, log_frames, copied = db.execute("PRAGMA wal_checkpoint(PASSIVE)").fetchone()
            if copied >= log_frames:  # all of it (-1, -1: not in WAL mode, a store in memory)
                return
            if time.monotonic() > deadline:
                _log.warning(
                    "store %s: checkpoint copied %d of %d log frames (a reader held an older snapshot for %g s)",
                    db.path,
                    copied,
                    log_frames,
                    CHECKPOINT_RETRY_S,
                )
                return
            time.sleep(0.005)
    except sqlite3.Error as exc:
        raise BenchError(f"{db.path}: cannot checkpoint the store ({exc})") from None


def insert_sample_row(db: GuardedConnection, row: tuple) -> None:
    """Insert and commit one row of :func:`encode_sample` on ``db`` (in its own transaction: ``synchronous=FULL``
    makes it durable before this returns)."""
    try:
        db.execute(
            "INSERT INTO samples (run_id, step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json,"
            " checksum) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            row,
        )
    except sqlite3.IntegrityError as exc:
        if "UNIQUE" in str(exc):
            raise DuplicateSample(f"run {row[0]}: step {row[1]} already has a stored sample") from exc
        raise ConfigError(f"run {row[0]}: no such run in {db.path}") from exc


class Store:
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
        self.wall_clock: Callable[[], str] = _utc_now
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

    def _reads_as(self, run_id: int, status: str, reason: str | None) -> tuple[str, str | None]:
        """A stored ``running`` run without a live owner reads as interrupted, naming the owner and the next step."""
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
            "INSERT OR IGNORE INTO campaigns (name, created_utc, notes) VALUES (?, ?, ?)", (name, _utc_now(), notes)
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
            _to_json(dict(config), "config"),
            _to_json(dict(settings or {}), "settings"),
            _to_json(sorted(int(i) for i in calibration_ids), "calibration_ids"),
            __version__,
            software_git_sha(),
            _utc_now(),
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
            run_id = int(cursor.lastrowid)
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
        now = _utc_now()
        ended = None if status == "running" else now
        # every settle and every reopening is kept in the run's history (the report lists each abort and resume)
        event = {
            "utc": now,
            "event": "resumed" if status == "running" else status,
            **({"reason": reason} if reason else {}),
        }
        settings = {**record.settings, "history": [*record.settings.get("history", ()), event]}
        self._db.execute(
            "UPDATE runs SET status = ?, reason = ?, ended_utc = ?, settings_json = ? WHERE id = ?",
            (status, reason, ended, _to_json(settings, "settings"), run_id),
        )

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
            settings = json.loads(row[0])
            entries = settings.setdefault("registrations", [])
            (after_t_s,) = self._db.execute("SELECT MAX(t_s) FROM samples WHERE run_id = ?", (int(run_id),)).fetchone()
            entries.append(
                {**registration, "segment": len(entries) + 1, **({} if after_t_s is None else {"after_t_s": after_t_s})}
            )
            self._db.execute(
                "UPDATE runs SET settings_json = ? WHERE id = ?", (_to_json(settings, "settings"), int(run_id))
            )
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

    def _select_runs(self, where: str, args: tuple) -> list[RunRecord]:
        query = (
            "SELECT r.id, r.uuid, r.bench, c.name, r.protocol_name, r.protocol_version, r.robot, r.config_json,"
            " r.settings_json,"
            " r.calibration_ids_json, r.software_version, r.git_sha, r.status, r.reason, r.started_utc,"
            " r.ended_utc, (SELECT COUNT(*) FROM samples s WHERE s.run_id = r.id)"
            f" FROM runs r LEFT JOIN campaigns c ON c.id = r.campaign_id {where} ORDER BY r.id"
        )
        return [
            RunRecord(
                id=row[0],
                uuid=row[1],
                bench=row[2],
                campaign=row[3],
                protocol_name=row[4],
                protocol_version=row[5],
                robot=row[6],
                config=json.loads(row[7]),
                settings=json.loads(row[8]),
                calibration_ids=tuple(json.loads(row[9])),
                software_version=row[10],
                git_sha=row[11],
                status=status,
                reason=reason,
                started_utc=row[14],
                ended_utc=row[15],
                n_samples=row[16],
            )
            for row in self._db.execute(query, args).fetchall()
            for status, reason in (self._reads_as(row[0], row[12], row[13]),)
        ]

    # ---- samples ---------------------------------------------------------------------------------------------

    def add_sample(
        self,
        run_id: int,
        step_index: int,
        *,
        values: Mapping[str, float],
        kind: str = "pose",
        pose: str | None = None,
        cycle: int | None = None,
        t_s: float,
        raw: Any = None,
    ) -> None:
        """Store one sample and commit it before returning.

        Parameters
        ----------
        run_id, step_index : int
            The run and the index of the protocol step that took the sample (unique per run).
        values : mapping of str to float
            Measured and commanded values, the unit in every key (``x_mm``, ``cmd_x_mm``, ``load_kg``).
        kind : str
            What the sample is: ``pose`` (an attained pose), ``calliper``, ``mouse``...
        pose, cycle : str, int, optional
            Pose label and cycle number (1-based) for pose-type tests.
        t_s : float
            Seconds since the run started, in the run's time base (its settings' ``time_base``: wall seconds on
            hardware, simulated seconds on a sped-up simulator).
        raw : JSON-serialisable, optional
            The raw counts, bytes (as hex) or readings the values were computed from.
        """
        self.insert_sample(
            encode_sample(
                run_id,
                step_index,
                values=values,
                kind=kind,
                pose=pose,
                cycle=cycle,
                t_s=t_s,
                raw=raw,
                wall_clock=self.wall_clock,
            )
        )

    def insert_sample(self, row: tuple) -> None:
        """Insert and commit one row of :func:`encode_sample` before returning (:meth:`add_sample` in two parts:
        :class:`bench.store.sample_writer.SampleWriter` encodes a sample when it is taken and commits it on its
        writer thread)."""
        insert_sample_row(self._db, row)

    def stored_steps(self, run_id: int) -> set[int]:
        """Indices of the steps of ``run_id`` whose sample is stored."""
        return {row[0] for row in self._db.execute("SELECT step_index FROM samples WHERE run_id = ?", (run_id,))}

    def samples(self, run_id: int, kind: str | None = None) -> list[SampleRecord]:
        """The samples of a run in step order, optionally of one ``kind`` only. Each is checked against its checksum
        as it is read: a damaged one raises :class:`bench.store.sample_checksum.DamagedSample` naming the run and
        the step, so nothing is computed from a changed number."""
        query = (
            f"SELECT {', '.join(CHECKED_COLUMNS)}, checksum FROM samples"
            " WHERE run_id = ?" + (" AND kind = ?" if kind else "") + " ORDER BY step_index"
        )
        args = (run_id, kind) if kind else (run_id,)
        samples = []
        for row in self._db.execute(query, args):
            values, raw = parse_sample(run_id, row, self.path)
            samples.append(
                SampleRecord(
                    run_id=run_id,
                    step_index=row[0],
                    kind=row[1],
                    pose=row[2],
                    cycle=row[3],
                    t_s=row[4],
                    wall_utc=row[5],
                    values=values,
                    raw=raw,
                )
            )
        return samples

    def stored_rows(self, run_id: int, after_step: int = -1, *, extract: Sequence[str] = ()) -> Iterator[tuple]:
        """The samples of a run after step ``after_step`` exactly as stored, in step order: ``(step_index, kind,
        pose, cycle, t_s, wall_utc, values_json, raw_json)`` with the JSON unparsed (what sync sends and what
        :func:`bench.store.lab.rows_checksum` hashes); with ``extract`` (two or more value names) two more items,
        the row's stored checksum and the JSON array of those values as stored (``null`` where absent; SQLite's
        ``json_extract``, number text kept): what the lab sync sends."""
        paths = "".join(", ?" for _ in extract)
        return self._db.execute(
            "SELECT step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json"
            + (f", checksum, json_extract(values_json{paths})" if extract else "")
            + " FROM samples WHERE run_id = ? AND step_index > ? ORDER BY step_index",
            (*(f"$.{name}" for name in extract), int(run_id), int(after_step)),
        )

    # ---- streamed rows ---------------------------------------------------------------------------------------

    def add_stream_rows(self, run_id: int, stream: str, t_s, dx_counts, dy_counts, valid) -> int:
        """Store one batch of a streaming sensor's frames (narrow rows) in one transaction, committed before
        returning: one fsync for the batch, so a stream of thousands of frames a second keeps the guarantee of
        :meth:`add_sample` for every batch this returned from (:class:`bench.store.streams.StreamWriter` batches).

        Parameters
        ----------
        run_id : int
            The run the stream belongs to.
        stream : str
            Which sensor (``mouse_xy``).
        t_s : array_like of float, shape (n,)
            Each frame's time (s, the sensor's clock); finite.
        dx_counts, dy_counts : array_like of int, shape (n,)
            Each frame's counts.
        valid : array_like of bool, shape (n,)
            False for a frame that closes a gap of lost counts.

        Returns the number of rows stored.
        """
        import itertools

        import numpy as np

        t = np.asarray(t_s, dtype=float)
        columns = (np.asarray(dx_counts, np.int64), np.asarray(dy_counts, np.int64), np.asarray(valid, bool))
        if any(c.shape != t.shape for c in columns) or t.ndim != 1:
            raise ConfigError(
                f"run {run_id} stream {stream}: t_s, dx_counts, dy_counts and valid have shapes "
                f"{[t.shape, *(c.shape for c in columns)]}, expected one length"
            )
        if not np.isfinite(t).all():
            bad = int(np.flatnonzero(~np.isfinite(t))[0])
            raise ConfigError(f"run {run_id} stream {stream}: t_s[{bad}] = {float(t[bad])!r}, expected a finite number")
        rows = zip(
            itertools.repeat(int(run_id)),
            itertools.repeat(stream),
            t.tolist(),
            columns[0].tolist(),
            columns[1].tolist(),
            columns[2].astype(int).tolist(),
        )
        raw = self._db.raw
        try:
            raw.execute("BEGIN IMMEDIATE")  # the write lock now, under the busy timeout, as every writer here
            raw.executemany(
                "INSERT INTO stream_rows (run_id, stream, t_s, dx_counts, dy_counts, valid) VALUES (?, ?, ?, ?, ?, ?)",
                rows,
            )
            raw.execute("COMMIT")
        except sqlite3.Error as exc:
            if raw.in_transaction:
                raw.execute("ROLLBACK")
            if isinstance(exc, sqlite3.IntegrityError):
                raise ConfigError(f"run {run_id}: no such run in {self.path}") from exc
            raise store_error(self.path, exc) from None
        return len(t)

    def stream_rows(self, run_id: int, stream: str) -> tuple:
        """The stored frames of one stream of a run in the order stored: arrays ``(t_s, dx_counts, dy_counts,
        valid)``."""
        import numpy as np

        rows = self._db.execute(
            "SELECT t_s, dx_counts, dy_counts, valid FROM stream_rows WHERE run_id = ? AND stream = ? ORDER BY rowid",
            (int(run_id), stream),
        ).fetchall()
        table = np.array(rows, dtype=float).reshape(-1, 4)
        return table[:, 0], table[:, 1].astype(np.int64), table[:, 2].astype(np.int64), table[:, 3] != 0

    def sample_kinds(self, run_id: int) -> dict[str, int]:
        """How many samples of each kind run ``run_id`` holds, most frequent first."""
        rows = self._db.execute(
            "SELECT kind, COUNT(*) FROM samples WHERE run_id = ? GROUP BY kind ORDER BY COUNT(*) DESC, kind", (run_id,)
        )
        return {kind: count for kind, count in rows}

    # ---- calibrations ----------------------------------------------------------------------------------------

    def add_calibration(
        self, name: str, params: Mapping[str, Any], *, source_run_id: int | None = None, notes: str = ""
    ) -> CalibrationRecord:
        """Store a new version of calibration ``name`` (versions count from 1) and return it."""
        self._db.execute("BEGIN IMMEDIATE")
        try:
            (latest,) = self._db.execute(
                "SELECT COALESCE(MAX(version), 0) FROM calibrations WHERE name = ?", (name,)
            ).fetchone()
            cursor = self._db.execute(
                "INSERT INTO calibrations (uuid, name, version, created_utc, params_json, source_run_id, notes)"
                " VALUES (?, ?, ?, ?, ?, ?, ?)",
                (
                    str(uuid.uuid4()),
                    name,
                    latest + 1,
                    _utc_now(),
                    _to_json(dict(params), "params"),
                    source_run_id,
                    notes,
                ),
            )
            self._db.execute("COMMIT")
        except BaseException:
            self._db.execute("ROLLBACK")
            raise
        return self.calibration_by_id(int(cursor.lastrowid))

    def ensure_calibration(self, name: str, params: Mapping[str, Any], *, notes: str = "") -> CalibrationRecord:
        """The latest version of ``name`` if its parameters equal ``params``, else a new version with them; while
        :attr:`resuming` a run, a new version is refused instead (a refused resume writes nothing)."""
        try:
            latest = self.calibration(name)
        except ConfigError:
            latest = None
        if latest is not None and latest.params == json.loads(_to_json(dict(params), "params")):
            return latest
        if self.resuming is not None:
            now = f"version {latest.version} is the latest" if latest else "none is stored"
            raise ConfigError(
                f"run {self.resuming}: calibration {name!r} in force would be a new version ({now}, "
                f"with other parameters); a run resumes only with the calibrations it started with: "
                "start a new run (bench run)"
            )
        return self.add_calibration(name, params, notes=notes)

    def calibration(self, name: str, version: int | None = None) -> CalibrationRecord:
        """Calibration ``name`` at ``version`` (the latest when None); ``ConfigError`` when missing."""
        query = "SELECT id FROM calibrations WHERE name = ?" + (" AND version = ?" if version else "")
        query += " ORDER BY version DESC LIMIT 1"
        row = self._db.execute(query, (name, version) if version else (name,)).fetchone()
        if row is None:
            wanted = f"version {version}" if version else "any version"
            raise ConfigError(f"calibration {name!r}: {wanted} not found in {self.path}")
        return self.calibration_by_id(row[0])

    def calibration_by_id(self, calibration_id: int) -> CalibrationRecord:
        row = self._db.execute(
            "SELECT id, uuid, name, version, created_utc, params_json, source_run_id, notes"
            " FROM calibrations WHERE id = ?",
            (calibration_id,),
        ).fetchone()
        if row is None:
            raise ConfigError(f"calibration id {calibration_id}: not found in {self.path}")
        return CalibrationRecord(
            id=row[0],
            uuid=row[1],
            name=row[2],
            version=row[3],
            created_utc=row[4],
            params=json.loads(row[5]),
            source_run_id=row[6],
            notes=row[7],
        )

    def calibrations(self) -> list[CalibrationRecord]:
        """Every calibration version, by name then version."""
        ids = [r[0] for r in self._db.execute("SELECT id FROM calibrations ORDER BY name, version")]
        return [self.calibration_by_id(i) for i in ids]
