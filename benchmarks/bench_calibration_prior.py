"""Held-out AP factor of the pkm5 mice calibration: the default free set against a maximum a posteriori fit.

Run as ``python benchmarks/bench_calibration_prior.py [PRIOR_SCALE] [--avoid-folds]``. Every one of the 36 parameters perturbed
(``true_geometry(seed)``: 0.3 mm joints and offsets, 0.5 % lead), 30 D-optimal poses of 300 candidates, mice-like
data (0.05 mm per axis), 50 held-out poses (AP in the instrument frame; before = documented geometry with the
registration fitted). A held-out pose the true robot misses by > 1 mm when commanded by its own geometry is left out
(the simulated plant's FK takes another branch there, an artefact of the simulator). ``--avoid-folds`` leaves out
of the candidates those with ``ForwardModel.fold_ratio`` below 1/100 of the median (near an FK fold).

* subset: ``identify`` over ``identifiable_subset`` (condition <= 50), the others fixed at 0 (the default);
* MAP: ``identify(..., prior_sigma=...)`` of all 36 parameters plus the registration, the manufacturing
  tolerances (``motion.pkm5.calibration.TOLERANCES`` times PRIOR_SCALE) as a Gaussian prior (the default fit of
  ``bench calibrate`` for the pkm5).

Prints per seed the AP before and after, the factor, the reduced chi^2 and the largest |z| of the identified
parameters against the truth (posterior uncertainty for MAP), and the MAP solve's wall time (one run; `uptime`).
"""

import sys
import time

import numpy as np

from bench.metrology.kinematic_calibration import away_from_folds, identifiable_subset, identify, select_poses
from bench.simulators.true_geometry import attained_poses, true_deviations, true_geometry
from motion import pkm5
from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, apply_parameters, modes_of_poses, tolerance

U_MM = 0.05
ALL = REGISTRATION + PARAMETERS
KINDS = ("constant-orientation", "alpha", "beta")


def held_out_ap(held, command_geometry, registration, truth) -> float:
    truth_steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(held, truth).lengths_mm, truth)
    attainable = (
        np.linalg.norm(attained_poses(truth_steps, modes_of_poses(held), truth)[:, :3] - held[:, :3], axis=1) < 1.0
    )
    target = np.array(held)
    target[:, :3] -= registration
    steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(target, command_geometry).lengths_mm, command_geometry)
    attained = attained_poses(steps, modes_of_poses(held), truth)[:, :3]
    return float(np.mean(np.linalg.norm(attained - held[:, :3], axis=1)[attainable]))


def main() -> None:
    numbers = [a for a in sys.argv[1:] if not a.startswith("--")]
    scale = float(numbers[0]) if numbers else 1.0
    sigma = np.array([tolerance(n) for n in ALL]) * scale
    candidates = pkm5.sample_reachable(300, kinds=KINDS, seed=1)
    all_steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(candidates).lengths_mm)
    all_modes = modes_of_poses(candidates)
    model = ForwardModel(all_steps, all_modes, ALL)
    jac = model.jacobian(np.zeros(len(ALL)))
    ratio = model.fold_ratio(np.zeros(len(ALL))) if "--avoid-folds" in sys.argv else None
    pick = select_poses(jac, U_MM, 30, fold_ratio=ratio)
    free = identifiable_subset(jac[pick], U_MM, ALL, required=REGISTRATION)
    steps, modes = all_steps[pick], all_modes[pick]
    held = pkm5.sample_reachable(50, kinds=KINDS, seed=99)
    left_out = 0 if ratio is None else int(np.sum(~away_from_folds(ratio)))
    print(
        f"prior sigma x {scale:g}; {left_out} candidates left out near an FK fold; default free "
        f"set {len(free)} of {len(ALL)}"
    )
    for seed in range(6):
        truth, deviations = true_geometry(seed), true_deviations(seed)
        noise = np.random.default_rng([seed, 8]).normal(0.0, U_MM, (len(steps), 3))
        measured = attained_poses(steps, modes, truth)[:, :3] + noise
        frame = identify(ForwardModel(steps, modes, REGISTRATION), measured, U_MM)
        before = held_out_ap(held, pkm5.DEFAULT_GEOMETRY, frame.values, truth)
        subset = identify(ForwardModel(steps, modes, free), measured, U_MM)
        after_subset = held_out_ap(held, apply_parameters(free, subset.values), subset.values[:3], truth)
        z_subset = max(
            abs(v - deviations[n]) / s for n, v, s in zip(free, subset.values, subset.uncertainty) if n in deviations
        )
        start = time.perf_counter()
        fit = identify(ForwardModel(steps, modes, ALL), measured, U_MM, prior_sigma=sigma)
        seconds = time.perf_counter() - start
        after_map = held_out_ap(held, apply_parameters(ALL, fit.values), fit.values[:3], truth)
        z_map = max(
            abs(fit.values[i] - deviations[n]) / fit.uncertainty[i] for i, n in enumerate(ALL) if n in deviations
        )
        print(
            f"seed {seed}: AP before {before:.3f} mm | subset {after_subset:.3f} mm x{before / after_subset:.1f} "
            f"chi2 {subset.reduced_chi2:.1f} max|z| {z_subset:.1f} | MAP {after_map:.3f} mm "
            f"x{before / after_map:.1f} chi2/dof {fit.reduced_chi2:.2f} (dof {fit.degrees_of_freedom:.1f}) "
            f"max|z| {z_map:.2f} ({seconds:.2f} s, "
            f"{fit.iterations} evaluations; prior only: {', '.join(fit.prior_only) or 'none'})",
            flush=True,
        )


if __name__ == "__main__":
    main()
