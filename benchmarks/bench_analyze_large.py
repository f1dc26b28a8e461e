"""``bench analyze iso9283`` against a plain pandas ``read_csv`` + groupby at several table sizes, measured in one run.

For each size in ``--rows`` (default 10^4, 10^5, 10^6, 10^7) a seeded table of ``--poses`` poses (default 100) is
written to a temporary folder; then, each in a fresh process and interleaved, ``--repeat`` times (default 5; sizes of
10^7 rows and more ``--repeat-large`` times, default 1): the full analysis with uncertainties (``python -m bench.cli
analyze iso9283 FILE --json``) and the peer, pandas ``read_csv`` + ``groupby`` computing AP_P and RP_l only. Printed
per size: min / median / max wall time and peak memory (``ru_maxrss`` of that process, read by a wrapper process that
runs only it), the ratios of the medians (and the smallest and largest ratio of a bench run to the peer run next to
it), and the largest AP/RP difference between the two. Then the linearity: seconds and bytes per row of each size,
the marginal cost per row between consecutive sizes (what a row adds once the fixed start-up is paid), and issue 34's
criterion as it reads, the per-row totals' spread between 10^5 and 10^7 rows, beside each tool's fixed start-up
(measured first, on a table of 10 cycles a pose). Last, the analysis itself in process, free of the start-up: in a
fresh process that has imported it and analysed a small table once (``--in-process-repeat`` times per size), the
wall and CPU time of the call ``bench analyze iso9283`` makes (``pose_file_results``) and its peak memory increment
(the peak resident set, reset by ``/proc/self/clear_refs`` just before the call, less the resident set then), per
row at each size, and their spread between 10^5 and 10^7 rows against issue 34's 1.5x; and the CPU time a row adds
to the same call on a reference table of ``REFERENCE_CYCLES`` cycles a pose (its fixed cost per call and per pose
taken out: with 100 poses about 0.4 ms a pose, numpy calls on small arrays), whose spread says whether a row's
cost grows with the table (``--poses 10`` shows the per-pose share: a tenth).
Targets (issue 34): within 2x of the peer's time at every size, peak memory within 1.5x, time and memory per row
within 1.5x between 10^5 and 10^7 rows.

    python benchmarks/bench_analyze_large.py [--rows 1e4 1e5 1e6 1e7] [--poses 100] [--repeat 5] [--repeat-large 1]
        [--in-process-repeat 3] [--in-process-only]

The tables are written with pyarrow (installed with pandas 3 here; `pip install pyarrow` otherwise).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from _timing import load_line

#: The peer: what a user would write with pandas for AP and RP alone (ISO 9283 7.2.1, 7.2.2).
PEER = textwrap.dedent("""
    import json, sys
    import numpy as np, pandas as pd
    frame = pd.read_csv(sys.argv[1])
    out = {}
    for pose, rows in frame.groupby("pose", sort=False):
        attained = rows[["x_mm", "y_mm", "z_mm"]].to_numpy()
        centre = attained.mean(axis=0)
        l = np.linalg.norm(attained - centre, axis=1)
        ap = float(np.linalg.norm(centre - rows[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy()[0]))
        out[pose] = {"AP_mm": ap, "RP_mm": float(l.mean() + 3 * l.std(ddof=1))}
    json.dump(out, sys.stdout)
""")

#: Runs argv[1:] and prints its exit code, wall time and peak resident memory (this wrapper's only child).
WRAPPER = textwrap.dedent("""
    import json, resource, subprocess, sys, time
    start = time.perf_counter()
    done = subprocess.run(sys.argv[1:], stdout=subprocess.PIPE)
    wall = time.perf_counter() - start
    peak_kib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    sys.stderr.write(json.dumps({"rc": done.returncode, "wall_s": wall, "peak_mb": peak_kib / 1024}) + "\\n")
    sys.stdout.buffer.write(done.stdout)
""")


#: Cycles a pose of the warm-up table, whose second analysis in process is the reference for the cost a row adds:
#: above ``MODEL_MAX_CYCLES`` (100), so that U(RP) takes the delta method there as in the large tables.
REFERENCE_CYCLES = 200
#: The analysis in process: argv = table, warm-up table. Imports and a first analysis (lazy imports, caches) before;
#: prints the call's wall and CPU seconds and its peak resident memory over the resident memory before it.
IN_PROCESS = textwrap.dedent("""
    import json, re, sys, time
    from bench.metrology.pose_stream import pose_file_results

    def status_kib(field):
        return int(re.search(field + r":\\s+(\\d+) kB", open("/proc/self/status").read()).group(1))

    pose_file_results(sys.argv[2])
    fixed_wall, fixed_cpu = time.perf_counter(), time.process_time()
    pose_file_results(sys.argv[2])  # again, timed: the fixed cost (per call and per pose) and a few rows
    fixed_wall, fixed_cpu = time.perf_counter() - fixed_wall, time.process_time() - fixed_cpu
    with open("/proc/self/clear_refs", "w") as handle:
        handle.write("5")  # resets the peak resident set (VmHWM) to the resident set now
    before_kib = status_kib("VmRSS")
    wall, cpu = time.perf_counter(), time.process_time()
    results = pose_file_results(sys.argv[1])
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    peak_kib = status_kib("VmHWM")
    added_mb = (peak_kib - before_kib) / 1024
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "added_mb": added_mb, "fixed_s": fixed_wall, "fixed_cpu_s": fixed_cpu}))
""")


def write_table(path: Path, poses: int, cycles: int, seed: int = 0) -> None:
    """A tidy pose table: per pose a commanded position and ``cycles`` attained ones (anisotropic scatter), written
    by Arrow's CSV writer a pose at a time (10^7 rows in about a minute; cells rounded to 3 and 4 decimals)."""
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    rng = np.random.default_rng(seed)
    command = rng.uniform([90, -20, 300], [130, 20, 340], size=(poses, 3)).round(3)
    bias = rng.normal(0, 0.5, size=(poses, 3))
    options = pa_csv.WriteOptions(include_header=False, quoting_style="none")
    with path.open("wb") as handle:
        handle.write(b"pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm\n")
        for p in range(poses):
            attained = (command[p] + bias[p] + rng.normal(0, [0.3, 0.2, 0.1], size=(cycles, 3))).round(4)
            columns = {"pose": pa.array([f"P{p + 1}"] * cycles), "cycle": np.arange(1, cycles + 1)}
            columns.update({name: np.full(cycles, command[p, i]) for i, name in enumerate(("cx", "cy", "cz"))})
            columns.update({name: attained[:, i] for i, name in enumerate(("x", "y", "z"))})
            pa_csv.write_csv(pa.table(columns), handle, write_options=options)


