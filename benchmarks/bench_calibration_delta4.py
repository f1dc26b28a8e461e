"""Identification time of the delta-4 kinematic calibration for 30, 60 and 100 measured poses (target: < 1 s).

Run as ``python benchmarks/bench_calibration_delta4.py``. Camera-like x-y readings (0.02 mm per axis, Gaussian) of a
robot with every parameter perturbed (seed 0: 0.3 deg servo zeros, 0.3 mm lengths and axes); the free set is what
the chosen poses identify. Prints min/median/max wall time of 5 runs each, and the ratio to one batched forward-
kinematics solve of the same poses (the physical floor: every model evaluation needs one).
"""

import numpy as np
from _timing import min_median_max, spread

from bench.metrology.kinematic_calibration import identifiable_subset, identify, select_poses
from motion import delta4
from motion.delta4.calibration import BASE_PARAMETERS, PARAMETERS, REGISTRATION, ForwardModel, attained_positions
from motion.delta4.workspace import workspace_samples

UNCERTAINTY_MM = 0.02
PLANE = REGISTRATION[:2]
CANDIDATES = PLANE + BASE_PARAMETERS


def main() -> None:
    points, reachable = workspace_samples(20000, seed=1)
    points = points[reachable]
    points = points[np.all(np.abs(points[:, :2]) < 75.0, axis=1)][:400]
    servo = delta4.inverse_kinematics(points).servo_deg
    jac = ForwardModel(servo, CANDIDATES).jacobian(np.zeros(len(CANDIDATES)))
    truth = np.random.default_rng(0).normal(0.0, 0.3, len(PARAMETERS))
    for n in (30, 60, 100):
        pick = select_poses(jac, UNCERTAINTY_MM, n)
        free = identifiable_subset(jac[pick], UNCERTAINTY_MM, CANDIDATES, required=PLANE)
        rng = np.random.default_rng(n)
        measured = attained_positions(servo[pick], PARAMETERS, truth)[:, :2] + rng.normal(0, UNCERTAINTY_MM, (n, 2))
        times, result = spread(lambda: identify(ForwardModel(servo[pick], free), measured, UNCERTAINTY_MM))
        (fk_s,), _ = spread(ForwardModel(servo[pick], free).predict, np.zeros(len(free)), repeat=1)
        print(
            f"{n:4d} poses, {len(free)} parameters: {min_median_max(times)}; {result.iterations} model "
            f"evaluations; median / one FK solve = {np.median(times) / fk_s:.0f}x"
        )


if __name__ == "__main__":
    main()
