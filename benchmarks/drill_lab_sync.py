"""The issue's 10-bench acceptance as a drill (the test suite runs it with 4 benches, tests/test_store_sync.py).

``--benches`` simulated benches (local stores of ``--samples`` pose samples each, in two runs) sync at once into one
throwaway PostgreSQL cluster (``tests/postgres_support.py``), each in its own ``bench sync`` process; one of them is
killed with SIGKILL after ``--kill-after`` committed batches, then the server is stopped (fast shutdown) and started
again ``--down-s`` later while the others sync (they reconnect: ``--retries``); the killed bench syncs again. Then,
and only then, it checks: every sample of every run on the server exactly once, the checksum of every run equal to
its local store's (``rows_checksum``), and the pose tables of the lab summary holding every pose sample once. Prints
one line per check and the times; exit status 1 when a check fails.

Usage: ``python benchmarks/drill_lab_sync.py [--benches 10] [--samples 20000] [--batch 1000]``.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from postgres_support import Cluster, _bindir, make_store, with_database

from bench.store import Store
from bench.store.lab import LabStore, rows_checksum, sync_store


def _sync(path: Path, url: str, batch: int, retries: int, **streams) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "bench.cli",
            "sync",
            "--store",
            str(path),
            "--to",
            url,
            "--batch",
            str(batch),
            "--retries",
            str(retries),
        ],
        cwd=ROOT,
        text=True,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        **streams,
    )


@contextmanager
def drill_server(name: str, *settings: str) -> Iterator[tuple[Cluster, str, Path]]:
    """A throwaway cluster with database ``name`` (``settings``: ``ALTER SYSTEM SET`` lines, then a restart), its
    URL and a work folder; all removed afterwards."""
    if _bindir() is None:
        sys.exit(f"drill {name}: no PostgreSQL (install Debian's postgresql: initdb, pg_ctl)")
    cluster = Cluster(_bindir())
    work = Path(tempfile.mkdtemp(prefix=f"bench-{name}-"))
    try:
        import psycopg

        with psycopg.connect(cluster.url, autocommit=True) as admin:
            admin.execute(f'CREATE DATABASE "{name}"')
            for setting in settings:
                admin.execute(f"ALTER SYSTEM SET {setting}")
        if settings:
            cluster.stop()
            cluster.start()
        yield cluster, with_database(cluster.url, name), work
    finally:
        cluster.close()
        for path in work.glob("*"):
            path.unlink()
        work.rmdir()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benches", type=int, default=10, help="simulated benches syncing at once")
    parser.add_argument("--samples", type=int, default=20_000, help="samples per bench (two runs)")
    parser.add_argument("--batch", type=int, default=1000, help="samples per sync transaction")
    parser.add_argument("--kill-after", type=int, default=3, help="committed batches before the SIGKILL")
    parser.add_argument("--down-s", type=float, default=1.0, help="seconds the server stays down")
    parser.add_argument("--retries", type=int, default=8, help="reconnections each sync may make")
    args = parser.parse_args(argv)
    with drill_server("drill") as (cluster, url, work):
        half = args.samples // 2
        paths = [
            make_store(
                work / f"bench{i:02d}.db",
                f"bench-{i:02d}",
                [args.samples - half, half],
                robot=("pkm5", "delta4")[i % 2],
            )
            for i in range(args.benches)
        ]
        start = time.perf_counter()
        victim = _sync(paths[0], url, args.batch, args.retries, stderr=subprocess.PIPE)
        others = [
            _sync(p, url, args.batch, args.retries, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for p in paths[1:]
        ]
        seen = 0
        for line in victim.stderr:
            seen += line.startswith("sync: run ")
            if seen == args.kill_after:
                os.kill(victim.pid, signal.SIGKILL)
                break
        victim.wait(timeout=60)
        print(f"bench-00 killed (SIGKILL) after {seen} batches, {time.perf_counter() - start:.1f} s in")
        cluster.stop("fast")
        restart = threading.Timer(args.down_s, cluster.start)
        restart.start()
        restart.join()
        print(f"server stopped and started again after {args.down_s:g} s")
        codes = [p.wait(timeout=600) for p in others]
        with Store(paths[0]) as store:
            again = sync_store(store, url)
        elapsed = time.perf_counter() - start
        print(
            f"other benches' syncs exited {sorted(set(codes))}; bench-00 synced again: {again.samples_sent} samples "
            f"sent; {elapsed:.1f} s in all"
        )

        expected, pose_samples = {}, 0
        for path in paths:
            with Store(path) as store:
                for run in store.runs():
                    expected[run.uuid] = rows_checksum(store.stored_rows(run.id))
                    pose_samples += store.sample_kinds(run.id).get("pose", 0)
        with LabStore(url) as lab:
            total, distinct = lab.query("SELECT count(*), count(DISTINCT (run_uuid, step_index)) FROM bench.samples")[0]
            checksums = {r.uuid: lab.checksum(r.uuid) for r in lab.runs()}
            points, folded = lab.query(
                "SELECT (SELECT sum(cardinality(x_mm)) FROM bench.pose_point_sets), (SELECT sum(n) FROM bench.pose_keys)"
            )[0]
        want = args.benches * args.samples
        checks = [
            (
                f"samples on the server {total:,}, distinct (run, step) {distinct:,}, expected {want:,}",
                total == distinct == want,
            ),
            (
                f"checksums equal to the local stores' for {sum(checksums.get(u) == d for u, d in expected.items())}"
                f" of {len(expected)} runs",
                checksums == expected,
            ),
            (
                f"pose tables: {points:,} points, sums over {int(folded or 0):,} samples, expected {pose_samples:,}",
                points == folded == pose_samples,
            ),
            ("every sync exited 0 (bench-00's second by the API)", codes == [0] * len(others)),
        ]
        for text, ok in checks:
            print(f"{'ok  ' if ok else 'FAIL'} {text}")
        print(f"load average: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")
        return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
