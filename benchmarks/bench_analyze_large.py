"""``bench analyze iso9283`` on a large table against a plain pandas ``read_csv`` + groupby, measured in one run.

A seeded table of ``--poses`` x ``--cycles`` rows (default 100 x 10,000 = 10^6) is written to a temporary folder;
then, each in a fresh process ``--repeat`` times (default 5): the full analysis with uncertainties
(``python -m bench.cli analyze iso9283 FILE --json``) and the peer, pandas ``read_csv`` + ``groupby`` computing
AP_P and RP_l only. Printed: min / median / max wall time and peak memory (``ru_maxrss`` of that process, read by
a wrapper process that runs only it), the ratios of the medians, and the largest AP/RP difference between the two.
Targets (issue 17): within 3x of the peer's time and under 500 MB peak.

    python benchmarks/bench_analyze_large.py [--poses 100] [--cycles 10000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

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


def write_table(path: Path, poses: int, cycles: int, seed: int = 0) -> None:
    """A tidy pose table: per pose a commanded position and ``cycles`` attained ones (anisotropic scatter)."""
    rng = np.random.default_rng(seed)
    command = rng.uniform([90, -20, 300], [130, 20, 340], size=(poses, 3)).round(3)
    bias = rng.normal(0, 0.5, size=(poses, 3))
    with path.open("w", encoding="utf-8") as handle:
        handle.write("pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm\n")
        for p in range(poses):
            attained = command[p] + bias[p] + rng.normal(0, [0.3, 0.2, 0.1], size=(cycles, 3))
            cells = np.column_stack([np.arange(1, cycles + 1), np.tile(command[p], (cycles, 1)), attained])
            lines = "\n".join(
                f"P{p + 1}," + ",".join(row)
                for row in np.char.mod(["%d", "%.3f", "%.3f", "%.3f", "%.4f", "%.4f", "%.4f"], cells).tolist()
            )
            handle.write(lines + "\n")


def measured(argv: list[str]) -> tuple[dict, bytes]:
    done = subprocess.run([sys.executable, "-c", WRAPPER, *argv], capture_output=True, check=True)
    figures = json.loads(done.stderr.decode().strip().splitlines()[-1])
    if figures["rc"] != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {figures['rc']}")
    return figures, done.stdout


def summary(name: str, runs: list[dict]) -> str:
    walls, peaks = [r["wall_s"] for r in runs], [r["peak_mb"] for r in runs]
    return (
        f"{name:<34} {min(walls):7.2f} {statistics.median(walls):8.2f} {max(walls):7.2f}   "
        f"{min(peaks):7.0f} {statistics.median(peaks):8.0f} {max(peaks):7.0f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=100)
    parser.add_argument("--cycles", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        table = Path(folder) / "poses.csv"
        start = time.perf_counter()
        write_table(table, args.poses, args.cycles)
        print(
            f"table: {args.poses} poses x {args.cycles} cycles = {args.poses * args.cycles:,} rows, "
            f"{table.stat().st_size / 1e6:.0f} MB (written in {time.perf_counter() - start:.1f} s)"
        )
        bench_runs, peer_runs = [], []
        for _ in range(args.repeat):
            figures, out = measured([sys.executable, "-m", "bench.cli", "analyze", "iso9283", str(table), "--json"])
            bench_runs.append(figures)
            ours = json.loads(out)["poses"]
            figures, out = measured([sys.executable, "-c", PEER, str(table)])
            peer_runs.append(figures)
            peer = json.loads(out)
    print(f"{'':<34} {'time_s':^24}   {'peak_MB':^24}")
    print(f"{'':<34} {'min':>7} {'median':>8} {'max':>7}   {'min':>7} {'median':>8} {'max':>7}")
    print(summary("bench analyze iso9283 (with U)", bench_runs))
    print(summary("pandas read_csv + groupby (peer)", peer_runs))
    ratio = statistics.median(r["wall_s"] for r in bench_runs) / statistics.median(r["wall_s"] for r in peer_runs)
    memory = statistics.median(r["peak_mb"] for r in bench_runs) / statistics.median(r["peak_mb"] for r in peer_runs)
    difference = max(abs(ours[p][key] - peer[p][key]) for p in peer for key in ("AP_mm", "RP_mm"))
    print(
        f"ratio of medians: time {ratio:.2f}x, peak memory {memory:.2f}x; largest |AP/RP difference| "
        f"{difference:.1e} mm"
    )


if __name__ == "__main__":
    main()
