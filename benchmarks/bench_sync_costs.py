"""Where the lab server's time per synced sample goes: the same COPY (the sync's text, typed columns and checksums
included) into tables that add one cost at a time, measured as the CPU of the server process that ran it (its
``/proc`` times, so the machine's other load counts far less than in a wall clock), alternated ``--repeat`` times
(min/median per variant, in microseconds per sample), and each against the bare floor of the same round:

1. floor: an unlogged table without key, trigger or check (``benchmarks/bench_sync.py``'s floor);
2. logged, no key: the same table written through the write-ahead log;
3. logged with the primary key ``(run_uuid, step_index)``;
4. ``bench.samples`` with its triggers off: 3 plus its typed-column layout as synced;
5. ``bench.samples`` with the run check only (lab schema 4's per-statement check against ``bench.runs``);
6. ``bench.samples`` as a sync writes it: the run check and the pose fold;
7. ``bench.samples`` with schema 3's per-row foreign key to ``bench.runs`` instead of the run check;
8. the floor without the typed columns (the COPY text cut after the checksum): what parsing and storing the 28
   typed values costs the server.

And the sync's own process, reading and formatting the same runs (its CPU, min/median over the rounds): the rows
from SQLite alone (with their checksums), their typed values alone (msgspec: decoded from ``values_json`` and
encoded as the COPY's tab-separated fields), and the rows read and formatted as COPY text (what a sync does).

Each COPY is one run's rows in one transaction, as a sync's batches are. Needs Debian's postgresql (a throwaway
cluster on this machine). Usage: ``python benchmarks/bench_sync_costs.py [--samples 100000] [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_sync import _database  # noqa: E402
from postgres_support import Cluster, _bindir, make_store  # noqa: E402

from bench.store import Store  # noqa: E402
from bench.store.lab import sync_store  # noqa: E402
from bench.store.lab_copy import COPY_COLUMNS, TYPED_COLUMNS, _typed_fields, copy_text  # noqa: E402

_FK = "ALTER TABLE bench.samples ADD CONSTRAINT samples_run_uuid_fkey FOREIGN KEY (run_uuid) REFERENCES bench.runs"
#: name -> (statements that set the variant up, the table copied into)
VARIANTS = {
    "floor: unlogged, no key": ("CREATE UNLOGGED TABLE t (LIKE bench.samples)", "t"),
    "logged, no key": ("CREATE TABLE t (LIKE bench.samples)", "t"),
    "logged, primary key": ("CREATE TABLE t (LIKE bench.samples INCLUDING INDEXES)", "t"),
    "bench.samples, triggers off": ("ALTER TABLE bench.samples DISABLE TRIGGER USER", "bench.samples"),
    "+ run check (schema 4)": ("ALTER TABLE bench.samples DISABLE TRIGGER samples_fold_pose", "bench.samples"),
    "+ pose fold: the sync": ("", "bench.samples"),
    "fold + row foreign key (3)": (
        f"ALTER TABLE bench.samples DISABLE TRIGGER samples_check_runs_after_insert; {_FK}",
        "bench.samples",
    ),
    "floor without typed columns": ("CREATE UNLOGGED TABLE t (LIKE bench.samples)", "t"),
}
_UNTYPED = "floor without typed columns"


def untyped(text: bytes) -> bytes:
    """COPY text of :data:`COPY_COLUMNS` cut after the checksum (the typed values left out)."""
    kept = len(COPY_COLUMNS) - len(TYPED_COLUMNS)
    return b"".join(b"\t".join(line.split(b"\t")[:kept]) + b"\n" for line in text.splitlines())


def client_cpu_us(store: Store, n: int) -> dict[str, float]:
    """This process's CPU per sample (us) reading every run: the rows alone, the typed values of rows read
    beforehand, and the rows read and formatted as the sync's COPY text."""
    runs, spent = store.runs(), {}
    values = {r.id: [row[6] for row in store.stored_rows(r.id)] for r in runs}
    for name, read in {
        "read the rows from SQLite": lambda r: all(True for _ in store.stored_rows(r.id, checksum=True)),
        "the typed values (of rows read beforehand)": lambda r: [_typed_fields(v) for v in values[r.id]],
        "+ COPY text: what a sync reads and formats": lambda r: copy_text(
            r.uuid, store.stored_rows(r.id, checksum=True)
        ),
    }.items():
        start = time.process_time()
        for run in runs:
            read(run)
        spent[name] = (time.process_time() - start) / n * 1e6
    return spent


