"""Batched storing of a streaming sensor's frames: one transaction (one fsync) per batch, not per frame.

A committed sample costs one ``fdatasync`` (~3 ms on a disk: 265-303 samples/s measured), right for step-wise
captures and far too slow for a mouse reporting at 1-8 kHz. :class:`StreamWriter` gathers frames and stores them
with :meth:`bench.store.database.Store.add_stream_rows` every ``batch_s`` seconds or ``batch_rows`` rows, whichever
comes first. Everything a flush returned from is committed and survives a SIGKILL or a power cut, as a sample
does; what a crash can lose is the frames gathered since the last flush (at most ``batch_s``, 0.1 s by default),
which the mice still hold as integrated counts (``benchmarks/bench_mouse_ingest.py`` measures the rows/s).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Self

import numpy as np

__all__ = ["StreamWriter"]


class StreamWriter:
    """Frames of one stream of one run, stored in batches.

    Parameters
    ----------
    store : bench.store.database.Store
        An open store.
    run_id : int
        The run.
    stream : str
        The sensor's name (``mouse_xy``).
    batch_s, batch_rows : float, int
        Flush when the oldest unflushed frame was appended ``batch_s`` ago, or ``batch_rows`` are waiting.
    """

    def __init__(
        self,
        store: Any,
        run_id: int,
        stream: str,
        *,
        batch_s: float = 0.1,
        batch_rows: int = 4000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.store, self.run_id, self.stream = store, run_id, stream
        self.batch_s, self.batch_rows, self._clock = batch_s, batch_rows, clock
        self._parts: list[tuple[np.ndarray, ...]] = []
        self._waiting = 0
        self._oldest_s: float | None = None
        #: Rows committed so far (every one of them durable).
        self.committed = 0

    def append(self, frames: Any) -> int:
        """Add ``frames`` (:class:`bench.sensors.input_event.MotionFrames`); flush if a batch is due. Returns the
        rows committed by this call."""
        if len(frames):
            self._parts.append((frames.t_s, frames.dx, frames.dy, frames.valid))
            self._waiting += len(frames)
            if self._oldest_s is None:
                self._oldest_s = self._clock()
        due = self._oldest_s is not None and (
            self._waiting >= self.batch_rows or self._clock() - self._oldest_s >= self.batch_s
        )
        return self.flush() if due else 0

    def flush(self) -> int:
        """Store and commit every frame waiting (one transaction); the rows committed."""
        if not self._parts:
            return 0
        columns = [np.concatenate(column) for column in zip(*self._parts, strict=True)]
        stored = self.store.add_stream_rows(self.run_id, self.stream, *columns)
        self._parts, self._waiting, self._oldest_s = [], 0, None
        self.committed += stored
        return stored

    def close(self) -> None:
        self.flush()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
