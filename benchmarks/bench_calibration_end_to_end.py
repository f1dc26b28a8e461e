"""The README's calibration commands end to end on the default simulated pkm5 (passive-joint play and backlash on,
a seeded true geometry), seed by seed: what gain a user gets, how much of it the validation's play lets show, and
how far the identified geometry lies from the truth.

Run as ``python benchmarks/bench_calibration_end_to_end.py [--seeds 60-69] [--calibration-cycles C]
[--validation-cycles V] [--speed-factor F] [--ideal]``. Per seed, in a fresh store, exactly the commands of
docs/calibration.md ("Workflow"), the example files with their cycles replaced only when asked:

    bench run examples/kinematic_calibration.toml --sim --true-geometry-seed SEED --no-kinematic-calibration
    bench calibrate RUN --json
    bench run examples/kinematic_validation.toml --sim --true-geometry-seed SEED
    bench run examples/kinematic_validation.toml --sim --true-geometry-seed SEED --no-kinematic-calibration

Prints per seed: AP off -> on (mean over the 12 held-out poses of ISO 9283 AP_P = |mean reading - commanded|) and
the gain; the play's floor (the mean |error| a pose mean of the validation's readings carries from their measured
scatter alone, Monte Carlo of the per-axis scatter / sqrt(cycles)) and the ceiling AP off / floor, the most gain a
validation of that many cycles can show; the gain with the floor taken out of both sides (per pose
``sqrt(max(|mean|^2 - sum_a s_a^2 / n, 0))``, what more validation cycles would show); the stored fit's reduced chi^2,
its plan for the target gain and the largest |identified - truth| / u over the parameters (the benchmark reads the
simulator's truth; production code never does); the moves and wall time of the runs. Then min/median/max of the
gains over the seeds. One process, seeds in sequence.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.cli import main as bench
from bench.simulators.true_geometry import true_deviations
from bench.store import Store

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
AXES = ("x_mm", "y_mm", "z_mm")


def _seeds(text: str) -> list[int]:
    first, _, last = text.partition("-")
    return list(range(int(first), int(last or first) + 1))


def _example(name: str, folder: Path, cycles: int | None) -> Path:
    """``examples/NAME`` as written, or with ``cycles`` cycles (every other line as written)."""
    if cycles is None:
        return EXAMPLES / name
    lines = [
        f"cycles = {cycles}" if ln.startswith("cycles = ") else ln for ln in (EXAMPLES / name).read_text().splitlines()
    ]
    path = folder / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _bench(*argv: str) -> str:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = bench(list(argv))
    if status != 0:
        raise RuntimeError(f"bench {' '.join(argv)}: exit {status}: {err.getvalue().strip()}")
    return out.getvalue()


def pose_errors(store: Path, run_id: int) -> dict[str, np.ndarray]:
    """Each pose's readings minus its command, (n, 3) mm."""
    with Store(store, read_only=True) as s:
        samples = s.samples(run_id, "pose")
    by_pose: dict[str, list[list[float]]] = {}
    for sample in samples:
        by_pose.setdefault(sample.pose, []).append([sample.values[a] - sample.values[f"cmd_{a}"] for a in AXES])
    return {pose: np.asarray(errors) for pose, errors in by_pose.items()}


def ap_figures(errors: dict[str, np.ndarray], rng: np.random.Generator) -> tuple[float, float, float]:
    """AP (mean over the poses of |mean error|), the play's floor (mean |noise of a pose mean|, Monte Carlo of the
    measured per-axis scatter / sqrt n) and AP with that noise taken out per pose (mm)."""
    ap, floor, debiased = [], [], []
    for e in errors.values():
        mean = e.mean(axis=0)
        var_of_mean = e.var(axis=0, ddof=1) / len(e)
        ap.append(float(np.linalg.norm(mean)))
        floor.append(float(np.linalg.norm(rng.normal(0.0, 1.0, (4000, 3)) * np.sqrt(var_of_mean), axis=1).mean()))
        debiased.append(float(np.sqrt(max(mean @ mean - var_of_mean.sum(), 0.0))))
    return float(np.mean(ap)), float(np.mean(floor)), float(np.mean(debiased))