def process_cpu_s(pid: int) -> float:
    """CPU seconds (user + system) of process ``pid`` so far (proc(5): utime, stime)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def copy_cpu_us(url: str, setup: str, table: str, texts: list[bytes], n: int, *, untyped_texts: bool = False) -> float:
    """Server CPU per sample (us) of COPYing ``texts`` (one transaction each) into ``table`` after ``setup``."""
    import psycopg

    with psycopg.connect(url) as conn:
        conn.execute("SET work_mem = '64MB'")  # as the sync's connections
        conn.execute("DROP TABLE IF EXISTS t")
        conn.execute("TRUNCATE bench.samples")  # (empties the pose tables too)
        conn.execute("ALTER TABLE bench.samples ENABLE TRIGGER USER")
        conn.execute("ALTER TABLE bench.samples DROP CONSTRAINT IF EXISTS samples_run_uuid_fkey")
        if setup:
            conn.execute(setup)
        conn.commit()
        pid = conn.execute("SELECT pg_backend_pid()").fetchone()[0]
        conn.commit()
        columns = ", ".join(f'"{c}"' for c in (COPY_COLUMNS[: -len(TYPED_COLUMNS)] if untyped_texts else COPY_COLUMNS))
        start = process_cpu_s(pid)
        for text in texts:
            with conn.cursor() as cur, cur.copy(f"COPY {table} ({columns}) FROM STDIN") as copy:
                copy.write(text)
            conn.commit()
        return (process_cpu_s(pid) - start) / n * 1e6


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000, help="samples (in 4 runs)")
    parser.add_argument("--repeat", type=int, default=3, help="rounds of all variants")
    args = parser.parse_args(argv)
    if _bindir() is None:
        sys.exit("bench_sync_costs: no PostgreSQL (install postgresql)")
    cluster = Cluster(_bindir())
    work = Path(tempfile.mkdtemp(prefix="bench-sync-costs-"))
    try:
        url = _database(cluster.url, "bench_sync_costs")
        path = make_store(work / "bench.db", "bench-a", [args.samples // 4] * 4)
        n = args.samples // 4 * 4
        with Store(path) as store:
            sync_store(store, url)  # the schema and the runs
            texts = [copy_text(r.uuid, store.stored_rows(r.id, checksum=True)) for r in store.runs()]
        print(f"load average before: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs; {n:,} samples a COPY")
        cpu: dict[str, list[float]] = {name: [] for name in VARIANTS}
        client: dict[str, list[float]] = {}
        untyped_texts = [untyped(text) for text in texts]
        for _ in range(args.repeat):
            for name, (setup, table) in VARIANTS.items():
                if name == _UNTYPED:
                    cpu[name].append(copy_cpu_us(url, setup, table, untyped_texts, n, untyped_texts=True))
                else:
                    cpu[name].append(copy_cpu_us(url, setup, table, texts, n))
            with Store(path) as store:
                for name, us in client_cpu_us(store, n).items():
                    client.setdefault(name, []).append(us)
        floor = cpu["floor: unlogged, no key"]
        print(f"{'variant':<30} {'server CPU us/sample':>22} {'/ floor (same round)':>22}")
        for name, values in cpu.items():
            ratios = [v / f for v, f in zip(values, floor)]
            print(
                f"{name:<30} min {min(values):5.2f} median {statistics.median(values):5.2f}"
                f"   min {min(ratios):4.2f} median {statistics.median(ratios):4.2f}"
            )
        print(f"{'the sync process':<44} {'CPU us/sample':>14}")
        for name, values in client.items():
            print(f"{name:<44} min {min(values):5.2f} median {statistics.median(values):5.2f}")
        print(f"load average after: {os.getloadavg()[0]:.1f}")
    finally:
        cluster.close()
        for file in work.glob("*"):
            file.unlink()
        work.rmdir()


if __name__ == "__main__":
    main()
