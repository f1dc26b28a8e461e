"""The lab store: one PostgreSQL database that many benches sync their local SQLite stores into (psycopg 3).

The local file stays the source of truth; the server holds copies, in the schema ``bench``:

- ``bench.runs``: one row per run, keyed by the run's UUID, with its bench, local id, campaign, protocol,
  configuration (``config_json``), robot settings (``settings_json``), calibrations, software version, status;
- ``bench.calibrations``: one row per calibration version, keyed by its UUID;
- ``bench.samples``: one row per sample, keyed by ``(run_uuid, step_index)``, every stored column as the local file
  holds it (JSON as text, byte for byte), so :func:`rows_checksum` is equal on both sides, and one typed column per
  declared value column (``x_mm``, ``velocity_pct``, ...: :mod:`bench.store.lab_copy`) for lab-wide queries.

- ``bench.pose_keys``, ``bench.pose_points``: the pose samples folded for the lab-wide summary, kept by a trigger
  as samples arrive (:mod:`bench.store.lab_summary`).

Schema versions: 1 had no typed columns, 2 no pose tables; a bench of version 3 adds and fills what is missing when
it first connects.

Sync is idempotent and resumable: runs and calibrations are upserted (the local file wins: a status, a reason, a
registration added by a resume travel on the next sync), and the samples the server lacks are sent in batches, each
one COPY straight into ``bench.samples`` in its own transaction (when another sync of the same file stored some of
its steps first: COPY into a temporary table, then ``INSERT ... ON CONFLICT DO NOTHING``). The runs to send are dealt
to two connections ("lanes", each its own runs, so their pose folds never touch the same keys); each lane has a
sender thread with one batch in flight while this thread reads and formats the next batches, so reading the local
file, the server's storing and its pose trigger overlap. A sync killed or cut off loses its open batches'
transactions only; the next sync asks the server which steps it holds and sends the rest, so every sample lands
exactly once. Sync never writes to the local file.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import random
import re
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Self

from bench.errors import BenchError, ConfigError
from bench.store.database import RunRecord, Store
from bench.store.lab_copy import COPY_COLUMNS, SAMPLE_COLUMNS, TYPED_COLUMNS, copy_text, typed_columns_ddl
from bench.store.lab_summary import POSE_TABLES_BACKFILL, POSE_TABLES_DDL

__all__ = [
    "LAB_SCHEMA_VERSION",
    "LabServerBusy",
    "LabStore",
    "LabStoreError",
    "LabURLError",
    "SyncResult",
    "check_lab_url",
    "is_lab_url",
    "open_runs_store",
    "redacted",
    "rows_checksum",
    "sync_after_run",
    "sync_store",
]

_log = logging.getLogger(__name__)

#: The lab schema version this bench writes (kept in ``bench.schema_version``).
LAB_SCHEMA_VERSION = 3

_DDL = """
CREATE SCHEMA IF NOT EXISTS bench;
CREATE TABLE IF NOT EXISTS bench.schema_version (version integer NOT NULL);
CREATE TABLE IF NOT EXISTS bench.runs (
    uuid uuid PRIMARY KEY,
    bench text NOT NULL,
    local_id integer NOT NULL,
    campaign text,
    protocol_name text NOT NULL,
    protocol_version text NOT NULL,
    robot text NOT NULL,
    config_json text NOT NULL,
    settings_json text NOT NULL,
    calibration_ids_json text NOT NULL,
    calibration_uuids_json text NOT NULL,
    software_version text NOT NULL,
    git_sha text NOT NULL,
    status text NOT NULL,
    reason text,
    started_utc text NOT NULL,
    ended_utc text,
    synced_utc timestamptz NOT NULL DEFAULT now()
);
CREATE INDEX IF NOT EXISTS runs_bench_robot_started ON bench.runs (bench, robot, started_utc);
CREATE TABLE IF NOT EXISTS bench.calibrations (
    uuid uuid PRIMARY KEY,
    bench text NOT NULL,
    local_id integer NOT NULL,
    name text NOT NULL,
    version integer NOT NULL,
    created_utc text NOT NULL,
    params_json text NOT NULL,
    source_run_uuid uuid,
    notes text NOT NULL
);
CREATE TABLE IF NOT EXISTS bench.samples (
    run_uuid uuid NOT NULL REFERENCES bench.runs (uuid),
    step_index integer NOT NULL,
    kind text NOT NULL,
    pose text,
    cycle integer,
    t_s double precision NOT NULL,
    wall_utc text NOT NULL,
    values_json text NOT NULL,
    raw_json text,
    PRIMARY KEY (run_uuid, step_index)
);
"""

_SAMPLE_COLUMNS = ", ".join(SAMPLE_COLUMNS)
_COPY_COLUMNS = ", ".join(f'"{c}"' for c in COPY_COLUMNS)
_CHUNK_ROWS = 2_000  # rows per COPY write: small enough to overlap formatting with the server's work
#: Connections sending batches at once (each its own runs): the server stores and folds two batches in parallel.
_LANES = 2
#: Memory for the pose trigger's transition table of one batch (about 400 bytes a row): with the server's default
#: (4 MB) a 20 000-sample batch spills to a temporary file (10-15 % more of the server's time per sample).
_WORK_MEM = "64MB"
_RUN_COLUMNS = (
    "uuid",
    "bench",
    "local_id",
    "campaign",
    "protocol_name",
    "protocol_version",
    "robot",
    "config_json",
    "settings_json",
    "calibration_ids_json",
    "calibration_uuids_json",
    "software_version",
    "git_sha",
    "status",
    "reason",
    "started_utc",
    "ended_utc",
)
#: Version 1 -> 2: each typed column from the stored JSON, where it holds a number there.
_BACKFILL_TYPED = "UPDATE bench.samples SET " + ", ".join(
    f"\"{name}\" = CASE WHEN jsonb_typeof(values_json::jsonb -> '{name}') = 'number'"
    f" THEN (values_json::jsonb ->> '{name}')::double precision END"
    for name in TYPED_COLUMNS
)
_LOCK_KEY = 9283_21  # advisory lock serialising schema creation by benches that connect at once


class LabStoreError(BenchError):
    """The lab store cannot be reached or used (credentials, server, schema); the local data is untouched."""

    exit_code = 1


class LabServerBusy(LabStoreError):
    """The server has no connection slot free now (more benches at once than its ``max_connections``): a sync
    waits a jittered, growing while and tries again (:func:`sync_store`), never counting it as a lost connection."""


class LabURLError(ConfigError):
    """A lab store address that is not a usable PostgreSQL URL (bad input, exit 2)."""


def is_lab_url(spec: str) -> bool:
    """True for a ``postgresql://`` (or ``postgres://``) store address rather than a file."""
    return str(spec).startswith(("postgresql://", "postgres://"))


