"""Throughput of the delta-4 kinematics, measured in one run (prints rates and ratios, asserts nothing).

* IK: N random points in the operating box (x, y in +-60 mm, z -230..-130 mm), one vectorised call.
* FK: the closed form and the batched least-squares fit on the IK angles plus 0.275 deg noise.
* The least-squares FK batched in numpy and in the compiled kernel (``engine='numpy'`` / ``'compiled'``), and the
  fair per-pose peer: the compiled kernel called once per pose from Python.
* Baseline: the same least-squares FK solved pose by pose with ``scipy.optimize.least_squares`` on a subset
  (numpy calls on 1-row arrays: call overhead more than arithmetic).

FK figures are min / median / max of ``--repeat`` runs. Usage:
``python benchmarks/bench_delta4.py [--ik N] [--fk N] [--baseline N] [--repeat R]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _timing import min_median_max, spread, timed
from scipy.optimize import least_squares

from motion import delta4, kernels
from motion.delta4 import compiled
from motion.delta4.geometry import LEG_OUTWARD


def scipy_per_pose(servo_deg: np.ndarray, start_mm: np.ndarray) -> np.ndarray:
    """One scipy least_squares solve per pose over the four sphere residuals (same model as the batched fit)."""
    geometry = delta4.NOMINAL
    knees = delta4.knees_mm(servo_deg, geometry)
    poses = np.empty((len(servo_deg), 3))
    for i, leg_knees in enumerate(knees):

        def residual(p, leg_knees=leg_knees):
            return (
                np.linalg.norm(p + geometry.ankle_offset_mm * LEG_OUTWARD - leg_knees, axis=1) - geometry.lower_arm_mm
            )

        poses[i] = least_squares(residual, start_mm[i], xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    return poses


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ik", type=int, default=1_000_000, help="points for the IK benchmark")
    parser.add_argument("--fk", type=int, default=200_000, help="angle sets for the FK benchmarks")
    parser.add_argument("--baseline", type=int, default=500, help="angle sets for the per-pose scipy baseline")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs of the least-squares FK")
    args = parser.parse_args(argv)

    rng = np.random.default_rng(0)
    points = rng.uniform([-60, -60, -230], [60, 60, -130], size=(args.ik, 3))
    ik_time, ik = timed(delta4.inverse_kinematics, points)
    ik_rate = args.ik / ik_time

    truth = points[: args.fk]
    noisy = ik.servo_deg[: args.fk] + rng.normal(0.0, 0.275, (len(truth), 4))
    closed_time, closed = timed(delta4.forward_kinematics, noisy, method="closed_form")
    ls_times, ls = spread(delta4.forward_kinematics, noisy, engine="numpy", repeat=args.repeat)
    ls_time = float(np.median(ls_times))
    subset = slice(0, args.baseline)
    base_time, base = timed(scipy_per_pose, noisy[subset], closed.pose_mm[subset], repeat=1)
    base_rate = args.baseline / base_time
    ls_rate = len(truth) / ls_time

    print(f"delta4 IK          {args.ik:>9,} points  {ik_time:7.3f} s  {ik_rate / 1e6:7.2f} M poses/s")
    print(
        f"delta4 FK closed   {len(truth):>9,} sets    {closed_time:7.3f} s  "
        f"{len(truth) / closed_time / 1e6:7.2f} M solves/s"
    )
    print(
        f"delta4 FK LS       {len(truth):>9,} sets    {ls_time:7.3f} s  {ls_rate / 1e3:7.1f} k solves/s, "
        f"converged {ls.ok.mean():.4%}, median residual {np.median(ls.residual_mm):.3f} mm"
    )
    print(
        f"  agreement with scipy per pose: max |dp| {np.abs(base - ls.pose_mm[subset]).max():.1e} mm; "
        f"mean position error vs truth: LS {np.linalg.norm(ls.pose_mm - truth, axis=1).mean():.3f} mm, "
        f"closed form {np.linalg.norm(closed.pose_mm - truth, axis=1).mean():.3f} mm"
    )
    print(f"  numpy {args.repeat} runs: {min_median_max(ls_times)}")
    print(f"scipy least_squares per pose, {args.baseline} solves: {base_rate:8.1f} solves/s")
    print(f"speed-up batched LS FK / per-pose scipy: {ls_rate / base_rate:7.0f}x   (not a fair peer)")
    if not kernels.available():
        print("numba not installed: no compiled figures (pip install 'bench[fast]')")
        return
    delta4.forward_kinematics(noisy[:10], engine="compiled")  # load (or compile) the kernel
    c_times, fast = spread(delta4.forward_kinematics, noisy, engine="compiled", repeat=args.repeat)
    c_rate = len(truth) / float(np.median(c_times))
    knees = delta4.knees_mm(noisy, delta4.NOMINAL)
    starts = closed.pose_mm
    peer_times = []
    for _ in range(args.repeat):
        begin = time.perf_counter()
        for i in range(args.baseline * 10):
            compiled.gauss_newton(starts[i : i + 1], knees[i : i + 1], delta4.NOMINAL, 50, 1e-10)
        peer_times.append(time.perf_counter() - begin)
    peer_rate = args.baseline * 10 / float(np.median(peer_times))
    print(
        f"delta4 FK LS compiled {len(truth):>9,} sets: {c_rate / 1e3:7.1f} k solves/s ({min_median_max(c_times)}), "
        f"{c_rate / ls_rate:.2f}x numpy; max |dp| vs numpy {np.abs(fast.pose_mm - ls.pose_mm)[ls.ok].max():.1e} mm"
    )
    print(
        f"  per-pose peer, the compiled kernel called per pose ({args.baseline * 10:,} solves): "
        f"{peer_rate / 1e3:7.1f} k solves/s ({min_median_max(peer_times)}); batched compiled / per-pose = "
        f"{c_rate / peer_rate:.2f}x"
    )


if __name__ == "__main__":
    main()
