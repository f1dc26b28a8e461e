"""What the integrity check before appending to a store that was not closed cleanly costs (prints figures and
ratios measured in one run, asserts nothing; see ``bench/store/recovery.py``).

A store of ``--samples`` pose samples (one run, six values and a raw record a sample, as a pose run stores them)
is checked ``--repeat`` times each way, min/median/max:

* ``PRAGMA quick_check`` (pages and records, no index against table), ``PRAGMA integrity_check`` (also every
  index against its table), and :func:`bench.store.connection.check_store` (integrity and foreign keys, what the
  check before appending and ``bench store check`` run);
* the sample checksums alone (:func:`bench.store.sample_checksum.damaged_sample_lines`: SHA-256 of every row,
  what ``bench store check`` adds to SQLite's checks to find a flipped bit in a stored digit);
* floor: one full scan of the samples table (``SELECT SUM(LENGTH(values_json))``), the least any check that
  reads every sample costs.

Usage: ``python benchmarks/bench_store_check.py [--samples 100000] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _timing import min_median_max, spread  # noqa: E402

from bench.store import Store  # noqa: E402
from bench.store.connection import check_store  # noqa: E402
from bench.store.sample_checksum import (
    damaged_sample_lines,  # noqa: E402
    sample_checksum,  # noqa: E402
)


def make_store(path: Path, samples: int) -> None:
    with Store(path) as store:
        run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={})
        raw = store._db.raw  # one transaction for the fill: add_sample commits each sample (fsync) by design
        raw.execute("BEGIN")
        for step in range(samples):
            values = {
                "x_mm": step * 1e-3,
                "y_mm": 1.5,
                "z_mm": 250.0,
                "cmd_x_mm": 0.0,
                "cmd_y_mm": 1.5,
                "cmd_z_mm": 250.0,
            }
            columns = (
                step,
                "pose",
                "P1",
                step // 5 + 1,
                float(step),
                "2026-12-02T00:00:00.000000+00:00",
                json.dumps(values),
                json.dumps({"counts": [step, -step, 3, 4]}),
            )
            raw.execute(
                "INSERT INTO samples (run_id, step_index, kind, pose, cycle, t_s, wall_utc, values_json,"
                " raw_json, checksum) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (run_id, *columns, sample_checksum(*columns)),
            )
        raw.execute("COMMIT")
        store.set_status(run_id, "completed")


def pragma(path: Path, name: str) -> list:
    db = sqlite3.connect(path)
    try:
        return db.execute(name).fetchall()
    finally:
        db.close()


def _checksums(path: Path) -> list[str]:
    db = sqlite3.connect(path)
    try:
        return list(damaged_sample_lines(db, str(path)))
    finally:
        db.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.db"
        make_store(path, args.samples)
        print(f"store: {args.samples} samples, {path.stat().st_size / 2**20:.1f} MiB, SQLite {sqlite3.sqlite_version}")
        floor, _ = spread(pragma, path, "SELECT SUM(LENGTH(values_json)) FROM samples", repeat=args.repeat)
        print(f"floor (one scan of the samples): {min_median_max(floor)}")
        for label, call in (
            ("quick_check", lambda: pragma(path, "PRAGMA quick_check")),
            ("integrity_check", lambda: pragma(path, "PRAGMA integrity_check")),
            ("checksums", lambda: _checksums(path)),
            ("check_store", lambda: check_store(str(path))),
        ):
            times, result = spread(call, repeat=args.repeat)
            ratio = statistics.median(times) / statistics.median(floor)
            print(f"{label}: {min_median_max(times)}; median {ratio:.1f} x the floor; result {result!r:.40}")


if __name__ == "__main__":
    main()
