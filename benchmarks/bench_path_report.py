"""Long path runs' analysis and report against reading their raw data, time and peak memory, measured in one run.

For each ``--points`` (default 1.15 and 2.3 million streamed points, half and the issue's size): builds a completed
``iso9283_path`` run of about that many points (simulated once and its cycles copied in the store, as
``bench_report.py --path`` does), then, each in a fresh process ``--repeat`` times (default 2), interleaved:
``bench analyze path-run RUN --json`` (the figures), ``bench report RUN --format html`` (figures, plots and the
raw-data CSV), and two floors, processes that read the run's raw data: every ``path`` sample's row from SQLite with
its JSON decoded, by the standard library's ``json.loads`` (the floor of the issue's measurements) and by msgspec's
decoder (as bench itself reads stored JSON since 0.5.1: the least any analysis of the stored raw data must do).
Printed per size: min / median / max wall time and peak memory (``ru_maxrss``) of each, and min / median / max of
each repeat's ratio to each floor's run beside it (time; memory against the json floor); then, per tool, the peak
memory of the largest run against the smallest. Targets (issue 34): within 3x of the floor's time (the json floor,
as the issue measured it; the msgspec floor's ratio printed beside it); memory bounded by a chunk, not the run (the
same peak at every size). The path model's Monte Carlo (U(AT_p), U(RT_p), ``path_uncertainty``) grows with the
square of the cycles: its own time is printed per size, measured in this process on the run's crossings. The report
writes its raw-data CSV in a second process only while the machine has core time free (``bench.reports.cores.core_time_free``):
how many of its runs found some is printed per size.

    python benchmarks/bench_path_report.py [--points 1150000 2300000] [--repeat 2] [--baseline CHECKOUT]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from _timing import load_line
from bench_analyze_large import measured
from bench_report import long_path_run

from bench.reports.cores import core_time_free

#: The floor: the run's path samples read from SQLite, each sample's JSON (values and series) decoded by
#: {decode} (the standard library's ``json.loads``, or msgspec's decoder as bench reads them, 5-6x faster).
FLOOR = textwrap.dedent("""
    import json, sqlite3, sys
    {imports}
    db = sqlite3.connect(f"file:{{sys.argv[1]}}?mode=ro", uri=True)
    points = 0
    for values, raw in db.execute(
        "SELECT values_json, raw_json FROM samples WHERE run_id = ? AND kind = 'path' ORDER BY step_index",
        (int(sys.argv[2]),),
    ):
        {decode}(values)
        points += len({decode}(raw)["series"]["t_s"])
    print(points)