def measured(argv: list[str]) -> tuple[dict, bytes]:
    done = subprocess.run([sys.executable, "-c", WRAPPER, *argv], capture_output=True, check=True)
    figures = json.loads(done.stderr.decode().strip().splitlines()[-1])
    if figures["rc"] != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {figures['rc']}")
    return figures, done.stdout


def summary(name: str, runs: list[dict]) -> str:
    walls, peaks = [r["wall_s"] for r in runs], [r["peak_mb"] for r in runs]
    return (
        f"  {name:<32} {min(walls):7.2f} {statistics.median(walls):8.2f} {max(walls):7.2f}   "
        f"{min(peaks):7.0f} {statistics.median(peaks):8.0f} {max(peaks):7.0f}"
    )


def in_process(table: Path, warm: Path, repeat: int) -> dict:
    """The analysis of ``table`` in process (:data:`IN_PROCESS`), ``repeat`` fresh processes: the line of this size
    and the medians."""
    runs = []
    for _ in range(repeat):
        done = subprocess.run(
            [sys.executable, "-c", IN_PROCESS, str(table), str(warm)], capture_output=True, check=True
        )
        runs.append(json.loads(done.stdout.decode().strip().splitlines()[-1]))
    walls, cpus, added, fixed = ([r[key] for r in runs] for key in ("wall_s", "cpu_s", "added_mb", "fixed_cpu_s"))
    print(
        f"  {'the analysis in process':<32} {min(walls):7.2f} {statistics.median(walls):8.2f} {max(walls):7.2f}   "
        f"{min(added):7.0f} {statistics.median(added):8.0f} {max(added):7.0f}  (memory: the call's increment; "
        f"CPU {statistics.median(cpus):.2f} s; on the reference table {min(fixed) * 1e3:.0f} ms CPU)"
    )
    # the fastest run of each: the least disturbed by other work on the machine (the medians drift with its load)
    return {
        "inproc_s": min(walls),
        "inproc_cpu_s": min(cpus),
        "inproc_mb": statistics.median(added),
        "inproc_fixed_cpu_s": min(fixed),
    }


