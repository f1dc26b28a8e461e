"""One sample's row as the store writes it (:func:`encode_sample`, checksum included), its insert and commit, and
the write-ahead log's checkpoint: the pieces :class:`bench.store.database.Store` and the runner's writer thread
(:mod:`bench.store.sample_writer`) share."""

from __future__ import annotations

import logging
import math
import sqlite3
import time
from collections.abc import Callable, Mapping
from typing import Any

from bench.errors import BenchError, ConfigError
from bench.store.connection import GuardedConnection
from bench.store.records import DuplicateSample, to_json, utc_now
from bench.store.sample_checksum import sample_checksum

__all__ = ["CHECKPOINT_RETRY_S", "checkpoint_wal", "encode_sample", "insert_sample_row"]

_log = logging.getLogger(__name__)

#: How long a checkpoint retries while a reader's older snapshot keeps part of the log out of the file, s.
CHECKPOINT_RETRY_S = 0.5


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
    wall_clock: Callable[[], str] = utc_now,
) -> tuple[Any, ...]:
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
        to_json({k: float(v) for k, v in values.items()}, "values"),
        None if raw is None else to_json(raw, "raw"),
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


def insert_sample_row(db: GuardedConnection, row: tuple[Any, ...]) -> None:
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
