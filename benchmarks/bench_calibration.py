"""Identification time of the pkm5 kinematic calibration for 30, 60 and 100 measured poses (target: < 1 s).

Run as ``python benchmarks/bench_calibration.py [--numpy]``. Synthetic mice-like data (0.05 mm per axis) from the
seeded true geometry 0 (every parameter perturbed); the poses are D-optimal away from FK folds (the default design).
Per pose count, min/median/max wall time of 5 runs of each fit: ``map`` (the default: every parameter and the
registration, the tolerances as the prior) and ``free-set`` (what the poses identify, least squares), with two
ratios measured in the same run:

* median / one batched forward-kinematics solve of the same poses (the physical floor: every model evaluation
  needs one);
* the Jacobian: one batched IK pass over every bumped geometry (``ForwardModel.jacobian``) against the same central
  differences taken one geometry at a time (the implementation before 2026-12-03), min of 5 each.

The compiled FK is ``ForwardModel``'s default when numba is installed (the set-up's Jacobian over the candidates
loads it before any timed run); ``--numpy`` times the numpy FK too.
"""

import os
import sys

import numpy as np
from _timing import load_line, min_median_max, spread

from bench.metrology.kinematic_calibration import identifiable_subset, identify, select_poses
from bench.simulators.true_geometry import attained_poses, true_geometry
from motion import pkm5
from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, apply_parameters, modes_of_poses, tolerance
from motion.pkm5.geometry import steps_to_lengths

UNCERTAINTY_MM = 0.05
ALL = REGISTRATION + PARAMETERS


def joint_columns_one_geometry_at_a_time(model: ForwardModel, theta) -> np.ndarray:
    """dF/dtheta of the joint positions by central differences, one IK pass per bumped geometry (the reference the
    batched Jacobian replaced; the same numbers up to rounding)."""
    p = np.nan_to_num(model.poses(theta))
    k = len(model.free)
    out = []
    for j, name in enumerate(model.free):
        if name.startswith(("reg_", "leg_offset_", "scale_")):
            continue
        values = []
        for sign in (1.0, -1.0):
            geometry = apply_parameters(model.free, theta + sign * 1e-4 * np.eye(k)[j], model.nominal)
            values.append(model._stationarity(p, geometry, steps_to_lengths(model.steps, geometry)))
        out.append((values[0] - values[1]) / 2e-4)
    return np.stack(out, -1)


def main() -> None:
    started = os.getloadavg()
    poses = pkm5.sample_reachable(400, kinds=("constant-orientation", "alpha", "beta"), seed=1)
    steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(poses).lengths_mm)
    modes = modes_of_poses(poses)
    candidates = ForwardModel(steps, modes, ALL)
    jac = candidates.jacobian(np.zeros(len(ALL)))
    fold_ratio = candidates.fold_ratio(np.zeros(len(ALL)))
    truth = true_geometry(0)
    sigma = np.array([tolerance(n) for n in ALL])
    engines = ("compiled", "numpy") if "--numpy" in sys.argv else ("compiled",)
    for n in (30, 60, 100):
        pick = select_poses(jac, UNCERTAINTY_MM, n, fold_ratio=fold_ratio)
        free = identifiable_subset(jac[pick], UNCERTAINTY_MM, ALL, required=REGISTRATION)
        rng = np.random.default_rng(n)
        measured = attained_poses(steps[pick], modes[pick], truth)[:, :3] + rng.normal(0, UNCERTAINTY_MM, (n, 3))
        for engine in engines:
            model = ForwardModel(steps[pick], modes[pick], ALL, engine=engine)
            (fk_s,), _ = spread(model.predict, np.zeros(len(ALL)), repeat=1)
            for fit, names, prior in (("map", ALL, sigma), ("free-set", free, None)):
                times, result = spread(
                    lambda: identify(
                        ForwardModel(steps[pick], modes[pick], names, engine=engine),
                        measured,
                        UNCERTAINTY_MM,
                        prior_sigma=prior,
                    )
                )
                print(
                    f"{n:4d} poses, {fit:8s} {len(names)} parameters, FK {engine:8s}: {min_median_max(times)}; "
                    f"{result.iterations} model evaluations; median / one FK solve = {np.median(times) / fk_s:.0f}x",
                    flush=True,
                )
        model = ForwardModel(steps[pick], modes[pick], ALL)
        theta = np.zeros(len(ALL))
        model.predict(theta)
        batched, _ = spread(model.jacobian, theta)
        one_at_a_time, _ = spread(joint_columns_one_geometry_at_a_time, model, theta)
        print(
            f"{n:4d} poses, Jacobian of all {len(ALL)}: batched {min_median_max(batched)}; the joint columns "
            f"alone one geometry at a time {min_median_max(one_at_a_time)}; ratio of the minima "
            f"{min(one_at_a_time) / min(batched):.1f}x",
            flush=True,
        )
    print(load_line(started))


if __name__ == "__main__":
    main()