#: ``scheme://user:PASSWORD@`` and ``password=VALUE`` (a query parameter or a conninfo keyword): what
#: :func:`redacted` hides. The user part stops at the first ``:``; the password runs to the last ``@`` (an unencoded
#: ``@`` in a password hides a little more, never less), wherever such a URL stands in the text.
_PASSWORD_PARTS = (
    re.compile(r"([A-Za-z][A-Za-z0-9+.-]*://[^:/@?#\s\"']*):[^\s\"']*@"),
    re.compile(r"(?i)\b(password=)[^&\s]*"),
)
#: libpq's own checks of an option's value start so ("invalid sslmode value", "invalid port number",
#: "invalid integer value ... for connection option"): a bad URL, not an unreachable server.
_BAD_OPTION = re.compile(r"^(connection is bad: )?invalid ")


#: What the server (or its socket's full listen queue: EAGAIN) says when it has no connection slot free now.
_BUSY = (
    "too many clients",
    "too many connections for role",
    "remaining connection slots are reserved",
    "Resource temporarily unavailable",
)


def redacted(url: str) -> str:
    """``url`` with its password (user info or ``password=`` parameter) replaced by ``***``, for messages; never
    fails, whatever the text (a malformed URL is shown redacted too)."""
    shown = _PASSWORD_PARTS[0].sub(r"\1:***@", str(url))
    return _PASSWORD_PARTS[1].sub(r"\1***", shown)