def measure_size(
    rows: int, poses: int, repeat: int, folder: Path, *, warm: Path | None = None, inproc_repeat: int = 0
) -> dict:
    """Write a table of ``rows`` rows, run bench and the peer ``repeat`` times each (interleaved), then the analysis
    in process ``inproc_repeat`` times (after a warm-up on ``warm``); print the lines of this size and return its
    medians."""
    table = folder / f"poses-{rows}.csv"
    start = time.perf_counter()
    write_table(table, poses, rows // poses)
    print(
        f"{rows:,} rows ({poses} poses x {rows // poses:,} cycles), {table.stat().st_size / 1e6:.0f} MB "
        f"(written in {time.perf_counter() - start:.1f} s), {repeat} run(s) each, min / median / max s and MB:"
    )
    inproc = in_process(table, warm, inproc_repeat) if warm is not None and inproc_repeat else {}
    if not repeat:
        table.unlink()
        return {"rows": rows, **inproc}
    bench_runs, peer_runs = [], []
    for _ in range(repeat):
        figures, out = measured([sys.executable, "-m", "bench.cli", "analyze", "iso9283", str(table), "--json"])
        bench_runs.append(figures)
        ours = json.loads(out)["poses"]
        figures, out = measured([sys.executable, "-c", PEER, str(table)])
        peer_runs.append(figures)
        peer = json.loads(out)
    table.unlink()
    print(summary("bench analyze iso9283 (with U)", bench_runs))
    print(summary("pandas read_csv + groupby (peer)", peer_runs))
    bench_s, peer_s = (statistics.median(r["wall_s"] for r in runs) for runs in (bench_runs, peer_runs))
    bench_mb, peer_mb = (statistics.median(r["peak_mb"] for r in runs) for runs in (bench_runs, peer_runs))
    pairs = [b["wall_s"] / p["wall_s"] for b, p in zip(bench_runs, peer_runs)]
    difference = max(abs(ours[p][key] - peer[p][key]) for p in peer for key in ("AP_mm", "RP_mm"))
    print(
        f"  time {bench_s / peer_s:.2f}x the peer's (median over median; run by run min {min(pairs):.2f}x, max "
        f"{max(pairs):.2f}x), peak memory {bench_mb / peer_mb:.2f}x; largest |AP/RP difference| {difference:.1e} mm"
    )
    fastest = {
        f"{name}_min_s": min(r["wall_s"] for r in runs) for name, runs in (("bench", bench_runs), ("peer", peer_runs))
    }
    return {
        "rows": rows,
        "bench_s": bench_s,
        "peer_s": peer_s,
        "bench_mb": bench_mb,
        "peer_mb": peer_mb,
        **fastest,
        **inproc,
    }


def in_process_criterion(sizes: list[dict], poses: int) -> None:
    """Issue 34's linearity of the analysis itself: time (wall and CPU) and peak memory increment per row at each
    size, and largest over smallest per-row figure between 10^5 and 10^7 rows (within 1.5x: linear). Memory read in
    chunks (files of ``STREAM_MIN_BYTES`` and more) is bounded by a chunk, so its per-row figure falls with size."""
    measured = [s for s in sizes if "inproc_s" in s]
    if not measured:
        return
    print("the analysis in process (pose_file_results after imports and a warm-up; fastest run, median memory):")
    for s in measured:
        print(
            f"  {s['rows']:>11,} rows: {s['inproc_s'] / s['rows'] * 1e6:7.2f} us/row wall, "
            f"{s['inproc_cpu_s'] / s['rows'] * 1e6:7.2f} us/row CPU, {s['inproc_mb'] * 2**20 / s['rows']:7.0f} B/row"
        )
    span = [s for s in measured if 10**5 <= s["rows"] <= 10**7]
    if len(span) < 2:
        return
    spread = {
        name: max(s[key] / s["rows"] for s in span) / min(s[key] / s["rows"] for s in span)
        for name, key in (("time", "inproc_s"), ("CPU", "inproc_cpu_s"), ("memory", "inproc_mb"))
    }
    growth = {  # the largest size's per-row figure over the smallest's: above 1, a row costs more in a larger table
        name: (span[-1][key] / span[-1]["rows"]) / (span[0][key] / span[0]["rows"])
        for name, key in (("time", "inproc_s"), ("memory", "inproc_mb"))
    }
    print(
        f"  per row, largest over smallest from {span[0]['rows']:,} to {span[-1]['rows']:,} rows (issue 34: within "
        f"1.5x): time {spread['time']:.2f}x (CPU {spread['CPU']:.2f}x), memory {spread['memory']:.2f}x: "
        f"{'met' if max(spread['time'], spread['memory']) <= 1.5 else 'not met'}; {span[-1]['rows']:,} rows' per-row "
        f"figure over {span[0]['rows']:,} rows': time {growth['time']:.2f}x, memory {growth['memory']:.2f}x "
        f"(above 1.5: super-linear; below 1: a fixed cost spread over more rows)"
    )
    reference_rows = poses * REFERENCE_CYCLES
    net = [(s["inproc_cpu_s"] - s["inproc_fixed_cpu_s"]) / (s["rows"] - reference_rows) for s in span]
    print(
        f"  CPU a row adds to the same call on {reference_rows:,} rows ({REFERENCE_CYCLES} cycles a pose, "
        f"{statistics.median(s['inproc_fixed_cpu_s'] for s in span) * 1e3:.0f} ms: the fixed cost per call and pose): "
        + ", ".join(f"{s['rows']:,} rows {v * 1e6:.2f} us" for s, v in zip(span, net))
        + f"; largest over smallest {max(net) / min(net):.2f}x: {'met' if max(net) / min(net) <= 1.5 else 'not met'}"
    )


def linearity(sizes: list[dict]) -> None:
    """Per-row and marginal per-row cost of bench (and the peer), and the spread of the marginal costs."""
    print("linearity (bench; the peer in brackets):")
    for s in sizes:
        print(
            f"  {s['rows']:>11,} rows: {s['bench_s'] / s['rows'] * 1e6:8.2f} us/row [{s['peer_s'] / s['rows'] * 1e6:8.2f}]"
            f", {s['bench_mb'] * 2**20 / s['rows']:9.0f} B/row [{s['peer_mb'] * 2**20 / s['rows']:9.0f}]"
        )
    marginal = []
    for a, b in zip(sizes, sizes[1:]):
        added = b["rows"] - a["rows"]
        time_us = (b["bench_s"] - a["bench_s"]) / added * 1e6
        memory_b = (b["bench_mb"] - a["bench_mb"]) * 2**20 / added
        peer_us = (b["peer_s"] - a["peer_s"]) / added * 1e6
        peer_b = (b["peer_mb"] - a["peer_mb"]) * 2**20 / added
        marginal.append((a["rows"], b["rows"], time_us, memory_b))
        print(
            f"  marginal {a['rows']:,} -> {b['rows']:,}: {time_us:.2f} us/row [{peer_us:.2f}], "
            f"{memory_b:.0f} B/row [{peer_b:.0f}]"
        )
    wide = [m for m in marginal if m[0] >= 10**5 and m[1] <= 10**7]
    if len(wide) >= 2:  # super-linear growth would make a later marginal cost the larger
        print(
            f"  marginal cost per row, largest over smallest size step between 10^5 and 10^7 (above 1: super-linear): "
            f"time {wide[-1][2] / wide[0][2]:.2f}x, memory {wide[-1][3] / wide[0][3]:.2f}x"
        )


def per_row_criterion(sizes: list[dict], startup: dict) -> None:
    """Issue 34's linearity as it reads: time and memory per row (a process's total over its rows) within 1.5x
    between 10^5 and 10^7 rows; beside it the fixed start-up, measured: the same process on a table of
    ``startup["rows"]`` rows (interpreter, imports, opening the file: paid whatever the rows), and its share of the
    smallest size's run (fastest runs: the least disturbed). Spread over few rows, the start-up makes the small
    sizes' per-row figures the larger for any tool; the marginal cost (:func:`linearity`) is free of it."""
    span = [s for s in sizes if 10**5 <= s["rows"] <= 10**7]
    if len(span) < 2:
        return
    for tool, name in (("bench", "bench analyze iso9283"), ("peer", "pandas peer")):
        spreads = []
        for unit in ("s", "mb"):
            per_row = [s[f"{tool}_{unit}"] / s["rows"] for s in span]
            spreads.append(max(per_row) / min(per_row))
        fixed_s, fixed_mb = startup[f"{tool}_min_s"], startup[f"{tool}_mb"]
        print(
            f"  {name}, per row (total / rows) largest over smallest from {span[0]['rows']:,} to "
            f"{span[-1]['rows']:,} rows (issue 34: within 1.5x): time {spreads[0]:.2f}x, memory {spreads[1]:.2f}x: "
            f"{'met' if max(spreads) <= 1.5 else 'not met'}; fixed start-up {fixed_s:.2f} s, {fixed_mb:.0f} MB "
            f"(fastest run on {startup['rows']:,} rows), {fixed_s / span[0][f'{tool}_min_s']:.0%} of the time and "
            f"{fixed_mb / span[0][f'{tool}_mb']:.0%} of the memory at {span[0]['rows']:,} rows"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=float, nargs="+", default=[1e4, 1e5, 1e6, 1e7])
    parser.add_argument("--poses", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--repeat-large", type=int, default=1, help="runs of each tool at 10^7 rows and more")
    parser.add_argument("--in-process-repeat", type=int, default=3, help="runs of the analysis in process per size")
    parser.add_argument("--in-process-only", action="store_true", help="only the analysis in process (no processes)")
    args = parser.parse_args()
    started = os.getloadavg()
    sizes = []
    with tempfile.TemporaryDirectory() as folder:
        warm = Path(folder) / "warm-up.csv"
        write_table(warm, args.poses, REFERENCE_CYCLES, seed=1)
        if not args.in_process_only:
            print("the fixed start-up, on a table of a few cycles:")
            startup = measure_size(args.poses * 10, args.poses, args.repeat, Path(folder))
        for rows in sorted(int(r) for r in args.rows):
            repeat = 0 if args.in_process_only else args.repeat_large if rows >= 10**7 else args.repeat
            sizes.append(
                measure_size(rows, args.poses, repeat, Path(folder), warm=warm, inproc_repeat=args.in_process_repeat)
            )
    if not args.in_process_only:
        linearity(sizes)
        per_row_criterion(sizes, startup)
    in_process_criterion(sizes, args.poses)
    print(load_line(started))


if __name__ == "__main__":
    main()
