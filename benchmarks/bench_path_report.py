"""A long path run's analysis and report against reading its raw data, time and peak memory, measured in one run.

Builds a completed ``iso9283_path`` run of about ``--points`` streamed points (default 2.3 million; simulated once and
its cycles copied in the store, as ``bench_report.py --path`` does), then, each in a fresh process ``--repeat``
times (default 3), interleaved: ``bench analyze path-run RUN --json`` (the figures), ``bench report RUN --format
html`` (figures, plots and the raw-data CSV), and the floor, a process that reads the run's raw data: every
``path`` sample's row from SQLite with its JSON series decoded (``json.loads`` of ``raw_json``: what any analysis of
the stored raw data must at least do). Printed: min / median / max wall time and peak memory (``ru_maxrss``) of
each, and the ratios of the medians to the floor's. Targets (issue 34): within 3x of the floor's time; memory
bounded by a chunk, not the run (run it at two ``--points`` to see whether the peak grows with the run).

    python benchmarks/bench_path_report.py [--points 2300000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import textwrap
from pathlib import Path

from _timing import load_line
from bench_analyze_large import measured
from bench_report import long_path_run

#: The floor: the run's path samples read from SQLite, each sample's JSON (values and series) decoded.
FLOOR = textwrap.dedent("""
    import json, sqlite3, sys
    db = sqlite3.connect(f"file:{sys.argv[1]}?mode=ro", uri=True)
    points = 0
    for values, raw in db.execute(
        "SELECT values_json, raw_json FROM samples WHERE run_id = ? AND kind = 'path' ORDER BY step_index",
        (int(sys.argv[2]),),
    ):
        json.loads(values)
        points += len(json.loads(raw)["series"]["t_s"])
    print(points)
""")


def _summary(name: str, runs: list[dict]) -> str:
    walls, peaks = [r["wall_s"] for r in runs], [r["peak_mb"] for r in runs]
    return (
        f"  {name:<44} {min(walls):7.2f} {statistics.median(walls):8.2f} {max(walls):7.2f} s   "
        f"{min(peaks):6.0f} {statistics.median(peaks):6.0f} {max(peaks):6.0f} MB"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=2_300_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    started = os.getloadavg()
    with tempfile.TemporaryDirectory() as folder:
        store, run_id = long_path_run(Path(folder), args.points)
        argvs = {
            "floor: read the raw data (SQLite + JSON)": [sys.executable, "-c", FLOOR, str(store), str(run_id)],
            "bench analyze path-run": [sys.executable, "-m", "bench.cli", "analyze", "path-run", str(run_id)]
            + ["--store", str(store), "--json"],
            "bench report --format html": [sys.executable, "-m", "bench.cli", "report", str(run_id)]
            + ["--store", str(store), "--format", "html", "--quiet", "--out", str(Path(folder) / "out")],
        }
        runs: dict[str, list[dict]] = {name: [] for name in argvs}
        points = ""
        for _ in range(args.repeat):
            for name, argv in argvs.items():
                figures, out = measured(argv)
                runs[name].append(figures)
                points = out.decode().strip() if name.startswith("floor") else points
        print(f"long path run {run_id}: {int(points):,} streamed points, {store.stat().st_size / 2**20:.0f} MiB store")
        print(f"  {'':<44} {'min':>7} {'median':>8} {'max':>7}     {'min':>6} {'median':>6} {'max':>6}")
        floor = runs[next(iter(argvs))]
        floor_s, floor_mb = (statistics.median(r[k] for r in floor) for k in ("wall_s", "peak_mb"))
        for name, measured_runs in runs.items():
            wall, peak = (statistics.median(r[k] for r in measured_runs) for k in ("wall_s", "peak_mb"))
            print(_summary(name, measured_runs) + f"   {wall / floor_s:5.2f}x / {peak / floor_mb:5.2f}x the floor")
    print(load_line(started))


if __name__ == "__main__":
    main()