def check_lab_url(url: str, option: str = "lab store") -> None:
    """Refuse, in one :class:`LabURLError` line with the password hidden, a lab store address that is not a
    well-formed PostgreSQL URL: another scheme, a malformed host, an unknown parameter, a port out of range. Nothing
    is connected to; a bad value that only libpq knows (``sslmode=bogus``) is refused by :func:`connect` as fast."""
    shown = redacted(url)
    if not is_lab_url(url):
        raise LabURLError(f"{option} {shown}: expected a postgresql://USER:PASSWORD@HOST/DBNAME URL")
    psycopg = _psycopg()
    try:
        options = psycopg.conninfo.conninfo_to_dict(url)
    except psycopg.ProgrammingError as exc:
        raise LabURLError(f"{option} {shown}: not a valid PostgreSQL URL ({redacted(_one_line(exc))})") from None
    for port in str(options.get("port", "5432")).split(","):
        if not (port.isdigit() and 1 <= int(port) <= 65535):
            raise LabURLError(f"{option} {shown}: port {port!r}, expected a number from 1 to 65535")


def _psycopg():
    from bench.extras import require

    return require("psycopg")


def _one_line(exc: BaseException) -> str:
    lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
    return lines[0] if lines else type(exc).__name__


def connect(url: str, *, connect_timeout_s: int = 5):
    """An open psycopg connection to ``url``; :class:`LabStoreError` says in one line what is wrong."""
    check_lab_url(url)
    psycopg = _psycopg()
    shown = redacted(url)
    try:
        return psycopg.connect(url, connect_timeout=connect_timeout_s)
    except psycopg.OperationalError as exc:
        detail = redacted(_one_line(exc))
        if _BAD_OPTION.match(detail):
            raise LabURLError(f"lab store {shown}: not a usable PostgreSQL URL ({detail})") from None
        if "password authentication failed" in detail or "no password supplied" in detail:
            raise LabStoreError(f"lab store {shown}: bad credentials ({detail})") from exc
        if any(words in detail for words in _BUSY):
            raise LabServerBusy(f"lab store {shown}: server busy, no connection slot free ({detail})") from exc
        if "does not exist" in detail:
            raise LabStoreError(f"lab store {shown}: {detail}") from exc
        raise LabStoreError(f"lab store {shown}: server unreachable ({detail})") from exc


def ensure_schema(conn, url: str) -> None:
    """Create the lab schema when missing; refuse a server whose schema is newer than this bench's."""
    with conn.transaction():
        conn.execute("SELECT pg_advisory_xact_lock(%s)", (_LOCK_KEY,))
        row = conn.execute("SELECT to_regclass('bench.schema_version')").fetchone()
        if row[0] is not None:
            found = conn.execute("SELECT max(version) FROM bench.schema_version").fetchone()[0]
            if found is not None and found > LAB_SCHEMA_VERSION:
                raise LabStoreError(
                    f"lab store {redacted(url)}: server schema version {found} is newer than "
                    f"this bench's ({LAB_SCHEMA_VERSION}); upgrade bench to sync"
                )
            if found == LAB_SCHEMA_VERSION:
                return
        else:
            found = None
        conn.execute(_DDL)
        conn.execute(typed_columns_ddl("bench.samples"))
        if found == 1:  # version 1 had no typed columns: fill them from the JSON the server holds
            conn.execute(_BACKFILL_TYPED)  # (before the pose triggers, which would refold every run it updates)
        conn.execute(POSE_TABLES_DDL)
        if found in (1, 2):  # versions 1 and 2 had no pose tables: fold the samples the server holds
            conn.execute(POSE_TABLES_BACKFILL)
            _log.warning("lab store %s: schema version %s migrated to %s", redacted(url), found, LAB_SCHEMA_VERSION)
        conn.execute("DELETE FROM bench.schema_version")
        conn.execute("INSERT INTO bench.schema_version VALUES (%s)", (LAB_SCHEMA_VERSION,))


def rows_checksum(rows: Iterable[tuple]) -> str:
    """SHA-256 over a run's sample rows in step order (``Store.stored_rows`` layout), one JSON line per row.

    Equal on the local file and on the server exactly when every stored column of every sample is equal
    (floats compared through their shortest round-trip repr)."""
    digest = hashlib.sha256()
    for row in rows:
        digest.update(json.dumps(list(row), allow_nan=False).encode())
        digest.update(b"\n")
    return digest.hexdigest()


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


