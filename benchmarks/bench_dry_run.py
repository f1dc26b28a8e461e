"""``bench run PROTOCOL --dry-run`` on ever longer plans: linear time and bounded memory, measured in one run.

The ISO 9283 pose protocol (examples/iso9283_pose.toml) at ``--cycles`` of 200, 2 000 and 20 000 (about 10^4,
10^5 and 10^6 steps), each dry run in a fresh process ``--repeat`` times; the floor beside it is the same plan's
generator iterated alone (:func:`bench.protocols.plan.iterate`, nothing summarised). Printed per size: min / median
/ max wall time, microseconds per step, peak memory (``ru_maxrss``), and the ratios of the largest size to the
smallest: time per step (1.0 is linear) and peak memory (1.0 is bounded).

    python benchmarks/bench_dry_run.py [--cycles 200 2000 20000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

from bench_analyze_large import measured

ROOT = Path(__file__).resolve().parents[1]
#: The floor: the plan's own generator, driven as the dry run drives it, its steps only counted.
FLOOR = (
    "import sys; from bench.protocols import load_protocol; from bench.protocols.plan import iterate; "
    "print(sum(1 for _ in iterate(load_protocol(sys.argv[1]))))"
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, nargs="+", default=[200, 2_000, 20_000])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    text = (ROOT / "examples" / "iso9283_pose.toml").read_text(encoding="utf-8")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for cycles in args.cycles:
            path = Path(folder) / f"pose_{cycles}.toml"
            path.write_text(text.replace("cycles = 30\n", f"cycles = {cycles}\n"), encoding="utf-8")
            _, out = measured([sys.executable, "-c", FLOOR, str(path)])
            steps = int(out.split()[-1])
            dry = [
                measured([sys.executable, "-m", "bench.cli", "run", str(path), "--dry-run"])[0]
                for _ in range(args.repeat)
            ]
            floor = [measured([sys.executable, "-c", FLOOR, str(path)])[0] for _ in range(args.repeat)]
            rows.append((cycles, steps, dry, floor))
    print(
        f"{'cycles':>7} {'steps':>10}   {'dry run s (min/median/max)':>28} {'us/step':>8} {'peak MB':>8}   "
        f"{'generator alone s':>18} {'peak MB':>8}"
    )
    for cycles, steps, dry, floor in rows:
        walls = [r["wall_s"] for r in dry]
        print(
            f"{cycles:>7} {steps:>10,}   {min(walls):8.2f} {statistics.median(walls):9.2f} {max(walls):9.2f} "
            f"{statistics.median(walls) / steps * 1e6:8.1f} {statistics.median(r['peak_mb'] for r in dry):8.0f}"
            f"   {statistics.median(r['wall_s'] for r in floor):18.2f} "
            f"{statistics.median(r['peak_mb'] for r in floor):8.0f}"
        )
    medians = [
        (steps, statistics.median(r["wall_s"] for r in dry), statistics.median(r["peak_mb"] for r in dry))
        for _, steps, dry, _ in rows
    ]
    marginal = [(b[1] - a[1]) / (b[0] - a[0]) * 1e6 for a, b in zip(medians, medians[1:])]
    print(
        "marginal us/step between consecutive sizes (start-up cancels; equal is linear): "
        + ", ".join(f"{m:.1f}" for m in marginal)
        + f"; peak memory largest / smallest {medians[-1][2] / medians[0][2]:.2f}x (1.0 is bounded); dry run / "
        f"generator alone at the largest {medians[-1][1] / statistics.median(r['wall_s'] for r in rows[-1][3]):.2f}x"
    )


if __name__ == "__main__":
    main()
