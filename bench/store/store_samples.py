"""The samples and streamed rows of the run store: :class:`StoreSamples`, a part of :class:`bench.store.Store`."""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any

from bench.errors import ConfigError
from bench.store.connection import GuardedConnection, GuardedCursor, store_error
from bench.store.records import SampleRecord
from bench.store.sample_checksum import CHECKED_COLUMNS, parse_sample
from bench.store.sample_rows import encode_sample, insert_sample_row

if TYPE_CHECKING:  # numpy is imported when streamed rows are used, not with the store
    import numpy as np
    from numpy.typing import ArrayLike, NDArray

__all__ = ["StoreSamples", "checked_sample"]


def checked_sample(run_id: int, row: tuple[Any, ...], path: str) -> SampleRecord:
    """The record of a stored row (:data:`CHECKED_COLUMNS` then ``checksum``) of run ``run_id``, its JSON parsed
    once the row has passed its checksum (:func:`bench.store.sample_checksum.parse_sample`: else DamagedSample)."""
    values, raw = parse_sample(run_id, row, path)
    return SampleRecord(
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


class StoreSamples:
    """:class:`bench.store.Store`'s samples (one committed row each) and streamed rows (batches)."""

    path: str
    _db: GuardedConnection
    wall_clock: Callable[[], str]

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

    def insert_sample(self, row: tuple[Any, ...]) -> None:
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
        return list(self.iter_samples(run_id, kind))

    def iter_samples(self, run_id: int, kind: str | None = None) -> Iterator[SampleRecord]:
        """:meth:`samples` one at a time: a caller that keeps only what it computes from each sample holds one
        parsed sample, not the run (a long path run's JSON series as Python lists: about 130 bytes a point)."""
        for record, _ in self.iter_samples_text(run_id, kind):
            yield record

    def iter_samples_text(self, run_id: int, kind: str | None = None) -> Iterator[tuple[SampleRecord, str | None]]:
        """:meth:`iter_samples`, each record with its ``raw_json`` text as stored (checked with it): the numbers'
        text as written, which a copy of the raw data can reuse instead of formatting every number again."""
        query = (
            f"SELECT {', '.join(CHECKED_COLUMNS)}, checksum FROM samples"
            " WHERE run_id = ?" + (" AND kind = ?" if kind else "") + " ORDER BY step_index"
        )
        args = (run_id, kind) if kind else (run_id,)
        for row in self._db.execute(query, args):
            yield checked_sample(run_id, row, self.path), row[7]

    def stored_rows(
        self, run_id: int, after_step: int = -1, *, before_step: int | None = None, checksum: bool = False
    ) -> GuardedCursor:
        """The samples of a run after step ``after_step`` (and before ``before_step``, when given) exactly as
        stored, in step order: ``(step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json)`` with the
        JSON unparsed (what sync sends and what :func:`bench.store.lab.rows_checksum` hashes); with ``checksum``
        the row's stored checksum after them (what the lab sync sends)."""
        return self._db.execute(
            "SELECT step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json"
            + (", checksum" if checksum else "")
            + " FROM samples WHERE run_id = ? AND step_index > ?"
            + ("" if before_step is None else " AND step_index < ?")
            + " ORDER BY step_index",
            (int(run_id), int(after_step), *(() if before_step is None else (int(before_step),))),
        )

    def step_marks(self, run_id: int, every: int) -> list[int]:
        """The step index of every ``every``-th sample of a run in step order (the first, the ``every + 1``-th, ...):
        the bounds that cut the run into batches of ``every`` samples."""
        return [
            row[0]
            for row in self._db.execute(
                "SELECT step_index FROM (SELECT step_index, row_number() OVER (ORDER BY step_index) - 1 AS i"
                " FROM samples WHERE run_id = ?) WHERE i % ? = 0 ORDER BY step_index",
                (int(run_id), int(every)),
            )
        ]

    # ---- streamed rows ---------------------------------------------------------------------------------------

    def add_stream_rows(
        self, run_id: int, stream: str, t_s: ArrayLike, dx_counts: ArrayLike, dy_counts: ArrayLike, valid: ArrayLike
    ) -> int:
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

    def stream_rows(
        self, run_id: int, stream: str
    ) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
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
