"""Identification time of the pkm5 kinematic calibration for 30, 60 and 100 measured poses (target: < 1 s).

Run as ``python benchmarks/bench_calibration.py``. Synthetic mice-like data (0.05 mm per axis) from the seeded true
geometry 0; the free set is what the chosen poses identify. Prints min/median/max wall time of 5 runs each, and the
ratio to one batched forward-kinematics solve of the same poses (the physical floor: every evaluation needs one), for
the numpy FK and the compiled one (``ForwardModel``'s default when numba is installed; the first compiled call of a
process loads numba: the set-up's Jacobian over the 400 candidate poses does it, before any timed run).
"""

import numpy as np

from _timing import min_median_max, spread

from bench.metrology.kinematic_calibration import identifiable_subset, identify, select_poses
from bench.simulators.true_geometry import attained_poses, true_geometry
from motion import pkm5
from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, modes_of_poses

UNCERTAINTY_MM = 0.05
ALL = REGISTRATION + PARAMETERS


def main() -> None:
    poses = pkm5.sample_reachable(400, kinds=("constant-orientation", "alpha", "beta"), seed=1)
    steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(poses).lengths_mm)
    modes = modes_of_poses(poses)
    jac = ForwardModel(steps, modes, ALL).jacobian(np.zeros(len(ALL)))
    truth = true_geometry(0)
    for n in (30, 60, 100):
        pick = select_poses(jac, UNCERTAINTY_MM, n)
        free = identifiable_subset(jac[pick], UNCERTAINTY_MM, ALL, required=REGISTRATION)
        rng = np.random.default_rng(n)
        measured = attained_poses(steps[pick], modes[pick], truth)[:, :3] + rng.normal(0, UNCERTAINTY_MM, (n, 3))
        for engine in ("numpy", "compiled"):
            times, result = spread(lambda: identify(ForwardModel(steps[pick], modes[pick], free, engine=engine),
                                                    measured, UNCERTAINTY_MM))
            model = ForwardModel(steps[pick], modes[pick], free, engine=engine)
            (fk_s,), _ = spread(model.predict, np.zeros(len(free)), repeat=1)
            print(f"{n:4d} poses, {len(free)} parameters, FK {engine:8s}: {min_median_max(times)}; "
                  f"{result.iterations} model evaluations; median / one FK solve = {np.median(times) / fk_s:.0f}x")

if __name__ == "__main__":
    main()
