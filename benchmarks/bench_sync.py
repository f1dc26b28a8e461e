"""Lab-store sync throughput and a cross-bench query, measured in one run (prints figures and ratios, asserts nothing).

* Sync: ``--benches`` local stores of ``--samples`` pose samples each (in ``--runs`` runs) are pushed with
  ``sync_store`` into one PostgreSQL server: the first ones one after the other (samples/s of each: min/median/max),
  the rest at once, one process each (aggregate samples/s from the first start to the last end, imports excluded).
* Floor: a bare COPY of the same sample rows into an unindexed, unlogged table of the same server (no staging, no
  conflict check, no SQLite read): the ratio sync/floor says what the idempotent path costs.
* Query: AP and RP (ISO 9283 7.2.1 and 7.2.2, per pose, the worst pose reported) per robot per ISO week over every
  synced sample, timed three times (min/median/max).

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
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from postgres_support import Cluster, _bindir, make_store, with_database  # noqa: E402

from bench.store import Store  # noqa: E402
from bench.store.lab import LabStore, sync_store  # noqa: E402

#: AP_p = |mean attained - commanded|, RP_p = mean(l) + 3 s(l), l = distance to the barycentre (ISO 9283 7.2).
AP_RP_PER_ROBOT_WEEK = """
WITH r AS (SELECT uuid, robot, date_trunc('week', started_utc::timestamptz)::date AS week FROM bench.runs),
s AS MATERIALIZED (
    SELECT r.robot, r.week, s.pose, v.x_mm AS x, v.y_mm AS y, v.z_mm AS z, v.cmd_x_mm AS cx, v.cmd_y_mm AS cy,
           v.cmd_z_mm AS cz
    FROM bench.samples s JOIN r ON r.uuid = s.run_uuid,
         jsonb_to_record(s.values_json::jsonb)  -- one parse per sample
             AS v(x_mm float8, y_mm float8, z_mm float8, cmd_x_mm float8, cmd_y_mm float8, cmd_z_mm float8)
    WHERE s.kind = 'pose'),
m AS (SELECT robot, week, pose, avg(x) AS mx, avg(y) AS my, avg(z) AS mz, avg(cx) AS cx, avg(cy) AS cy,
             avg(cz) AS cz FROM s GROUP BY robot, week, pose),
p AS (SELECT m.robot, m.week, m.pose, sqrt((m.mx - m.cx) ^ 2 + (m.my - m.cy) ^ 2 + (m.mz - m.cz) ^ 2) AS ap_mm,
             avg(sqrt((s.x - m.mx) ^ 2 + (s.y - m.my) ^ 2 + (s.z - m.mz) ^ 2))
             + 3 * stddev_samp(sqrt((s.x - m.mx) ^ 2 + (s.y - m.my) ^ 2 + (s.z - m.mz) ^ 2)) AS rp_mm,
             count(*) AS n
      FROM s JOIN m USING (robot, week, pose) GROUP BY m.robot, m.week, m.pose, ap_mm)
SELECT robot, week, max(ap_mm), max(rp_mm), sum(n) FROM p GROUP BY robot, week ORDER BY robot, week
"""


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


def copy_floor(url: str, path: Path) -> float:
    """Seconds of a bare COPY of the samples of ``path`` into an unlogged table without keys."""
    import psycopg
    with Store(path) as store, psycopg.connect(url) as conn:
        rows = [(r.uuid, *row) for r in store.runs() for row in store.stored_rows(r.id)]
        conn.execute("CREATE UNLOGGED TABLE floor (run_uuid uuid, step_index int, kind text, pose text, cycle int,"
                     " t_s float8, wall_utc text, values_json text, raw_json text)")
        conn.commit()
        start = time.perf_counter()
        with conn.cursor() as cur, cur.copy("COPY floor FROM STDIN") as copy:
            for row in rows:
                copy.write_row(row)
        conn.commit()
        elapsed = time.perf_counter() - start
        conn.execute("DROP TABLE floor")
        conn.commit()
    return elapsed


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benches", type=int, default=10, help="simulated benches (local stores)")
    parser.add_argument("--samples", type=int, default=100_000, help="samples per bench")
    parser.add_argument("--runs", type=int, default=4, help="runs per bench")
    parser.add_argument("--sequential", type=int, default=3, help="benches synced one after the other")
    args = parser.parse_args(argv)

    cluster = None
    server = os.environ.get("BENCH_TEST_POSTGRES")
    if not server:
        if _bindir() is None:
            sys.exit("bench_sync: no PostgreSQL (set BENCH_TEST_POSTGRES or install postgresql)")
        cluster = Cluster(_bindir())
        server = cluster.url
    work = Path(tempfile.mkdtemp(prefix="bench-sync-"))
    try:
        url = _database(server, "bench_sync_benchmark")
        start = time.perf_counter()
        per_run = [args.samples // args.runs] * args.runs
        stores = [make_store(work / f"bench{i:02d}.db", f"bench-{i:02d}", per_run,
                             robot=("pkm5", "delta4")[i % 2]) for i in range(args.benches)]
        total = sum(per_run) * args.benches
        print(f"local stores       {args.benches} benches x {sum(per_run):,} samples written in "
              f"{time.perf_counter() - start:.1f} s")

        rates = []
        for path in stores[: args.sequential]:
            with Store(path) as store:
                result = sync_store(store, url)
            rates.append(result.samples_per_s)
        print(f"sync, one bench    {sum(per_run):>9,} samples  min {min(rates):9,.0f}  median "
              f"{statistics.median(rates):9,.0f}  max {max(rates):9,.0f} samples/s")

        rest = stores[args.sequential:]
        if rest:  # one process per bench; the window runs from the first sync's start to the last one's end
            procs = [subprocess.Popen([sys.executable, "-c", _CHILD, str(p), url], cwd=ROOT, stdout=subprocess.PIPE,
                                      text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}) for p in rest]
            spans = [tuple(map(float, p.communicate()[0].split())) for p in procs]
            window = max(end for _, end in spans) - min(start for start, _ in spans)
            n = sum(per_run) * len(rest)
            print(f"sync, {len(rest)} at once    {n:>9,} samples  {window:7.2f} s  {n / window:9,.0f} samples/s "
                  "aggregate")

        floor_s = copy_floor(url, stores[0])
        floor_rate = sum(per_run) / floor_s
        print(f"floor: bare COPY   {sum(per_run):>9,} samples  {floor_rate:9,.0f} samples/s; sync median / floor "
              f"= {statistics.median(rates) / floor_rate:.2f}")

        with LabStore(url) as lab:
            held = lab.query("SELECT count(*) FROM bench.samples")[0][0]
            times, rows = [], []
            for _ in range(3):
                start = time.perf_counter()
                rows = lab.query(AP_RP_PER_ROBOT_WEEK)
                times.append(time.perf_counter() - start)
        print(f"query AP/RP per robot per week over {held:,} samples (expected {total:,}): min {min(times):.3f}  "
              f"median {statistics.median(times):.3f}  max {max(times):.3f} s")
        for robot, week, ap, rp, n in rows:
            print(f"  {robot:<7} week of {week}  AP {ap:.4f} mm  RP {rp:.4f} mm  ({n:,} samples)")
    finally:
        if cluster is not None:
            cluster.close()
        for path in work.glob("*"):
            path.unlink()
        work.rmdir()


if __name__ == "__main__":
    main()