def _run_row(store: Store, run: RunRecord, calibration_uuids: dict[int, str]) -> tuple:
    return (
        run.uuid,
        run.bench,
        run.id,
        run.campaign,
        run.protocol_name,
        run.protocol_version,
        run.robot,
        json.dumps(run.config, sort_keys=True),
        json.dumps(run.settings, sort_keys=True),
        json.dumps(list(run.calibration_ids)),
        json.dumps([calibration_uuids.get(i) for i in run.calibration_ids]),
        run.software_version,
        run.git_sha,
        run.status,
        run.reason,
        run.started_utc,
        run.ended_utc,
    )


def _copy(cur, table: str, chunks: list[bytes]) -> None:
    """COPY the formatted ``chunks`` into ``table``, one write each (the server parses one while the next goes)."""
    with cur.copy(f"COPY {table} ({_COPY_COLUMNS}) FROM STDIN") as copy:
        for chunk in chunks:
            copy.write(chunk)


def _read_batches(
    store: Store, run: RunRecord, held: set[int], batch_size: int
) -> Iterator[tuple[list[bytes], int, RunRecord]]:
    """The samples of ``run`` that the server lacks (steps not in ``held``), batch by batch: each batch as its COPY
    text in chunks of :data:`_CHUNK_ROWS` rows at most, its number of samples (``batch_size`` at most), the run."""
    rows = store.stored_rows(run.id, extract=TYPED_COLUMNS)
    exhausted = False
    while not exhausted:
        chunks, n = [], 0
        while n < batch_size:
            chunk = rows.fetchmany(min(_CHUNK_ROWS, batch_size - n))
            if not chunk:
                exhausted = True
                break
            if held:
                chunk = [row for row in chunk if row[0] not in held]
            if chunk:
                chunks.append(copy_text(run.uuid, chunk))
                n += len(chunk)
        if n:
            yield chunks, n, run


def _send_batch(conn, chunks: list[bytes], n: int) -> int:
    """Store one batch in its own transaction; returns how many of its ``n`` samples were new on the server."""
    psycopg = _psycopg()
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


def _held_steps(conn, runs: list[RunRecord]) -> dict[str, set[int] | None]:
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


def _prepare_sender(conn) -> None:
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
    store: Store,
    lanes: list[list[RunRecord]],
    connections: list,
    held: dict[str, set[int] | None],
    *,
    batch_size: int,
    progress: Callable[[str], None],
    sent: list[int],
) -> None:
    """Send the lanes' batches, each lane through its own connection and sender thread, one batch in flight per
    lane; this thread reads and formats the next batches meanwhile, taking the lanes in turn."""
    batches = [
        itertools.chain.from_iterable(_read_batches(store, run, held[run.uuid], batch_size) for run in lane)
        for lane in lanes
    ]
    in_flight: list[tuple | None] = [None] * len(lanes)
    with ThreadPoolExecutor(max_workers=len(lanes), thread_name_prefix="lab-sync") as senders:
        live = list(range(len(lanes)))
        try:
            while live:
                for lane in list(live):
                    batch = next(batches[lane], None)
                    if in_flight[lane] is not None:
                        _settle(*in_flight[lane], progress=progress, sent=sent)
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


def _settle(batch: Future, run: RunRecord, n: int, *, progress: Callable[[str], None], sent: list[int]) -> None:
    """Wait for a batch sent (its exception raised here), count its new samples once committed, report it."""
    sent[0] += batch.result()
    progress(f"sync: run {run.id} ({run.uuid}) +{n} samples")


