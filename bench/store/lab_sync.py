"""``bench sync``: push a bench's SQLite store into the lab store (see :mod:`bench.store.lab` for the design)."""

from __future__ import annotations

import json
import logging
import random
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bench.errors import BenchError
from bench.store.database import RunRecord, Store
from bench.store.lab_batches import BATCH_SAMPLES, Batch, lane_batches, producer_count
from bench.store.lab_connection import LabServerBusy, LabStoreError, connect, one_line, psycopg_module, redacted
from bench.store.lab_copy import COPY_COLUMNS
from bench.store.lab_schema import ensure_schema
from bench.store.record_checksum import CALIBRATION_CHECKED_COLUMNS, RUN_CHECKED_COLUMNS
from bench.store.records import from_json

if TYPE_CHECKING:  # psycopg is the lab-store extra, imported when a sync starts
    from psycopg import Connection, Cursor

__all__ = ["SyncResult", "sync_after_run", "sync_store"]

_log = logging.getLogger(__name__)

_COPY_COLUMNS = ", ".join(f'"{c}"' for c in COPY_COLUMNS)
#: Connections sending batches at once (each its own runs): the server stores and folds two batches in parallel.
LANES = 2
#: Memory for the pose trigger's transition table of one batch (about 400 bytes a row): with the server's default
#: (4 MB) a 20 000-sample batch (``bench sync --batch 20000``) spills to a temporary file (10-15 % more of the
#: server's time per sample); the default batch (5,000, about 2 MB) fits either way.
_WORK_MEM = "64MB"
#: The bench.runs columns a sync fills: the run's checked columns exactly as its file stores them (status and
#: reason as stored) with the file's checksum of them, and beside them the status and reason the file reads the
#: run as when synced (a ``running`` run without a live owner reads as interrupted), which the lab shows.
_RUN_COLUMNS = (
    *RUN_CHECKED_COLUMNS,
    "local_id",
    "calibration_uuids_json",
    "checksum",
    "read_status",
    "read_reason",
)
_CALIBRATION_COLUMNS = (
    *(c for c in CALIBRATION_CHECKED_COLUMNS if c != "source_run_id"),
    "bench",
    "local_id",
    "source_run_uuid",
    "source_run_local_id",
    "checksum",
)


@dataclass(frozen=True)
class SyncResult:
    """What one sync did: runs and calibrations upserted, samples sent (new on the server) and their seconds."""

    runs: int
    calibrations: int
    samples_sent: int
    seconds: float

    @property
    def samples_per_s(self) -> float:
        return self.samples_sent / self.seconds if self.seconds > 0 else float("inf")


def _run_row(
    store: Store, stored: tuple[int, tuple[Any, ...], str], calibration_uuids: dict[int, str]
) -> tuple[Any, ...]:
    """One bench.runs row (:data:`_RUN_COLUMNS`) from a run ``stored`` as :meth:`Store.stored_records` reads it."""
    run_id, fields, checksum = stored
    row = dict(zip(RUN_CHECKED_COLUMNS, fields))
    read_status, read_reason = store.reads_as(run_id, row["status"], row["reason"])
    calibration_ids = from_json(row["calibration_ids_json"])
    row |= {
        "local_id": run_id,
        "calibration_uuids_json": json.dumps([calibration_uuids.get(i) for i in calibration_ids]),
        "checksum": checksum,
        "read_status": read_status,
        "read_reason": read_reason,
    }
    return tuple(row[c] for c in _RUN_COLUMNS)


def _calibration_benches(
    store: Store, stored_runs: list[tuple[int, tuple[Any, ...], str]]
) -> tuple[dict[int, str], str]:
    """The bench each run of the file was measured on (its stored ``bench``), and the file's bench: its runs' one
    bench when they agree, else the name the file was opened with (``--bench``, or the host name)."""
    at = RUN_CHECKED_COLUMNS.index("bench")
    benches = {run_id: fields[at] for run_id, fields, _ in stored_runs}
    named = set(benches.values())
    return benches, named.pop() if len(named) == 1 else store.bench


