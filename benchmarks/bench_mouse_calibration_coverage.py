"""Coverage of the mouse matrix calibration's stated U (95 % claimed), before and after issue 32.

    python benchmarks/bench_mouse_calibration_coverage.py [--trials 2000] [--seed 1]

Prints, per design (moves in both directions / in one direction, 0.6-count start/stop offset) and n (10, 30 moves),
the share of simulated runs whose U(A) covers the true A, per element A11 A12 A21 A22: the old fit (no intercept,
U = 2u) and the production fit (an intercept per move direction, U = t(0.975, K - p) u).
"""

from __future__ import annotations

import argparse

from bench.metrology import fit_matrix
from bench.simulators.mouse_calibration_mc import DESIGNS, matrix_coverage


def _old(reference, counts):
    fit = fit_matrix(reference, counts)
    return fit.a_mm_per_count, 2.0 * fit.u_a_mm_per_count


def _production(reference, counts):
    fit = fit_matrix(reference, counts, per_direction=True)
    return fit.a_mm_per_count, fit.expanded_a_mm_per_count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    print(f"{'design':<16} {'n':>3}  {'fit':<22} {'A11':>6} {'A12':>6} {'A21':>6} {'A22':>6}")
    for design in DESIGNS:
        for n in (10, 30):
            for name, fit in (("old: none, U = 2u", _old), ("per direction, t", _production)):
                coverage = matrix_coverage(fit, n, design, trials=args.trials, seed=args.seed + n)
                print(f"{design:<16} {n:>3}  {name:<22} " + " ".join(f"{100 * c:5.1f}%" for c in coverage.ravel()))


if __name__ == "__main__":
    main()
