"""A run's samples committed on a writer thread while the robot makes its next move.

A sample's commit is one ``fdatasync`` (~3 ms on a disk), and between two moves of a sped-up simulated campaign the
host has little else to do: waiting for it before the next ``MOVE`` made it the largest share of the host's time
between moves. :class:`SampleWriter` keeps the guarantee of :meth:`bench.store.database.Store.add_sample` in
substance while the robot moves on:

- the sample is checked and encoded (its ``wall_utc``) when it is taken, and its commit starts at that moment on the
  writer thread, in its own transaction on its own connection (``synchronous=FULL``, as every commit of the store);
- one commit at a time: :meth:`SampleWriter.wait` returns once the commit in flight is durable, and
  :meth:`SampleWriter.add` refuses to start another before it was waited for. The runner waits before anything
  else touches the instruments or the operator (the next capture or prompt, a pause, the end of the run), so only
  motion and settling (``Move``, ``ActuatorMove``, ``Settle``) overlap a commit. A checkpoint step queues the
  store's WAL checkpoint (:meth:`SampleWriter.checkpoint`) behind the commit on the same thread, and the wait
  covers it: once the next sample is stored, the ``.db`` file alone holds every sample before the checkpoint;
- a failed commit raises from that wait: the run fails before anything else is measured;
- nothing is reported as stored before it is durable: the runner counts a sample, advances its progress bar and
  tells its ``on_sample`` observers only once :meth:`~SampleWriter.wait` returned for it.

What a power cut (or SIGKILL) can lose is unchanged: the commit starts at the moment the sample is taken, as
before, and lasts as long, so a cut at any moment loses exactly the samples whose commit had not finished by then
(at most the one in flight, which was never reported as stored, and which a resume takes again, as before). What
changed is only what the robot does during those milliseconds: it is already on its way to the next target, a
target the pre-flight proved reachable before the run began. A store in memory (``:memory:``, tests) has nothing
durable to overlap, and one connection only: its samples are committed at once, on the caller's thread.
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from typing import Any

from bench.store.connection import GuardedConnection, open_connection
from bench.store.database import Store, checkpoint_wal, encode_sample, insert_sample_row

__all__ = ["SampleWriter"]


class SampleWriter:
    """Commits the samples of ``store`` one at a time on a writer thread (see the module); close it when done.

    Parameters
    ----------
    store : Store
        The open store (for writing) whose file the samples go to.
    """

    def __init__(self, store: Store) -> None:
        self.store = store
        #: the work in flight on the writer thread (a commit, then perhaps a checkpoint) and what wait() returns
        self._pending: tuple[list[Future[None]], Any] | None = None
        self._executor: ThreadPoolExecutor | None = None
        self._db: GuardedConnection | None = None
        if store.path != ":memory:":
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="store-writer")
            try:  # the connection is made, used and closed on the writer thread only (sqlite3's one-thread rule)
                self._db = self._executor.submit(
                    lambda: GuardedConnection(open_connection(store.path), store.path)
                ).result()
            except BaseException:
                self._executor.shutdown(wait=True)
                raise

    def add(
        self,
        run_id: int,
        step_index: int,
        *,
        values: Mapping[str, float],
        kind: str,
        pose: str | None,
        cycle: int | None,
        t_s: float,
        raw: Any,
        report: Any = None,
    ) -> None:
        """Check and encode the sample now (a refused value raises here, nothing written), then start its commit
        and return; :meth:`wait` returns ``report`` once it is durable. The commit before must have been waited
        for (one in flight at a time, each one's outcome seen once)."""
        if self._pending is not None:
            raise RuntimeError("SampleWriter.add: the commit before is unsettled, expected wait() first")
        row = encode_sample(
            run_id,
            step_index,
            values=values,
            kind=kind,
            pose=pose,
            cycle=cycle,
            t_s=t_s,
            raw=raw,
            wall_clock=self.store.wall_clock,
        )
        if self._executor is None:
            self.store.insert_sample(row)
            self._pending = ([], report)
            return
        assert self._db is not None  # (opened with the executor)
        self._pending = ([self._executor.submit(insert_sample_row, self._db, row)], report)

    def checkpoint(self) -> None:
        """Copy the write-ahead log into the ``.db`` file (:meth:`Store.checkpoint`) on the writer thread, after the
        commit in flight; :meth:`wait` waits for it too, so once the next sample is stored the ``.db`` file alone
        holds every sample before this checkpoint, as with the store's own checkpoint."""
        if self._executor is None:  # its commits are done already
            self.store.checkpoint()
            return
        futures, report = self._pending if self._pending is not None else ([], None)
        assert self._db is not None  # (opened with the executor)
        self._pending = (futures + [self._executor.submit(checkpoint_wal, self._db)], report)

    def wait(self) -> Any:
        """Return once the commit in flight is durable: its ``report`` (None when nothing was in flight, or nothing
        was to be reported); raise its failure (``StoreError``, ``DuplicateSample``...), reported once. Interrupted
        (Ctrl-C) while the commit runs, the commit stays in flight and a later wait waits again."""
        if self._pending is None:
            return None
        futures, report = self._pending
        wait_for(futures)  # an interruption here leaves them in flight
        self._pending = None
        for future in futures:  # in the order they ran: a failed commit is named before its checkpoint
            failure = future.exception()  # done: at once
            if failure is not None:
                raise failure
        return report

    def close(self) -> None:
        """Wait for the commit in flight (raising its failure) and close the writer's connection and thread."""
        try:
            self.wait()
        finally:
            if self._executor is not None:
                db, self._db = self._db, None
                if db is not None:
                    self._executor.submit(db.close).result()
                self._executor.shutdown(wait=True)
                self._executor = None