def _calibration_row(
    stored: tuple[int, tuple[Any, ...], str], run_uuids: dict[int, str], benches: tuple[dict[int, str], str]
) -> tuple[Any, ...]:
    """One bench.calibrations row (:data:`_CALIBRATION_COLUMNS`) from a calibration as stored, labelled with the
    bench of its source run, else the file's bench (:func:`_calibration_benches`: the name the file was opened with
    only when its runs name no single bench). Before 0.5.1 always that name: a lab manager syncing a bench's file
    from another machine labelled every calibration with that machine; such rows keep their label (the upsert
    leaves a synced calibration as it is)."""
    calibration_id, fields, checksum = stored
    row = dict(zip(CALIBRATION_CHECKED_COLUMNS, fields))
    source = row["source_run_id"]
    run_benches, file_bench = benches
    row |= {
        "bench": run_benches.get(source, file_bench),  # no source run, or not in this file: the file's bench
        "local_id": calibration_id,
        "source_run_uuid": None if source is None else run_uuids.get(source),
        "source_run_local_id": source,
        "checksum": checksum,
    }
    return tuple(row[c] for c in _CALIBRATION_COLUMNS)


def _copy(cur: Cursor[Any], table: str, chunks: list[bytes]) -> None:
    """COPY the formatted ``chunks`` into ``table``, one write each (the server parses one while the next goes)."""
    with cur.copy(f"COPY {table} ({_COPY_COLUMNS}) FROM STDIN") as copy:
        for chunk in chunks:
            copy.write(chunk)


def _send_batch(conn: Connection[Any], chunks: list[bytes], n: int) -> int:
    """Store one batch in its own transaction; returns how many of its ``n`` samples were new on the server."""
    psycopg = psycopg_module()
    try:  # fast path: straight into bench.samples, the server lacked these steps when asked
        with conn.transaction(), conn.cursor() as cur:
            _copy(cur, "bench.samples", chunks)
        return n
    except psycopg.errors.UniqueViolation:  # another sync of this file got there first: skip its rows
        with conn.transaction(), conn.cursor() as cur:
            _copy(cur, "sample_stage", chunks)
            cur.execute(
                f"INSERT INTO bench.samples ({_COPY_COLUMNS}) SELECT {_COPY_COLUMNS}"
                " FROM sample_stage ON CONFLICT DO NOTHING"
            )
            return cur.rowcount


def _held_steps(conn: Connection[Any], runs: list[RunRecord]) -> dict[str, set[int] | None]:
    """Per run UUID, the steps the server holds: None when it holds all of the run's samples (nothing to send),
    an empty set when it holds none."""
    counts = dict(
        conn.execute(
            "SELECT run_uuid::text, count(*) FROM bench.samples WHERE run_uuid = ANY(%s::uuid[]) GROUP BY run_uuid",
            ([r.uuid for r in runs],),
        ).fetchall()
    )
    held: dict[str, set[int] | None] = {}
    for run in runs:
        count = counts.get(run.uuid, 0)
        if count == run.n_samples:
            held[run.uuid] = None
        elif count == 0:
            held[run.uuid] = set()
        else:  # partly synced (a sync cut off, or a run resumed since): the steps it holds
            held[run.uuid] = {
                row[0] for row in conn.execute("SELECT step_index FROM bench.samples WHERE run_uuid = %s", (run.uuid,))
            }
    conn.commit()
    return held


def _prepare_sender(conn: Connection[Any]) -> None:
    """A connection ready to send batches: its staging table, and memory for the pose trigger's transition table."""
    conn.execute("CREATE TEMP TABLE IF NOT EXISTS sample_stage (LIKE bench.samples) ON COMMIT DELETE ROWS")
    conn.execute(f"SET work_mem = '{_WORK_MEM}'")
    conn.commit()


def _deal(runs: list[RunRecord], held: dict[str, set[int] | None], lanes: int) -> list[list[RunRecord]]:
    """The runs to send dealt to ``lanes`` lanes (fewer when there are fewer runs; one, empty, for none), each run
    to the lane with the fewest samples to send so far, in the file's order."""
    dealt: list[list[RunRecord]] = [[] for _ in range(min(lanes, len(runs)))] or [[]]
    load = [0] * len(dealt)
    for run in runs:
        lane = load.index(min(load))
        dealt[lane].append(run)
        load[lane] += run.n_samples - len(held[run.uuid] or ())
    return dealt