def _push(
    store: Store, conn, url: str, *, batch_size: int, progress: Callable[[str], None], sent: list[int]
) -> tuple[int, int]:
    """Upsert runs and calibrations, then send the samples the server lacks; ``sent[0]`` counts the samples
    committed (kept when a later batch fails)."""
    calibrations = store.calibrations()
    runs = store.runs()
    run_uuids = {r.id: r.uuid for r in runs}
    calibration_uuids = {c.id: c.uuid for c in calibrations}
    placeholders = ", ".join(["%s"] * len(_RUN_COLUMNS))
    updates = ", ".join(f"{c} = EXCLUDED.{c}" for c in _RUN_COLUMNS[1:])
    with conn.transaction(), conn.cursor() as cur:
        cur.executemany(
            f"INSERT INTO bench.runs ({', '.join(_RUN_COLUMNS)}) VALUES ({placeholders})"
            f" ON CONFLICT (uuid) DO UPDATE SET {updates}, synced_utc = now()",
            [_run_row(store, r, calibration_uuids) for r in runs],
        )
        cur.executemany(
            "INSERT INTO bench.calibrations (uuid, bench, local_id, name, version, created_utc, params_json,"
            " source_run_uuid, notes) VALUES (%s, %s, %s, %s, %s, %s, %s, %s, %s) ON CONFLICT (uuid) DO NOTHING",
            [
                (
                    c.uuid,
                    store.bench,
                    c.id,
                    c.name,
                    c.version,
                    c.created_utc,
                    json.dumps(c.params, sort_keys=True),
                    run_uuids.get(c.source_run_id),
                    c.notes,
                )
                for c in calibrations
            ],
        )
    conn.commit()
    held = _held_steps(conn, runs)
    to_send = [run for run in runs if held[run.uuid] is not None]
    lanes = _deal(to_send, held, _LANES)
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
        _send_lanes(store, lanes, connections, held, batch_size=batch_size, progress=progress, sent=sent)
    finally:
        for lane_conn in connections[1:]:
            lane_conn.close()
    return len(runs), len(calibrations)


def sync_store(
    store: Store,
    url: str,
    *,
    batch_size: int = 20_000,
    retries: int = 3,
    retry_wait_s: float = 1.0,
    busy_wait_s: float = 600.0,
    progress: Callable[[str], None] | None = None,
) -> SyncResult:
    """Push every run, calibration and sample of ``store`` that the server at ``url`` lacks (see the module
    docstring); after a lost connection, reconnect and resume up to ``retries`` times (waits ``retry_wait_s``,
    then twice that, ...). A server with no connection slot free (:class:`LabServerBusy`) is asked again after a
    random wait (0.5-1.5 times ``retry_wait_s``, doubling up to 30 s), for ``busy_wait_s`` in all: a crowd of benches
    syncing at once shares the server's connections instead of failing.

    Raises
    ------
    LabStoreError
        Bad URL or credentials, a newer server schema (at once); an unreachable server after the retries.
    """
    psycopg = _psycopg()
    report = progress or (lambda line: _log.info("%s", line))
    started = time.perf_counter()
    sent, attempt, busy = [0], 0, 0
    while True:
        try:
            conn = connect(url)
            try:
                ensure_schema(conn, url)
                runs, calibrations = _push(store, conn, url, batch_size=batch_size, progress=report, sent=sent)
            finally:
                conn.close()
            return SyncResult(runs, calibrations, sent[0], time.perf_counter() - started)
        except LabServerBusy as exc:
            wait = min(30.0, retry_wait_s * 2 ** min(busy, 10)) * random.uniform(0.5, 1.5)
            if time.perf_counter() - started + wait > busy_wait_s:
                raise
            busy += 1
            if busy == 1:
                report(f"sync: {_one_line(exc)}; waiting for a free connection")
            time.sleep(wait)
        except (psycopg.OperationalError, LabStoreError) as exc:  # (a LabURLError is no LabStoreError: at once)
            retryable = isinstance(exc, psycopg.OperationalError) or "server unreachable" in str(exc)
            if not retryable or attempt >= retries:
                if isinstance(exc, LabStoreError):
                    raise
                raise LabStoreError(
                    f"lab store {redacted(url)}: connection lost ({_one_line(exc)}); run bench sync again to resume"
                ) from exc
            attempt += 1
            report(f"sync: {_one_line(exc)}; retry {attempt} of {retries}")
            time.sleep(retry_wait_s * 2 ** (attempt - 1))


