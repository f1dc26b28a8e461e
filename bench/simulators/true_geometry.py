"""A seeded TRUE geometry of a simulated pkm5 or delta4: the documented geometry perturbed at realistic sizes.

Printed parts and hand-assembled joints put each joint a fraction of a millimetre off its drawing; leg zero offsets
are set by hand; lead screws differ by fractions of a percent (methods-turn2.md §1.1: geometry explains ~90 % of
the pose error of a lightly loaded robot). Each parameter of :data:`motion.pkm5.calibration.PARAMETERS` is drawn
from a normal distribution of its manufacturing tolerance (:func:`motion.pkm5.calibration.tolerance`: joint
positions 0.3 mm, leg zero offsets 0.3 mm, lead 0.5 %, the calibration's prior), truncated at 2.5 sigma, from
``np.random.default_rng([seed, 20])`` (a stream of its own, so the error model's draws of the same seed do not
change).

The delta4 (``bench sim delta4 --true-geometry-seed SEED``): every parameter of
:data:`motion.delta4.calibration.PARAMETERS` (servo zeros 0.3 deg; arm lengths and servo axis positions 0.3 mm: the
tolerances of :data:`motion.delta4.calibration.TOLERANCES`), the same truncation, from
``np.random.default_rng([seed, 40])``.
"""

from __future__ import annotations

import numpy as np

from motion.pkm5 import DEFAULT_GEOMETRY, Geometry
from motion.pkm5.calibration import PARAMETERS, apply_parameters, tolerance

__all__ = ["attained_poses", "delta4_true_deviations", "true_geometry", "true_deviations"]

_TRUNCATE_SIGMA = 2.5


def true_deviations(seed: int, names=PARAMETERS) -> dict[str, float]:
    """Seeded deviations of ``names`` from the nominal geometry (the other parameters stay nominal)."""
    rng = np.random.default_rng([int(seed), 20])
    draws = np.clip(
        rng.normal(0.0, 1.0, len(PARAMETERS)), -_TRUNCATE_SIGMA, _TRUNCATE_SIGMA
    )  # always all, so a subset keeps its values
    return {name: float(draw * tolerance(name)) for name, draw in zip(PARAMETERS, draws) if name in set(names)}


def true_geometry(seed: int, names=PARAMETERS, nominal: Geometry = DEFAULT_GEOMETRY) -> Geometry:
    """The nominal geometry with the seeded deviations of ``names`` applied."""
    deviations = true_deviations(seed, names)
    return apply_parameters(tuple(deviations), tuple(deviations.values()), nominal)


def attained_poses(steps, modes, geometry: Geometry) -> np.ndarray:
    """Poses (N, 5; mm, rad) the robot of ``geometry`` attains for commanded steps in their motion modes (the
    least-squares FK over the six legs, as the simulator's plant moves), NaN rows where the FK fails."""
    from motion.pkm5.calibration import ForwardModel

    return ForwardModel(steps, modes, (), nominal=geometry).poses(np.zeros(0))


def delta4_true_deviations(seed: int) -> dict[str, float]:
    """Seeded deviations of every :data:`motion.delta4.calibration.PARAMETERS` entry (deg or mm, by its unit) from
    the documented delta4 geometry: the truth a delta4 simulator moves by (:func:`bench.simulators.delta4.build_plant`)."""
    from motion.delta4.calibration import PARAMETERS as DELTA4_PARAMETERS
    from motion.delta4.calibration import tolerance as delta4_tolerance

    rng = np.random.default_rng([int(seed), 40])
    draws = np.clip(rng.normal(0.0, 1.0, len(DELTA4_PARAMETERS)), -_TRUNCATE_SIGMA, _TRUNCATE_SIGMA)
    return {name: float(draw * delta4_tolerance(name)) for name, draw in zip(DELTA4_PARAMETERS, draws)}