def _send_lanes(
    batches: list[Iterator[Batch]],
    connections: list[Connection[Any]],
    *,
    progress: Callable[[str], None],
    sent: list[int],
) -> None:
    """Send the lanes' ``batches``, each lane through its own connection and sender thread, one batch in flight per
    lane; this thread takes the next batches meanwhile (reads and formats them, or takes them from the producer
    processes), the lanes in turn."""
    in_flight: list[tuple[Future[int], RunRecord, int] | None] = [None] * len(batches)
    with ThreadPoolExecutor(max_workers=len(batches), thread_name_prefix="lab-sync") as senders:
        live = list(range(len(batches)))
        try:
            while live:
                for lane in list(live):
                    batch = next(batches[lane], None)
                    settling = in_flight[lane]
                    if settling is not None:
                        _settle(*settling, progress=progress, sent=sent)
                        in_flight[lane] = None
                    if batch is None:
                        live.remove(lane)
                        continue
                    chunks, n, run = batch
                    in_flight[lane] = (senders.submit(_send_batch, connections[lane], chunks, n), run, n)
        finally:  # one lane failed (or this thread): the batches the other lanes committed still count
            for pending in in_flight:
                if pending is not None and pending[0].exception() is None:
                    _settle(*pending, progress=progress, sent=sent)


def _settle(batch: Future[int], run: RunRecord, n: int, *, progress: Callable[[str], None], sent: list[int]) -> None:
    """Wait for a batch sent (its exception raised here), count its new samples once committed, report it."""
    sent[0] += batch.result()
    progress(f"sync: run {run.id} ({run.uuid}) +{n} samples")


def _push(
    store: Store,
    conn: Connection[Any],
    url: str,
    *,
    batch_size: int,
    producers: int | None,
    progress: Callable[[str], None],
    sent: list[int],
) -> tuple[int, int]:
    """Upsert runs and calibrations, then send the samples the server lacks; ``sent[0]`` counts the samples
    committed (kept when a later batch fails)."""
    calibrations = store.stored_records("calibrations")  # before the runs: every run's calibrations are among them
    runs = store.runs()  # (then every run whose samples are sent has its row: a run started meanwhile waits)
    stored_runs = store.stored_records("runs")
    run_uuids = {r[0]: r[1][0] for r in stored_runs}
    benches = _calibration_benches(store, stored_runs)
    calibration_uuids = {c[0]: c[1][0] for c in calibrations}
    updates = ", ".join(f"{c} = EXCLUDED.{c}" for c in _RUN_COLUMNS[1:])
    with conn.transaction(), conn.cursor() as cur:
        cur.executemany(
            f"INSERT INTO bench.runs ({', '.join(_RUN_COLUMNS)}) VALUES ({', '.join(['%s'] * len(_RUN_COLUMNS))})"
            f" ON CONFLICT (uuid) DO UPDATE SET {updates}, synced_utc = now()",
            [_run_row(store, r, calibration_uuids) for r in stored_runs],
        )
        cur.executemany(  # a calibration never changes: one synced before v5 only gets what its check needs
            f"INSERT INTO bench.calibrations ({', '.join(_CALIBRATION_COLUMNS)})"
            f" VALUES ({', '.join(['%s'] * len(_CALIBRATION_COLUMNS))}) ON CONFLICT (uuid) DO UPDATE SET"
            " source_run_local_id = EXCLUDED.source_run_local_id, checksum = EXCLUDED.checksum"
            " WHERE bench.calibrations.checksum IS NULL",
            [_calibration_row(c, run_uuids, benches) for c in calibrations],
        )
    conn.commit()
    held = _held_steps(conn, runs)
    to_send = [run for run in runs if held[run.uuid] is not None]
    lanes = _deal(to_send, held, LANES)
    connections = [conn]
    try:
        for _ in lanes[1:]:
            try:
                connections.append(connect(url))
            except LabServerBusy:  # a crowded server: this bench sends through the connection it holds
                lanes = _deal(to_send, held, len(connections))
                break
        for lane_conn in connections:
            _prepare_sender(lane_conn)
        samples = sum(run.n_samples - len(held[run.uuid] or ()) for run in to_send)
        workers = producer_count(store, samples, len(lanes), producers)
        with lane_batches(store, lanes, held, batch_size=batch_size, producers=workers) as batches:
            _send_lanes(batches, connections, progress=progress, sent=sent)
    finally:
        for lane_conn in connections[1:]:
            lane_conn.close()
    return len(runs), len(calibrations)