def one_seed(seed: int, folder: Path, args: argparse.Namespace) -> dict:
    store = folder / f"seed{seed}.db"
    common = ["--sim", "--true-geometry-seed", str(seed), "--no-progress", "--store", str(store)]
    common += ["--speed-factor", str(args.speed_factor)] + (["--ideal"] if args.ideal else [])
    calibration = _example("kinematic_calibration.toml", folder, args.calibration_cycles)
    validation = _example("kinematic_validation.toml", folder, args.validation_cycles)
    started = time.perf_counter()
    run = int(_bench("run", str(calibration), *common, "--no-kinematic-calibration").split()[-1])
    try:
        stored = json.loads(_bench("calibrate", str(run), "--json", "--store", str(store)))
    except RuntimeError as refused:
        return {"seed": seed, "refused": str(refused).split(": exit 2: ")[-1]}
    on = int(_bench("run", str(validation), *common).split()[-1])
    off = int(_bench("run", str(validation), *common, "--no-kinematic-calibration").split()[-1])
    wall_s = time.perf_counter() - started
    rng = np.random.default_rng(seed)
    ap_on, floor_on, true_on = ap_figures(pose_errors(store, on), rng)
    ap_off, floor_off, true_off = ap_figures(pose_errors(store, off), rng)
    truth = true_deviations(seed)
    z = {
        name: abs(p["value"] - truth[name]) / p["uncertainty"]
        for name, p in stored["parameters"].items()
        if name in truth
    }
    worst = max(z, key=z.__getitem__)
    with Store(store, read_only=True) as s:
        samples = {r: len(s.samples(r, "pose")) for r in (run, on, off)}
    plan = stored.get("campaign", {}).get("plan") or {}
    return {
        "seed": seed,
        "ap_off": ap_off,
        "ap_on": ap_on,
        "gain": ap_off / ap_on,
        "floor": floor_on,
        "ceiling": ap_off / floor_on,
        "gain_debiased": true_off / true_on if true_on > 0 else float("inf"),
        "true_off": true_off,
        "true_on": true_on,
        "reduced_chi2": stored["reduced_chi2"],
        "plan": (plan.get("calibration_cycles"), plan.get("validation_cycles")),
        "worst": (worst, z[worst]),
        "samples": samples,
        "wall_s": wall_s,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="60-69", help="first-last true-geometry seeds (default 60-69)")
    parser.add_argument("--calibration-cycles", type=int, default=None, help="default: the example's")
    parser.add_argument("--validation-cycles", type=int, default=None, help="default: the example's")
    parser.add_argument("--speed-factor", type=float, default=10000.0)
    parser.add_argument("--ideal", action="store_true", help="the simulator without its error model")
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in _seeds(args.seeds):
            row = one_seed(seed, Path(tmp), args)
            rows.append(row)
            if "refused" in row:
                print(f"seed {seed}: refused: {row['refused']}", flush=True)
                continue
            print(
                f"seed {seed}: AP {row['ap_off']:.3f} -> {row['ap_on']:.3f} mm, gain {row['gain']:.1f}x "
                f"(ceiling {row['ceiling']:.1f}x, floor {row['floor']:.3f} mm; floor out: {row['true_off']:.3f} -> "
                f"{row['true_on']:.3f} mm, {row['gain_debiased']:.1f}x); reduced chi^2 {row['reduced_chi2']:.2f}, "
                f"plan {row['plan'][0]} / {row['plan'][1]} cycles, worst {row['worst'][0]} {row['worst'][1]:.1f} u; "
                f"samples {row['samples']}, {row['wall_s']:.0f} s",
                flush=True,
            )
    gains = [r["gain"] for r in rows if "gain" in r]
    if gains:
        print(
            f"gain over {len(gains)} stored of {len(rows)}: min {min(gains):.1f}x, median "
            f"{statistics.median(gains):.1f}x, max {max(gains):.1f}x; >= 5x on {sum(g >= 5 for g in gains)}"
        )
    sys.exit(0)


if __name__ == "__main__":
    main()