def sync_after_run(store: Store, url: str, *, say: Callable[[str], None] | None = None) -> SyncResult | None:
    """Sync ``store`` to ``url`` once a run has ended (``[lab_store] auto_sync``), never failing the run: any
    failure (server down, credentials, a bug) is one line on stderr (``say``) and the next sync catches up, since
    the local file stays the source of truth. Returns the result, or None when the sync failed."""
    tell = say or (lambda line: print(line, file=sys.stderr, flush=True))
    try:
        result = sync_store(store, url, retries=1, retry_wait_s=0.5, busy_wait_s=30.0, progress=lambda line: None)
    except BenchError as exc:
        tell(f"bench: lab store sync failed, the run is kept locally (bench sync catches up): {_one_line(exc)}")
        return None
    except Exception as exc:  # noqa: BLE001 - the local run must survive whatever the sync meets
        _log.exception("lab store sync after the run failed")
        tell(
            f"bench: lab store sync failed, the run is kept locally (bench sync catches up): "
            f"{type(exc).__name__}: {_one_line(exc)}"
        )
        return None
    tell(f"bench: synced to the lab store {redacted(url)}: {result.samples_sent} new samples")
    return result


class LabStore:
    """Read-only access to the lab store's runs, the same records as :class:`Store` gives (``id`` is the run's id
    in its bench's file; ``n_samples`` counts the samples synced)."""

    def __init__(self, url: str) -> None:
        self.path = redacted(url)
        self._conn = connect(url)
        self._conn.read_only = True
        found = self._conn.execute("SELECT to_regclass('bench.runs')").fetchone()[0]
        if found is None:
            self._conn.close()
            raise LabStoreError(f"lab store {self.path}: no bench data yet (run bench sync first)")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self._conn.close()

    def runs(self, *, bench: str | None = None, robot: str | None = None, since: str | None = None) -> list[RunRecord]:
        """Every synced run, oldest first, optionally filtered as :meth:`Store.runs` is."""
        clauses, args = [], []
        for clause, value in (("r.bench = %s", bench), ("r.robot = %s", robot), ("r.started_utc >= %s", since)):
            if value is not None:
                clauses.append(clause)
                args.append(value)
        where = "WHERE " + " AND ".join(clauses) if clauses else ""
        rows = self._conn.execute(
            "SELECT r.local_id, r.uuid::text, r.bench, r.campaign, r.protocol_name, r.protocol_version, r.robot,"
            " r.config_json, r.settings_json, r.calibration_ids_json, r.software_version, r.git_sha, r.status,"
            " r.reason, r.started_utc, r.ended_utc,"
            " (SELECT count(*) FROM bench.samples s WHERE s.run_uuid = r.uuid)"
            f" FROM bench.runs r {where} ORDER BY r.started_utc, r.bench, r.local_id",
            args,
        ).fetchall()
        self._conn.rollback()
        return [
            RunRecord(
                id=r[0],
                uuid=r[1],
                bench=r[2],
                campaign=r[3],
                protocol_name=r[4],
                protocol_version=r[5],
                robot=r[6],
                config=json.loads(r[7]),
                settings=json.loads(r[8]),
                calibration_ids=tuple(json.loads(r[9])),
                software_version=r[10],
                git_sha=r[11],
                status=r[12],
                reason=r[13],
                started_utc=r[14],
                ended_utc=r[15],
                n_samples=int(r[16]),
            )
            for r in rows
        ]

    def checksum(self, run_uuid: str) -> str:
        """:func:`rows_checksum` of the samples the server holds for ``run_uuid``."""
        rows = self._conn.execute(
            f"SELECT {_SAMPLE_COLUMNS} FROM bench.samples WHERE run_uuid = %s ORDER BY step_index", (run_uuid,)
        )
        result = rows_checksum(rows)
        self._conn.rollback()
        return result

    def query(self, sql: str, args: Any = (), *, settings: Mapping[str, str] | None = None) -> list[tuple]:
        """Rows of a read-only SQL query over the lab schema (for lab-wide analyses and benchmarks); ``settings``
        (e.g. ``{"work_mem": "256MB"}``) are server settings for this query's transaction only."""
        for name, value in (settings or {}).items():
            self._conn.execute("SELECT set_config(%s, %s, true)", (name, value))
        cursor = self._conn.execute(sql, args)
        rows = cursor.fetchall() if cursor.description else []
        self._conn.rollback()
        return rows


def open_runs_store(spec: str, **store_args: Any) -> Store | LabStore:
    """A :class:`LabStore` for a ``postgresql://`` address, else the SQLite :class:`Store` file."""
    return LabStore(spec) if is_lab_url(spec) else Store(spec, **store_args)
