"""An integrity check before appending to a store that was not closed cleanly.

A store was not closed cleanly when it holds a run stored as ``running`` that no live process owns
(:mod:`bench.store.ownership`): its writer was killed (``kill -9``, the OOM killer), lost its power or crashed
before it could settle the run, and may have died in the middle of a write. That is the sign used here because it
is exact in both directions:

- every command that appends samples (``bench run``, ``bench resume``, a campaign, the desktop app's runs) writes
  inside a run it owns, and settles the run (``completed``, ``failed``, ``aborted``) before it lets go; a writer
  that ends any other way leaves the run ``running`` with its lock released by the kernel;
- a leftover ``-wal`` file is not a sign: a live reader keeps it (a read-only connection never deletes it), and a
  live writer of another run has one; checking on it would check on most opens.

:func:`refuse_if_damaged` runs when a store is opened for writing (:class:`bench.store.Store`), before anything is
written to it (before a schema migration, before a rig is opened or a calibration stored): when the store was not
closed cleanly, it runs the checks of ``bench store check`` (SQLite's ``PRAGMA integrity_check`` and
``foreign_key_check``, :func:`bench.store.connection.check_store`) and refuses a damaged store in one line.

Cost (``python benchmarks/bench_store_check.py``: 10^5 pose samples, 20.7 MiB, SQLite 3.40, 2 cores shared
under load 4): ``quick_check`` 0.05-0.06 s (1.2 x one scan of the samples), ``integrity_check`` 0.12-0.15 s
(3.0 x), the whole check with the foreign keys 0.11-0.17 s. The full ``integrity_check`` is used: it also checks
that each index matches its table, which is what keeps a sample from being stored twice (``UNIQUE (run_id,
step_index)``); a tenth of a second per 10^5 samples, paid only after an unclean end, is nothing beside a run.
"""

from __future__ import annotations

import logging
import sqlite3
import time
from collections.abc import Set as AbstractSet

from bench.store.connection import StoreError, check_store
from bench.store.ownership import owner_of

__all__ = ["StoreDamaged", "interrupted_runs", "refuse_if_damaged"]

_log = logging.getLogger(__name__)


class StoreDamaged(StoreError):
    """A store that was not closed cleanly failed its integrity check: nothing was written to it."""


def interrupted_runs(db: sqlite3.Connection, path: str, owned: AbstractSet[int] = frozenset()) -> list[int]:
    """The runs of the store behind ``db`` stored as ``running`` that no live process owns (``owned``: the ones
    this process holds). A file without a ``runs`` table (a new store) has none."""
    if db.execute("SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = 'runs'").fetchone()[0] == 0:
        return []
    running = [row[0] for row in db.execute("SELECT id FROM runs WHERE status = 'running' ORDER BY id")]
    gone = []
    for run_id in running:
        owner = owner_of(path, run_id)
        if run_id not in owned and (owner is None or not owner.alive):
            gone.append(run_id)
    return gone


def refuse_if_damaged(db: sqlite3.Connection, path: str, owned: AbstractSet[int] = frozenset()) -> list[int]:
    """Check the store at ``path`` when it was not closed cleanly; returns the interrupted runs (empty: the store
    was closed cleanly and nothing was checked).

    Raises
    ------
    StoreDamaged
        One line: the interrupted runs, the first problem found (and how many more), and what to do.
    """
    gone = interrupted_runs(db, path, owned)
    if not gone:
        return gone
    started = time.perf_counter()
    problems = check_store(path)
    elapsed_s = time.perf_counter() - started
    runs = ", ".join(str(i) for i in gone)
    if problems:
        first = problems[0].removeprefix(f"{path}: ").replace("\n", " ")
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise StoreDamaged(
            f"store {path}: not closed cleanly (run {runs} interrupted) and damaged: {first}{more}; nothing was "
            f"written: list the damage with `bench store check {path}`, keep a copy with `bench backup COPY.db "
            f"--store {path}`, and run into a new store (--store NEW.db)"
        )
    _log.info("store %s: not closed cleanly (run %s interrupted); integrity check ok in %.3f s", path, runs, elapsed_s)
    return gone