def sync_store(
    store: Store,
    url: str,
    *,
    batch_size: int = BATCH_SAMPLES,
    retries: int = 3,
    retry_wait_s: float = 1.0,
    busy_wait_s: float = 600.0,
    producers: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> SyncResult:
    """Push every run, calibration and sample of ``store`` that the server at ``url`` lacks (see the module
    docstring); after a lost connection, reconnect and resume up to ``retries`` times (waits ``retry_wait_s``,
    then twice that, ...). A server with no connection slot free (:class:`LabServerBusy`) is asked again after a
    random wait (0.5-1.5 times ``retry_wait_s``, doubling up to 30 s), for ``busy_wait_s`` in all: a crowd of benches
    syncing at once shares the server's connections instead of failing. ``producers``: processes reading and
    formatting the batches of as many lanes (:mod:`bench.store.lab_batches`; 0: all in this thread; None: one for a
    sync of 80,000 samples or more on a machine of 4 cores or more).

    Raises
    ------
    LabStoreError
        Bad URL or credentials, a newer server schema (at once); an unreachable server after the retries.
    """
    psycopg = psycopg_module()
    report = progress or (lambda line: _log.info("%s", line))
    started = time.perf_counter()
    sent, attempt, busy = [0], 0, 0
    while True:
        try:
            conn = connect(url)
            try:
                ensure_schema(conn, url)
                runs, calibrations = _push(
                    store, conn, url, batch_size=batch_size, producers=producers, progress=report, sent=sent
                )
            finally:
                conn.close()
            return SyncResult(runs, calibrations, sent[0], time.perf_counter() - started)
        except LabServerBusy as exc:
            wait = min(30.0, retry_wait_s * 2 ** min(busy, 10)) * random.uniform(0.5, 1.5)
            if time.perf_counter() - started + wait > busy_wait_s:
                raise
            busy += 1
            if busy == 1:
                report(f"sync: {one_line(exc)}; waiting for a free connection")
            time.sleep(wait)
        except (psycopg.OperationalError, LabStoreError) as exc:  # (a LabURLError is no LabStoreError: at once)
            retryable = isinstance(exc, psycopg.OperationalError) or "server unreachable" in str(exc)
            if not retryable or attempt >= retries:
                if isinstance(exc, LabStoreError):
                    raise
                raise LabStoreError(
                    f"lab store {redacted(url)}: connection lost ({one_line(exc)}); run bench sync again to resume"
                ) from exc
            attempt += 1
            report(f"sync: {one_line(exc)}; retry {attempt} of {retries}")
            time.sleep(retry_wait_s * 2 ** (attempt - 1))


def sync_after_run(store: Store, url: str, *, say: Callable[[str], None] | None = None) -> SyncResult | None:
    """Sync ``store`` to ``url`` once a run has ended (``[lab_store] auto_sync``), never failing the run: any
    failure (server down, credentials, a bug) is one line on stderr (``say``) and the next sync catches up, since
    the local file stays the source of truth. Returns the result, or None when the sync failed."""
    tell = say or (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        result = sync_store(store, url, retries=1, retry_wait_s=0.5, busy_wait_s=30.0, progress=lambda line: None)
    except BenchError as exc:
        tell(f"bench: lab store sync failed, the run is kept locally (bench sync catches up): {one_line(exc)}")
        return None
    except Exception as exc:  # noqa: BLE001 - the local run must survive whatever the sync meets
        _log.exception("lab store sync after the run failed")
        tell(
            f"bench: lab store sync failed, the run is kept locally (bench sync catches up): "
            f"{type(exc).__name__}: {one_line(exc)}"
        )
        return None
    tell(f"bench: synced to the lab store {redacted(url)}: {result.samples_sent} new samples")
    return result
