"""Held-out error of the delta4 camera calibration: the MAP fit (the default) against the free-set fit.

Run as ``python benchmarks/bench_calibration_prior_delta4.py [SEEDS]`` (default: seeds 0-5). Every one of the 24
deviations perturbed (``delta4_true_deviations(seed)``: 0.3 deg servo zeros, 0.3 mm arm lengths and servo axes,
the frame's included), 30 D-optimal poses of 300 candidates in the camera's field, camera-like readings (x, y;
0.02 mm per axis), 50 held-out positions commanded by each fit (continuous angles: the geometry's share, without
the servo bytes' steps) and read by the true robot. Before: the documented geometry with the registration fitted.

* free-set (``--fit free-set``): ``identify`` over ``identifiable_subset`` (condition <= 100), the others held at
  the drawing;
* MAP (``bench calibrate``'s default): every base parameter and the registration, ``prior_sigma`` (the tolerances;
  servo axis positions sqrt 2 of theirs, measured from the frame legs 1 and 4 fix) as a Gaussian prior.

Prints per seed the held-out mean |reading - target| before and after each fit, its factor, and the largest |z| of
the fitted parameters against the truth's base equivalent (one run; the fits take well under a second).
"""

import sys

import numpy as np

from bench.metrology.kinematic_calibration import identifiable_subset, identify, select_poses
from bench.simulators.true_geometry import delta4_true_deviations
from motion import delta4
from motion.delta4.calibration import (
    BASE_PARAMETERS,
    REGISTRATION,
    ForwardModel,
    attained_positions,
    base_equivalent,
    commanded_servo_deg,
    prior_sigma,
)
from motion.delta4.workspace import workspace_samples

U_MM = 0.02
PLANE = REGISTRATION[:2]
CANDIDATES = PLANE + BASE_PARAMETERS
REGISTRATION_MM = np.array([0.35, -0.2])  # where the camera was registered, in the robot's frame


def _field(seed: int, count: int) -> np.ndarray:
    points, reachable = workspace_samples(20000, seed=seed)
    points = points[reachable]
    return points[np.all(np.abs(points[:, :2]) < 75.0, axis=1)][:count]


def main(seeds) -> None:
    pool, targets = _field(1, 300), _field(50, 50)
    servo = delta4.inverse_kinematics(pool).servo_deg
    jac = ForwardModel(servo, CANDIDATES).jacobian(np.zeros(len(CANDIDATES)))
    pick = select_poses(jac, U_MM, 30)
    free = identifiable_subset(jac[pick], U_MM, CANDIDATES, required=PLANE)
    print(f"30 poses; free set {len(free)} of {len(CANDIDATES)} parameters; MAP all {len(CANDIDATES)}")
    print("seed  before_mm  free-set_mm (factor, max|z|)  MAP_mm (factor, max|z|, reduced chi2)")
    for seed in seeds:
        deviations = delta4_true_deviations(seed)
        names, values = list(deviations), list(deviations.values())
        rng = np.random.default_rng([seed, 5])
        measured = (
            attained_positions(servo[pick], names, values)[:, :2]
            + REGISTRATION_MM
            + rng.normal(0.0, U_MM, (len(pick), 2))
        )
        base = base_equivalent({**deviations, "reg_x_mm": REGISTRATION_MM[0], "reg_y_mm": REGISTRATION_MM[1]})

        def held_out_mm(fit):
            reading = attained_positions(commanded_servo_deg(targets, fit.names, fit.values), names, values)
            return float(np.mean(np.linalg.norm(reading[:, :2] + REGISTRATION_MM - targets[:, :2], axis=1)))

        def max_z(fit):
            return max(abs(v - base[n]) / u for n, v, u in zip(fit.names, fit.values, fit.uncertainty))

        before = held_out_mm(identify(ForwardModel(servo[pick], PLANE), measured, U_MM))
        subset = identify(ForwardModel(servo[pick], free), measured, U_MM)
        posterior = identify(ForwardModel(servo[pick], CANDIDATES), measured, U_MM, prior_sigma=prior_sigma(CANDIDATES))
        a, b = held_out_mm(subset), held_out_mm(posterior)
        print(
            f"{seed:4d}  {before:9.3f}  {a:11.3f} ({before / a:4.1f}x, {max_z(subset):5.1f})    "
            f"{b:6.3f} ({before / b:4.1f}x, {max_z(posterior):4.1f}, {posterior.reduced_chi2:.2f})"
        )


if __name__ == "__main__":
    main([int(s) for s in sys.argv[1:]] or range(6))
