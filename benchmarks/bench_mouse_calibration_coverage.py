"""Coverage of the mouse matrix calibration's stated U (95 % claimed), before and after issue 32.

    python benchmarks/bench_mouse_calibration_coverage.py [--trials 1000] [--seed 1]

Prints, per design (an out-and-back chain read at every reversal / outward moves read at both ends, 0.6-count
start/stop offset) and n (10, 30 moves), the share of simulated runs whose U(A) covers the true A, per element
A11 A12 A21 A22, with its binomial standard error: the first fit (no intercept, U = 2u), the fit of 3fa276f (an
intercept per move direction, each sensor axis's residual variance pooled, U = t(0.975, K - p) u) and the
production fit (the same with the moves' shared readings, their known quantisation and REML variance components:
feasible GLS). The mouse counts as a real one (bench.simulators.mouse_calibration_mc).
"""

from __future__ import annotations

import argparse

import numpy as np

from bench.metrology import fit_matrix
from bench.simulators.mouse_calibration_mc import DESIGNS, matrix_coverage


def _first(reference, counts, readings):
    fit = fit_matrix(reference, counts)
    return fit.a_mm_per_count, 2.0 * fit.u_a_mm_per_count


def _pooled(reference, counts, readings):
    fit = fit_matrix(reference, counts, per_direction=True)
    return fit.a_mm_per_count, fit.expanded_a_mm_per_count


def _production(reference, counts, readings):
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    return fit.a_mm_per_count, fit.expanded_a_mm_per_count


FITS = (
    ("first: none, U = 2u", _first),
    ("3fa276f: pooled OLS, t", _pooled),
    ("weighted (FGLS), t", _production),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    standard_error = 100 * np.sqrt(0.95 * 0.05 / args.trials)
    print(f"coverage of U (95 % claimed), {args.trials} runs each; binomial SE at 95 %: {standard_error:.1f} %")
    print(f"{'design':<16} {'n':>3}  {'fit':<24} {'A11':>6} {'A12':>6} {'A21':>6} {'A22':>6}  in 93-97 %")
    for design in DESIGNS:
        for n in (10, 30):
            for name, fit in FITS:
                coverage = 100 * matrix_coverage(fit, n, design, trials=args.trials, seed=args.seed + n)
                inside = "yes" if ((coverage >= 93) & (coverage <= 97)).all() else "no"
                cells = " ".join(f"{c:5.1f}%" for c in coverage.ravel())
                print(f"{design:<16} {n:>3}  {name:<24} {cells}  {inside}", flush=True)


if __name__ == "__main__":
    main()
