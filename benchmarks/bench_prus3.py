"""Throughput of the 3-PRUS kinematics, measured in one run (prints rates and ratios, asserts nothing).

* IK: N random poses near T1 (sliders, ``clip`` revolutes, reach/stroke/existence checks), one vectorised call,
  and the ``balanced`` convention (60 bisection steps) for comparison.
* FK: from the IK's complete leg joint sets, per-leg FK plus the Kabsch fit, batched.
* Baseline: the same pose fitted pose by pose with ``scipy.optimize.least_squares`` on a subset.

Usage: ``python benchmarks/bench_prus3.py [--ik N] [--fk N] [--baseline N]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from _timing import timed
from scipy.optimize import least_squares

from motion import prus3


def scipy_per_pose(corners: np.ndarray) -> np.ndarray:
    """Fit (P, alpha, beta, gamma) to each pose's three corners with scipy, one solve per pose."""
    poses = np.empty((len(corners), 6))
    for i, target in enumerate(corners):

        def residual(q, target=target):
            return (prus3.corners_mm(q[None])[0][0] - target).ravel()

        start = np.concatenate([target.mean(axis=0), np.zeros(3)])
        poses[i] = least_squares(residual, start, xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    return poses


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ik", type=int, default=1_000_000, help="poses for the IK benchmark")
    parser.add_argument("--fk", type=int, default=200_000, help="joint sets for the FK benchmark")
    parser.add_argument("--baseline", type=int, default=300, help="poses for the per-pose scipy baseline")
    args = parser.parse_args(argv)

    rng = np.random.default_rng(0)
    poses = np.column_stack(
        [rng.uniform([380, 50, -700], [520, 250, -500], (args.ik, 3)), rng.uniform(-8, 8, (args.ik, 3))]
    )
    ik_time, ik = timed(prus3.inverse_kinematics, poses)
    balanced_time, _ = timed(prus3.inverse_kinematics, poses[: args.fk], revolute_convention="balanced", repeat=1)
    count = min(args.fk, len(poses))
    fk_time, fit = timed(
        prus3.forward_kinematics, ik.sliders_mm[:count], ik.revolute_deg[:count], ik.universal_deg[:count]
    )
    error = np.abs(fit.pose - poses[:count])[ik.reachable[:count]].max()
    base_time, base = timed(scipy_per_pose, ik.corners_mm[: args.baseline], repeat=1)
    base_rate, fk_rate = args.baseline / base_time, count / fk_time

    print(
        f"prus3 IK (clip)      {args.ik:>9,} poses  {ik_time:7.3f} s  {args.ik / ik_time / 1e6:7.2f} M poses/s, "
        f"reachable {ik.reachable.mean():.1%}"
    )
    print(
        f"prus3 IK (balanced)  {count:>9,} poses  {balanced_time:7.3f} s  {count / balanced_time / 1e6:7.2f} M poses/s"
    )
    print(
        f"prus3 FK (joints)    {count:>9,} sets   {fk_time:7.3f} s  {fk_rate / 1e3:7.1f} k solves/s, "
        f"max error {error:.1e}"
    )
    print(
        f"scipy least_squares per pose, {args.baseline} solves: {base_rate:8.1f} solves/s, "
        f"max |dpose| vs truth {np.abs(base - poses[: args.baseline]).max():.1e}"
    )
    print(f"speed-up batched FK / per-pose scipy: {fk_rate / base_rate:7.0f}x")


if __name__ == "__main__":
    main()
