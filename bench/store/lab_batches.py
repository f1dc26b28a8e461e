"""The batches a lab sync sends: the samples the server lacks, read from the local file and formatted as COPY text.

Reading a sample from SQLite and formatting its COPY line (its typed values included, :mod:`bench.store.lab_copy`) cost
about 7 us of the sync's process a sample, under Python's lock: on a machine with cores to spare, that one thread
sets the sync's pace while the server's two connections wait (``benchmarks/bench_sync.py``: its busiest process).
So a large sync from a store file can read and format a lane's batches in a producer process (this module run with
``python -m``, its own read-only connection to the file) while the sync's threads send them, and this thread
formats the other lane's (:func:`lane_batches`). A producer's start costs about 0.15 s of CPU, and its batches
cross a pipe: worth it for a sync of :data:`PRODUCED_SAMPLES` samples or more on a machine of 4 cores or more
(:func:`producer_count`), a loss on a machine whose cores are all busy.

Every sample the server lacked when the sync asked is in exactly one batch: a produced run is cut at the step index
of every ``batch_size``-th sample (:meth:`bench.store.Store.step_marks`) into consecutive step ranges, the last one
open, and each range's rows, less the steps the server holds, are one batch (one transaction on the server). A
producer that fails (an exception, or its process killed) fails the sync after the batches committed before it,
in one line; the next sync sends the rest.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import tempfile
from collections import deque
from collections.abc import Collection, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from typing import Any

from bench.store.child_env import bench_child_env
from bench.store.database import RunRecord, Store
from bench.store.lab_connection import LabStoreError
from bench.store.lab_copy import copy_text

__all__ = ["BATCH_SAMPLES", "PRODUCED_SAMPLES", "Batch", "lane_batches", "producer_count"]

#: A batch: its COPY text in chunks of :data:`_CHUNK_ROWS` rows at most, its number of samples, its run.
Batch = tuple[list[bytes], int, RunRecord]

_CHUNK_ROWS = 2_000  # rows per COPY write: the server parses one while the next goes
#: Samples a batch (one transaction) holds by default. 5,000 rather than 20,000: the first batch is read and
#: formatted while nothing is sent, the last sent while nothing is formatted, and on two cores those ends were a
#: fifth of a 100,000-sample sync (``benchmarks/bench_sync.py``, quiet machine, medians of runs: 0.40 -> 0.46-0.54
#: of a bare COPY's rate); a batch's commit (one WAL flush, about 3 ms) is overlapped by the other lane's batch.
BATCH_SAMPLES = 5_000
#: Samples a sync sends, at least, for producer processes to pay for their start (about 0.15 s of CPU each).
PRODUCED_SAMPLES = 80_000


def producer_count(store: Store, samples: int, lanes: int, requested: int | None) -> int:
    """Producer processes for a sync of ``samples`` samples in ``lanes`` lanes: ``requested`` when given (one per
    lane at most), else one (the busiest process's CPU per sample falls from about 10 to 6 us, for about 1.5 us
    more in all, measured in ``benchmarks/bench_sync.py``) for a sync of :data:`PRODUCED_SAMPLES` samples or more
    on a machine of 4 cores or more; none for an in-memory store (which another process cannot open)."""
    if store.path == ":memory:":
        return 0
    if requested is not None:
        return min(requested, lanes)
    return min(1, lanes) if samples >= PRODUCED_SAMPLES and (os.cpu_count() or 1) >= 4 else 0


def _formatted(rows: Any, run_uuid: str, held: Collection[int], limit: int | None) -> tuple[list[bytes], int, bool]:
    """Up to ``limit`` (None: all) of the rows of the cursor ``rows`` whose step is not in ``held``, as COPY text
    in chunks; their number; whether the cursor is exhausted."""
    chunks: list[bytes] = []
    n = 0
    while limit is None or n < limit:
        chunk = rows.fetchmany(_CHUNK_ROWS if limit is None else min(_CHUNK_ROWS, limit - n))
        if not chunk:
            return chunks, n, True
        if held:
            chunk = [row for row in chunk if row[0] not in held]
        if chunk:
            chunks.append(copy_text(run_uuid, chunk))
            n += len(chunk)
    return chunks, n, False


def _read_batches(store: Store, run: RunRecord, held: Collection[int], batch_size: int) -> Iterator[Batch]:
    """The samples of ``run`` that the server lacks (steps not in ``held``), ``batch_size`` at most a batch, read
    and formatted in this thread."""
    rows = store.stored_rows(run.id, checksum=True)
    exhausted = False
    while not exhausted:
        chunks, n, exhausted = _formatted(rows, run.uuid, held, batch_size)
        if n:
            yield chunks, n, run


def _ranges(store: Store, run: RunRecord, batch_size: int) -> list[tuple[int, int | None]]:
    """The step ranges of ``run``'s batches: ``(after_step, before_step)``, both excluded, None for the open end."""
    bounds = store.step_marks(run.id, batch_size)[1:]
    return list(zip([-1, *(step - 1 for step in bounds)], [*bounds, None]))