""")
FLOORS = {
    "floor: read the raw data (SQLite + json)": FLOOR.format(imports="", decode="json.loads"),
    "floor: read the raw data (SQLite + msgspec)": FLOOR.format(
        imports="import msgspec; decode = msgspec.json.Decoder().decode", decode="decode"
    ),
}


def _ratios(runs: list[dict], floor: list[dict], key: str) -> str:
    """min / median / max of each repeat's ``key`` against the floor's repeat beside it."""
    ratios = [r[key] / f[key] for r, f in zip(runs, floor)]
    return f"{min(ratios):5.2f} {statistics.median(ratios):5.2f} {max(ratios):5.2f}"


def _summary(name: str, runs: list[dict], floors: list[list[dict]]) -> str:
    walls, peaks = [r["wall_s"] for r in runs], [r["peak_mb"] for r in runs]
    return (
        f"  {name:<44} {min(walls):6.2f} {statistics.median(walls):6.2f} {max(walls):6.2f} s "
        f"{min(peaks):5.0f} {statistics.median(peaks):5.0f} {max(peaks):5.0f} MB   "
        + "   ".join(f"{_ratios(runs, floor, 'wall_s')} x" for floor in floors)
        + f"   {_ratios(runs, floors[0], 'peak_mb')} x"
    )


def _monte_carlo_s(store: Path, run_id: int) -> str:
    """The path model's Monte Carlo alone on the run's crossings (each path at its first velocity): seconds."""
    from bench.metrology.uncertainty_figures import path_uncertainty
    from bench.reports.path_cycles import PathCycles
    from bench.reports.path_run import PathDesign
    from bench.store import Store

    with Store(store, read_only=True) as db:
        design = PathDesign.from_config(db.run(run_id).config, "benchmark")
        cycles = PathCycles(design, station_mm=1.0, margin_mm=2.0, speed_station_mm=2.0)
        for sample in db.iter_samples(run_id, kind="path"):
            cycles.add(sample)
    parts = []
    for key, held in cycles.keys.items():
        crossings = np.stack([c.crossings_mm for c in cycles.complete(key)], axis=1)
        start = time.perf_counter()
        path_uncertainty(crossings, held.stations)
        parts.append(
            f"{key[0]} {crossings.shape[0]} stations x {crossings.shape[1]} cycles {time.perf_counter() - start:.2f} s"
        )
    return "; ".join(parts)


def measure_size(points: int, repeat: int, folder: Path, baseline: Path | None) -> dict[str, float]:
    """Build a run of about ``points`` points, run the processes ``repeat`` times each (interleaved; with
    ``baseline``, its analysis and report too); print this size's lines and return each one's median peak (MB)."""
    store, run_id = long_path_run(folder, points)
    argvs = {name: [sys.executable, "-c", floor, str(store), str(run_id)] for name, floor in FLOORS.items()}
    for label, prefix in [("", [])] + (
        [(" (baseline)", ["env", "-C", str(baseline), f"PYTHONPATH={baseline}"])] if baseline else []
    ):
        argvs[f"bench analyze path-run{label}"] = [*prefix, sys.executable, "-m", "bench.cli", "analyze"] + [
            "path-run",
            str(run_id),
            "--store",
            str(store),
            "--json",
        ]
        argvs[f"bench report --format html{label}"] = [*prefix, sys.executable, "-m", "bench.cli", "report"] + [
            str(run_id),
            "--store",
            str(store),
            "--format",
            "html",
            "--quiet",
            "--out",
            str(folder / f"out{label.strip()}"),
        ]
    runs: dict[str, list[dict]] = {name: [] for name in argvs}
    counted, spare = "", []
    for _ in range(repeat):
        for name, argv in argvs.items():
            if name == "bench report --format html":  # whether its CSV goes to a second process (the same test)
                spare.append(core_time_free())
            figures, out = measured(argv)
            runs[name].append(figures)
            counted = out.decode().strip() if name in FLOORS else counted
    print(f"long path run: {int(counted):,} streamed points, {store.stat().st_size / 2**20:.0f} MiB store")
    print(
        f"  {'':<44} {'wall min / median / max':>22}   {'peak MB':>15}   time / json floor (x)   "
        "time / msgspec floor (x)   memory / json floor (x)"
    )
    floors = [runs[name] for name in FLOORS]
    for name, measured_runs in runs.items():
        print(_summary(name, measured_runs, floors))
    print(f"  path model Monte Carlo alone: {_monte_carlo_s(store, run_id)}")
    print(
        f"  raw-data CSV by a second process (core time free as the report started): {sum(spare)} of {len(spare)} "
        "report runs (the baseline's: none)"
    )
    return {name: statistics.median(r["peak_mb"] for r in measured_runs) for name, measured_runs in runs.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, nargs="+", default=[1_150_000, 2_300_000])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        metavar="CHECKOUT",
        help="another checkout of bench (its folder holding bench/): its analysis and report measured too, in turn",
    )
    args = parser.parse_args()
    started = os.getloadavg()
    peaks = {}
    for points in sorted(args.points):
        with tempfile.TemporaryDirectory() as folder:
            peaks[points] = measure_size(points, args.repeat, Path(folder), args.baseline)
    if len(peaks) > 1:
        small, large = peaks[min(peaks)], peaks[max(peaks)]
        print(f"peak memory at {max(peaks):,} points against {min(peaks):,} (median of each; 1.00 = bounded):")
        for name in small:
            print(f"  {name:<42} {small[name]:6.0f} -> {large[name]:6.0f} MB   {large[name] / small[name]:5.2f}x")
    print(load_line(started))


if __name__ == "__main__":
    main()
