"""Throughput of the PKM kinematics, measured in one run (prints rates and ratios, asserts nothing).

* IK: N = 10^6 random poses in the constant-orientation box, one vectorised call.
* FK: N = 10^5 leg-length sets of reachable poses (translation, alpha and beta mixed), batched least squares.
* Baseline: the same FK solved pose by pose with ``scipy.optimize.least_squares`` (trust-region reflective with
  the same exact Jacobian), on a subset; the speed-up ratio compares solves per second.

Targets on a 2-core machine (issue 3): IK >= 1 M poses/s; batched FK >= 100 k solves/s and >= 100x the per-pose
baseline. Issue 17: IK within 10x of its memory-bandwidth floor (bytes of the poses read and of every result
array written, at the copy bandwidth measured in the same run); min / median / max of ``--repeat`` runs. Usage: ``python benchmarks/bench_pkm5.py [--fk N] [--baseline N]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import least_squares

from _timing import copy_bandwidth_bytes_s, min_median_max, nbytes_of, spread, timed

from motion import pkm5


def scipy_per_pose(lengths: np.ndarray) -> np.ndarray:
    """One scipy least_squares solve per pose, same unknowns and Jacobian as the batched solver."""
    modes = pkm5.detect_mode(lengths)
    poses = np.zeros((len(lengths), 5))
    for i, (target, mode) in enumerate(zip(lengths, modes)):
        angle_col = pkm5.fk.MODES[mode]
        cols = [0, 1, 2] + ([angle_col] if angle_col is not None else [])

        def full(q):
            pose = np.zeros(5)
            pose[cols] = q
            return pose[None, :]

        def residual(q):
            return pkm5.inverse_kinematics(full(q), check_limits=False).lengths_mm[0] - target

        def jac(q):
            return pkm5.jacobian(full(q))[0][:, cols]

        q0 = np.array([150.0, 0.0, 300.0, 0.0][: len(cols)])
        poses[i, cols] = least_squares(residual, q0, jac=jac, xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    return poses


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ik", type=int, default=1_000_000, help="poses for the IK benchmark")
    parser.add_argument("--fk", type=int, default=100_000, help="poses for the batched FK benchmark")
    parser.add_argument("--baseline", type=int, default=300, help="poses for the per-pose scipy baseline")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of IK and FK (min / median / max)")
    args = parser.parse_args(argv)

    rng = np.random.default_rng(0)
    ik_poses = np.zeros((args.ik, 5))
    ik_poses[:, 0] = rng.uniform(46.5, 235.14, args.ik)
    ik_poses[:, 1] = rng.uniform(-136.12, 136.12, args.ik)
    ik_poses[:, 2] = rng.uniform(262.08, 356.68, args.ik)
    ik_times, ik_result = spread(pkm5.inverse_kinematics, ik_poses, repeat=args.repeat)
    ik_time = float(np.median(ik_times))
    ik_rate = args.ik / ik_time
    # floor: read the poses once and write every result array once, at this machine's copy bandwidth
    bandwidth = copy_bandwidth_bytes_s()
    ik_floor = (ik_poses.nbytes + nbytes_of(ik_result)) / bandwidth

    poses = pkm5.sample_reachable(args.fk, kinds=("constant-orientation", "alpha", "beta"), seed=1)
    lengths = pkm5.inverse_kinematics(poses).lengths_mm
    # the seed tables (4,000 reachable poses per mode and their k-d trees) are built once per process
    setup_time, _ = timed(pkm5.forward_kinematics, lengths[:3], repeat=1)
    fk_times, result = spread(pkm5.forward_kinematics, lengths, repeat=args.repeat)
    fk_time = float(np.median(fk_times))
    fk_rate = args.fk / fk_time
    fk_error = np.abs(result.pose - poses).max()

    subset = lengths[: args.baseline]
    base_time, base_poses = timed(scipy_per_pose, subset, repeat=1)
    base_rate = args.baseline / base_time
    base_error = np.abs(base_poses - poses[: args.baseline]).max()

    print(f"IK   {args.ik:>9,} poses   {ik_time:7.3f} s   {ik_rate / 1e6:7.2f} M poses/s   (target >= 1 M/s); "
          f"{args.repeat} runs: {min_median_max(ik_times)}")
    print(f"     memory-bandwidth floor {ik_floor:.4f} s ({(ik_poses.nbytes + nbytes_of(ik_result)) / 1e6:.0f} MB "
          f"at {bandwidth / 1e9:.1f} GB/s copy bandwidth): median / floor = {ik_time / ik_floor:.0f}x "
          "(target <= 10x)")
    print(f"FK   {args.fk:>9,} solves  {fk_time:7.3f} s   {fk_rate / 1e3:7.1f} k solves/s  (target >= 100 k/s), "
          f"max error {fk_error:.1e}, converged {result.converged.mean():.4%}; {args.repeat} runs: "
          f"{min_median_max(fk_times)}")
    print(f"     one-off seed-table build (first call in a process): {setup_time:.3f} s")
    print(f"scipy least_squares per pose, {args.baseline} solves: {base_rate:8.1f} solves/s, max error {base_error:.1e}")
    print(f"speed-up batched FK / per-pose scipy: {fk_rate / base_rate:7.0f}x   (not a fair peer: the per-pose "
          "residual and Jacobian are numpy calls on 1-row arrays, call overhead rather than arithmetic)")


if __name__ == "__main__":
    main()