class _ProducedBatches:
    """The batches of one lane's runs, read and formatted in step order by a producer process (this module run
    with ``python -m``): it is given every range at once on its stdin, and writes each batch to its stdout as a
    header line ``<samples> <bytes of each chunk>...`` and the chunks of COPY text (as this thread cuts them, so that the
    server parses one while the next goes), then ``end``; the pipe holds it about one batch ahead."""

    def __init__(
        self, store: Store, runs: Sequence[RunRecord], held: dict[str, set[int] | None], batch_size: int
    ) -> None:
        self._path = store.path
        ranges = [(run, after, before) for run in runs for after, before in _ranges(store, run, batch_size)]
        self._runs = deque(run for run, _, _ in ranges)
        work = [
            [run.id, run.uuid, after, before, _held_between(held[run.uuid], after, before)]
            for run, after, before in ranges
        ]
        self._errors = tempfile.TemporaryFile()
        self._process = subprocess.Popen(
            [sys.executable, "-m", __name__, self._path],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._errors,
            env=bench_child_env(),
        )
        assert self._process.stdin is not None and self._process.stdout is not None
        self._out = self._process.stdout
        self._process.stdin.write(json.dumps(work).encode())  # read whole before it writes: no deadlock
        self._process.stdin.close()

    def __iter__(self) -> Iterator[Batch]:
        return self

    def __next__(self) -> Batch:
        while True:
            header = self._out.readline()
            if header == b"end\n" and not self._runs:
                raise StopIteration
            fields = header.split()
            if not fields or not self._runs:
                raise self._failure()
            n, sizes = int(fields[0]), [int(size) for size in fields[1:]]
            chunks = [self._out.read(size) for size in sizes]
            if [len(chunk) for chunk in chunks] != sizes:
                raise self._failure()
            run = self._runs.popleft()
            if n:
                return chunks, n, run

    def _failure(self) -> LabStoreError:
        code = self._process.wait()
        self._errors.seek(0)
        lines = self._errors.read().decode(errors="replace").strip().splitlines()
        how = f"killed by signal {-code}" if code < 0 else f"exit {code}"
        return LabStoreError(
            f"sync: the process reading {self._path} stopped ({how}: {lines[-1] if lines else 'no message'});"
            " the batches sent are kept, run bench sync again to resume"
        )

    def close(self) -> None:
        if self._process.poll() is None:  # the sync stopped early: this producer is ours to end
            self._process.kill()
        self._process.wait()
        self._out.close()
        self._errors.close()


def _held_between(held: set[int] | None, after: int, before: int | None) -> list[int]:
    """The steps of ``held`` in the range (a partly synced run's; none for most runs)."""
    return sorted(s for s in held or () if s > after and (before is None or s < before))


@contextmanager
def lane_batches(
    store: Store,
    lanes: list[list[RunRecord]],
    held: dict[str, set[int] | None],
    *,
    batch_size: int,
    producers: int,
) -> Iterator[list[Iterator[Batch]]]:
    """Per lane, the batches of its runs: read and formatted by a producer process each when ``producers`` (the
    first ``producers`` lanes), else in this thread as they are sent; the processes end with the context."""
    with ExitStack() as stack:
        batches: list[Iterator[Batch]] = []
        for index, lane in enumerate(lanes):
            if index < producers:
                produced = _ProducedBatches(store, lane, held, batch_size)
                stack.callback(produced.close)
                batches.append(produced)
            else:
                batches.append(
                    itertools.chain.from_iterable(
                        _read_batches(store, run, held[run.uuid] or set(), batch_size) for run in lane
                    )
                )
        yield batches


def _produce(path: str) -> None:
    """The producer process: the ranges (JSON) from stdin, each batch to stdout (see :class:`_ProducedBatches`)."""
    out = sys.stdout.buffer
    with Store(path, read_only=True) as store:
        for run_id, run_uuid, after, before, held in json.load(sys.stdin):
            rows = store.stored_rows(run_id, after, before_step=before, checksum=True)
            chunks, n, _ = _formatted(rows, run_uuid, frozenset(held), None)
            out.write(b" ".join([b"%d" % n, *(b"%d" % len(chunk) for chunk in chunks)]) + b"\n")
            out.writelines(chunks)
            out.flush()
    out.write(b"end\n")
    out.flush()


if __name__ == "__main__":
    _produce(sys.argv[1])
