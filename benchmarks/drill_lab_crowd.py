"""A crowd of benches syncing at once into one PostgreSQL server through its bounded connections, as a drill.

``--benches`` simulated benches (default 500; local stores of ``--samples`` pose samples each, in two runs) start
``sync_store`` at the same moment, each in its own thread of this process, against one throwaway cluster
(``tests/postgres_support.py``) whose ``max_connections`` is ``--max-connections`` (default 100, PostgreSQL's
default). A bench the server turns away ("too many clients") waits a jittered, growing while and asks again
(``LabServerBusy``); a bench that gets one slot sends through it alone. A monitor samples the server's open
connections. The server logs every session's start and end (``log_connections``, ``log_disconnections``; each
bench's sessions named by ``application_name``), from which ``postgres_support.connection_peaks`` counts exactly
the most sessions each bench held at once and the most the server held at once. Then it checks: every sample of
every run on the server exactly once, every run's checksum equal to its local store's, every sync returned, every
bench within its bound (``LANES`` connections: the first one is also the first sender, see
``bench.store.lab_sync``), the server within ``max_connections``. Prints the peak connections, the benches that
had to wait, the times, and one line per check; exit status 1 when a check fails.

Usage: ``python benchmarks/drill_lab_crowd.py [--benches 500] [--samples 200] [--max-connections 100]``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from drill_lab_sync import drill_server
from postgres_support import connection_peaks, make_store

from bench.store import Store
from bench.store.lab import LabStore, rows_checksum, sync_store
from bench.store.lab_sync import LANES


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benches", type=int, default=500, help="simulated benches syncing at once")
    parser.add_argument("--samples", type=int, default=200, help="samples per bench (two runs)")
    parser.add_argument("--max-connections", type=int, default=100, help="the server's max_connections")
    args = parser.parse_args(argv)
    settings = (f"max_connections = {int(args.max_connections)}", "log_connections = on", "log_disconnections = on")
    with drill_server("crowd", *settings) as (cluster, url, work):
        import psycopg

        half = args.samples // 2
        start = time.perf_counter()
        paths = [
            make_store(work / f"bench{i:03d}.db", f"bench-{i:03d}", [args.samples - half, half])
            for i in range(args.benches)
        ]
        print(f"{args.benches} stores of {args.samples} samples written in {time.perf_counter() - start:.1f} s")
        monitor = psycopg.connect(url, autocommit=True)  # before the crowd: the drill's own slot
        open_connections, done = [], threading.Event()

        def watch() -> None:
            while not done.is_set():
                open_connections.append(
                    monitor.execute(
                        "SELECT count(*) FROM pg_stat_activity WHERE backend_type = 'client backend'"
                    ).fetchone()[0]
                )
                time.sleep(0.05)

        results: dict[int, object] = {}
        waited: set[int] = set()
        go = threading.Barrier(args.benches)

        def bench(i: int) -> None:
            with Store(paths[i], read_only=True) as store:
                go.wait()
                began = time.perf_counter()
                try:
                    sync_store(
                        store,
                        f"{url}&application_name=bench-{i:03d}",
                        batch_size=1000,
                        retries=5,
                        retry_wait_s=0.2,
                        busy_wait_s=900,
                        progress=lambda line: waited.add(i) if "waiting for a free" in line else None,
                    )
                    results[i] = time.perf_counter() - began
                except Exception as exc:  # noqa: BLE001 - the drill reports every failure
                    results[i] = exc

        watcher = threading.Thread(target=watch)
        watcher.start()
        threads = [threading.Thread(target=bench, args=(i,)) for i in range(args.benches)]
        start = time.perf_counter()
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        elapsed = time.perf_counter() - start
        done.set()
        watcher.join()
        monitor.close()
        peaks, server_peak = connection_peaks(cluster, "crowd")
        bench_peaks = [peaks.get(f"bench-{i:03d}", 0) for i in range(args.benches)]
        failures = [r for r in results.values() if isinstance(r, Exception)]
        times = [r for r in results.values() if isinstance(r, float)]
        print(
            f"{args.benches} benches synced in {elapsed:.1f} s (per bench min {min(times, default=0):.2f}, median "
            f"{statistics.median(times) if times else 0:.2f}, max {max(times, default=0):.2f} s); {len(waited)} "
            f"waited for a free connection; server connections peak {max(open_connections, default=0)} "
            f"(max_connections {args.max_connections}, the monitor's included)"
        )
        print(
            f"sessions at once, from the server's log: per bench min {min(bench_peaks)}, median "
            f"{statistics.median(bench_peaks):g}, max {max(bench_peaks)} (bound {LANES}); "
            f"{sum(p == LANES for p in bench_peaks)} benches held {LANES}; the server {server_peak}"
        )
        expected = {}
        for path in paths:
            with Store(path, read_only=True) as store:
                for run in store.runs():
                    expected[run.uuid] = rows_checksum(store.stored_rows(run.id))
        with LabStore(url) as lab:
            total, distinct = lab.query("SELECT count(*), count(DISTINCT (run_uuid, step_index)) FROM bench.samples")[0]
            checksums = {r.uuid: lab.checksum(r.uuid) for r in lab.runs()}
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
                f"every bench held 1 to {LANES} connections at once (max {max(bench_peaks)}, "
                f"{sum(not 1 <= p <= LANES for p in bench_peaks)} outside)",
                all(1 <= p <= LANES for p in bench_peaks),
            ),
            (
                f"the server held at most max_connections = {args.max_connections} at once ({server_peak})",
                server_peak <= args.max_connections,
            ),
            (
                f"every sync returned ({len(failures)} failed" + (f", first: {failures[0]}" if failures else "") + ")",
                not failures,
            ),
        ]
        for text, ok in checks:
            print(f"{'ok  ' if ok else 'FAIL'} {text}")
        return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
