"""Lab-store sync throughput and a cross-bench query, measured in one run (prints figures and ratios, asserts nothing).

* Sync: ``--benches`` local stores of ``--samples`` pose samples each (in ``--runs`` runs) are pushed with
  ``sync_store`` into one PostgreSQL server: the first ``--sequential`` (5) one after the other, each twice, into
  two databases: reading and formatting in the sync's own thread (``producers=0``, the default below 4 cores) and
  in two producer processes (``producers=2``, the default for a large sync on 4 cores or more; samples/s of each:
  min/median/max); the rest at once, one process each (aggregate samples/s from the first start to the last end,
  imports excluded). With the throwaway cluster, also the CPU microseconds per sample of this process with its
  producer processes (SQLite read, formatting) and of the server (every postgres process of the cluster, the
  exited backends included; autovacuum off while timing, so that one sync's later vacuum never lands in
  another's figure), which depend far less on the machine's load than the wall clock does.
* Floor: a bare COPY of the same rows (the same COPY text, typed columns and checksums included, formatted
  beforehand) into a table of the same server without key or trigger (no SQLite read, no formatting, one
  connection), logged (written through the write-ahead log, as any durable table is: the floor the target uses)
  and unlogged (no WAL: a lower floor no durable store reaches), right after each bench's syncs, so that each ratio
  sync/floor is taken at one load (min/median/max over the benches). The floor's CPU (server and this process)
  over the sync's is the ratio on a machine whose cores are all busy, where wall time is CPU time shared.
* Sending alone: each file synced again into a fresh database with its batches read and formatted before the
  clock starts: the server's side of a sync (two lanes, the key, the triggers) against the floor, without the
  client's SQLite read and formatting sharing the cores.
* Query: ``bench lab summary`` (``bench.store.lab_summary.pose_summary``: AP and RP, ISO 9283 7.2.1 and 7.2.2, per
  bench, robot, ISO week, pose, velocity and commanded position) over every synced sample, five times, after
  ANALYZE of bench.samples (what autovacuum does soon after a large sync); the pose tables the summary reads are
  left unanalysed, the worst case right after a sync.

Server: ``BENCH_TEST_POSTGRES`` when set, else a throwaway cluster (``tests/postgres_support.py``; needs Debian's
postgresql). Usage: ``python benchmarks/bench_sync.py [--benches 10] [--samples 100000] [--runs 4]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from postgres_support import Cluster, _bindir, make_store, with_database  # noqa: E402

from bench.store import Store  # noqa: E402
from bench.store.lab import LabStore, sync_store  # noqa: E402
from bench.store.lab_copy import COPY_COLUMNS, copy_text  # noqa: E402
from bench.store.lab_summary import pose_summary  # noqa: E402
from bench.store.lab_sync import LANES  # noqa: E402

#: A bench syncing in its own process: prints the wall-clock start and end of its sync (imports excluded).
_CHILD = """
import sys, time
from bench.store import Store
from bench.store.lab import sync_store
with Store(sys.argv[1]) as store:
    start = time.time()
    sync_store(store, sys.argv[2])
    print(start, time.time())
"""


def _database(url: str, name: str) -> str:
    import psycopg

    with psycopg.connect(url, autocommit=True) as admin:
        admin.execute(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.execute(f'CREATE DATABASE "{name}"')
    return with_database(url, name)


def copy_floor(url: str, path: Path, cluster: Cluster | None, *, logged: bool) -> tuple[float, float, float]:
    """A bare COPY of the samples of ``path`` (as sync formats them, formatted beforehand) into a table without key
    or trigger, ``logged`` (written through the write-ahead log, as any durable table) or not: samples/s, and the
    CPU microseconds per sample of this process and of the server (NaN for a server that is not ours)."""
    import psycopg

    with Store(path) as store, psycopg.connect(url) as conn:
        data = [copy_text(r.uuid, store.stored_rows(r.id, checksum=True)) for r in store.runs()]
        n = sum(r.n_samples for r in store.runs())
        conn.execute(f"CREATE {'' if logged else 'UNLOGGED '}TABLE floor (LIKE bench.samples)")
        conn.commit()
        columns = ", ".join(f'"{c}"' for c in COPY_COLUMNS)
        cpu, server, start = time.process_time(), server_cpu_s(cluster), time.perf_counter()
        with conn.cursor() as cur, cur.copy(f"COPY floor ({columns}) FROM STDIN") as copy:
            for chunk in data:
                copy.write(chunk)
        conn.commit()
        elapsed = time.perf_counter() - start
        client_s, server_s = time.process_time() - cpu, server_cpu_s(cluster) - server
        conn.execute("DROP TABLE floor")
        conn.commit()
    return n / elapsed, client_s / n * 1e6, server_s / n * 1e6


def timed_sync(path: Path, url: str, cluster: Cluster | None, producers: int) -> tuple[float, float, float, float]:
    """Sync ``path`` to ``url`` with ``producers`` producer processes: samples/s, and the CPU microseconds per
    sample of this process, of its producers (``os.times``: children once waited for) and of the server."""
    with Store(path) as store:
        before, server = os.times(), server_cpu_s(cluster)
        result = sync_store(store, url, producers=producers)
        after = os.times()
    own = after.user + after.system - before.user - before.system
    children = after.children_user + after.children_system - before.children_user - before.children_system
    return (
        result.samples_per_s,
        own / result.samples_sent * 1e6,
        children / result.samples_sent * 1e6,
        (server_cpu_s(cluster) - server) / result.samples_sent * 1e6,
    )


def send_only(path: Path, url: str) -> float:
    """Sync ``path`` to ``url`` with every batch read and formatted before the clock starts (no producers): the
    samples/s of sending alone, the server's side of a sync (two lanes, the key, the triggers) without the client's
    reading and formatting beside it on the same cores."""
    import bench.store.lab_sync as lab_sync

    formatted = lab_sync.lane_batches
    ready = [0.0]

    @contextmanager
    def beforehand(*args, **kwargs):
        with formatted(*args, **kwargs) as batches:
            lanes = [list(lane) for lane in batches]
            ready[0] = time.perf_counter()
            yield [iter(lane) for lane in lanes]

    lab_sync.lane_batches = beforehand
    try:
        with Store(path) as store:
            result = sync_store(store, url, producers=0)
            elapsed = time.perf_counter() - ready[0]
    finally:
        lab_sync.lane_batches = formatted
    return result.samples_sent / elapsed


def _autovacuum(url: str, setting: str) -> None:
    """Autovacuum on or off for the throwaway cluster: off while syncs and floors are timed, so that the vacuum and
    analysis of one sync's rows (due once per table, later) never land in another's CPU; on for the summary."""
    import psycopg

    with psycopg.connect(url, autocommit=True) as admin:
        admin.execute(f"ALTER SYSTEM SET autovacuum = {setting}")
        admin.execute("SELECT pg_reload_conf()")


def _spread(values: list[float], form: str) -> str:
    return f"min {min(values):{form}}  median {statistics.median(values):{form}}  max {max(values):{form}}"


def server_cpu_s(cluster: Cluster | None, *, background: bool = False) -> float:
    """CPU seconds used so far by the throwaway cluster's connections: the backends it has reaped (the postmaster's
    cutime, cstime: autovacuum is off while timing) and the live ones (proc(5): utime, stime); with
    ``background``, those of its background processes instead (checkpointer, WAL writer, background writer: the
    durable writes' later work, which lands in whichever window runs then). NaN for a server that is not ours."""
    if cluster is None:
        return float("nan")
    tick = os.sysconf("SC_CLK_TCK")
    postmaster = int((cluster.root / "data" / "postmaster.pid").read_text().split()[0])

    def fields(pid: int) -> list[str]:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()

    main_fields = fields(postmaster)
    total = 0 if background else sum(int(main_fields[i]) for i in (13, 14))
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                child = fields(int(entry.name))
                backend = (entry / "cmdline").read_bytes().startswith(b"postgres: bench ")
            except OSError:  # exited meanwhile: its time is in the postmaster's cutime, cstime
                continue
            if int(child[1]) == postmaster and backend != background:
                total += int(child[11]) + int(child[12])
    if background:
        total += int(main_fields[11]) + int(main_fields[12])
    return total / tick


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benches", type=int, default=10, help="simulated benches (local stores)")
    parser.add_argument("--samples", type=int, default=100_000, help="samples per bench")
    parser.add_argument("--runs", type=int, default=4, help="runs per bench")
    parser.add_argument("--sequential", type=int, default=5, help="benches synced one after the other")
    args = parser.parse_args(argv)

    cluster = None
    server = os.environ.get("BENCH_TEST_POSTGRES")
    if not server:
        if _bindir() is None:
            sys.exit("bench_sync: no PostgreSQL (set BENCH_TEST_POSTGRES or install postgresql)")
        cluster = Cluster(_bindir())
        server = cluster.url
        _autovacuum(server, "off")
    work = Path(tempfile.mkdtemp(prefix="bench-sync-"))
    try:
        start = time.perf_counter()
        per_run = [args.samples // args.runs] * args.runs
        stores = [
            make_store(work / f"bench{i:02d}.db", f"bench-{i:02d}", per_run, robot=("pkm5", "delta4")[i % 2])
            for i in range(args.benches)
        ]
        total = sum(per_run) * args.benches
        print(
            f"local stores       {args.benches} benches x {sum(per_run):,} samples written in "
            f"{time.perf_counter() - start:.1f} s"
        )

        print(f"load average before the syncs: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
        variants = {"in this thread": 0, "1 producer": 1, f"{LANES} producers": LANES}
        urls = {name: _database(server, f"bench_sync_benchmark_{i}") for i, name in enumerate(variants)}
        sending: list[float] = []
        url = urls["in this thread"]  # the one the concurrent syncs and the summary use
        rates: dict[str, list[float]] = {name: [] for name in variants}
        cpu: dict[str, list[tuple[float, float, float]]] = {name: [] for name in variants}
        floors: dict[str, list[tuple[float, float, float]]] = {"logged": [], "unlogged": []}
        n = sum(per_run)
        background = server_cpu_s(cluster, background=True)
        for path in stores[: args.sequential]:  # the syncs and floors of one file in a row: the load moves
            for name, producers in variants.items():
                rate, *cpu_us = timed_sync(path, urls[name], cluster, producers)
                rates[name].append(rate)
                cpu[name].append((cpu_us[0], cpu_us[1], cpu_us[2]))
            for kind in floors:
                floors[kind].append(copy_floor(url, path, cluster, logged=kind == "logged"))
            sending.append(send_only(path, _database(server, "bench_sync_benchmark_send")))
        background = server_cpu_s(cluster, background=True) - background
        floor_cpu = {kind: [statistics.median(v[i] for v in values) for i in (1, 2)] for kind, values in floors.items()}
        for kind, values in floors.items():
            print(
                f"floor: bare COPY, {kind + ' table':<15} {n:,} samples: {_spread([v[0] for v in values], '9,.0f')}"
                f" samples/s; CPU per sample (medians): this process {floor_cpu[kind][0]:.1f} us, server"
                f" {floor_cpu[kind][1]:.1f} us"
            )
        print(
            f"server's background processes (checkpoints, WAL writer): {background / n / args.sequential * 1e6:.1f} us"
            " a sample synced, over every sync and floor above (in none of their figures)"
        )
        for name, producers in variants.items():
            print(f"sync, {name:<21} {n:,} samples: {_spread(rates[name], '9,.0f')} samples/s")
            for kind, values in floors.items():
                ratios = [rate / floor[0] for rate, floor in zip(rates[name], values)]
                print(f"    sync / floor ({kind + ')':<9} {_spread(ratios, '.2f')}")
            own, children, server_us = (statistics.median(c[i] for c in cpu[name]) for i in (0, 1, 2))
            print(
                f"    CPU per sample (medians): this process {own:.1f} us, its producers {children:.1f} us, server"
                f" {server_us:.1f} us"
            )
            floor_own, floor_server = floor_cpu["logged"]
            # all cores busy: wall time is CPU time shared out; a core free for each process: its busiest one sets
            # the pace (the producers and the server's lanes share their CPU evenly: the runs are dealt by samples)
            busiest = max(own, children / max(producers, 1), server_us / LANES)
            print(
                f"    floor (logged) CPU / sync CPU: all of it {(floor_own + floor_server) / (own + children + server_us):.2f}"
                f" (the ratio on a machine with every core busy); the busiest process's"
                f" {max(floor_own, floor_server) / busiest:.2f} (the ratio with a core free for each process)"
            )

        ratios = [rate / floor[0] for rate, floor in zip(sending, floors["logged"])]
        print(
            f"sending alone (batches read and formatted beforehand) {n:,} samples: {_spread(sending, '9,.0f')}"
            f" samples/s; / floor (logged) {_spread(ratios, '.2f')}"
        )

        rest = stores[args.sequential :]
        if rest:  # one process per bench; the window runs from the first sync's start to the last one's end
            procs = [
                subprocess.Popen(
                    [sys.executable, "-c", _CHILD, str(p), url],
                    cwd=ROOT,
                    stdout=subprocess.PIPE,
                    text=True,
                    env={**os.environ, "PYTHONPATH": str(ROOT)},
                )
                for p in rest
            ]
            spans = [tuple(map(float, p.communicate()[0].split())) for p in procs]
            window = max(end for _, end in spans) - min(start for start, _ in spans)
            n = sum(per_run) * len(rest)
            print(
                f"sync, {len(rest)} at once    {n:>9,} samples  {window:7.2f} s  {n / window:9,.0f} samples/s aggregate"
            )

        import psycopg

        if cluster is not None:
            _autovacuum(server, "on")
        with psycopg.connect(url, autocommit=True) as conn:  # the statistics autovacuum would have gathered by now
            conn.execute("ANALYZE bench.runs")
            conn.execute("ANALYZE bench.samples")
        with LabStore(url) as lab:
            held = lab.query("SELECT count(*) FROM bench.samples")[0][0]
            times, groups = [], []
            for _ in range(5):
                start = time.perf_counter()
                groups = pose_summary(lab, since="2026-01-01")
                times.append(time.perf_counter() - start)
        print(
            f"lab summary (AP/RP per bench, robot, week, pose, velocity) over {held:,} samples (expected "
            f"{total:,}), {len(groups)} groups: min {min(times):.3f}  median {statistics.median(times):.3f}  "
            f"max {max(times):.3f} s"
        )
        print(f"load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
    finally:
        if cluster is not None:
            cluster.close()
        for path in work.glob("*"):
            path.unlink()
        work.rmdir()


if __name__ == "__main__":
    main()
