"""Monte Carlo of the mouse matrix calibration: does its stated U cover the true A as often as it claims (95 %)?

Each trial simulates a calibration run of ``n`` moves of known length (the protocol's 5-40 mm) with a mouse whose
true forward matrix is :data:`TRUE_B` (800 cpi nominal, 2 % and -1.5 % scale errors, 0.8 degrees of rotation and
some cross-talk): each move starts at a random sub-count phase, its end and start positions are quantised to
whole counts, white count noise is added, and a start/stop offset of ``offset_counts`` is added along the move's
direction (the sensor's lag at starting and stopping). The fit's U(A) (Student's t at its degrees of freedom) is
compared element by element with the truth. Used by ``tests/test_mouse_calibration_coverage.py`` and
``benchmarks/bench_mouse_calibration_coverage.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bench.sensors.calibration import DEFAULT_CPI, MM_PER_INCH

__all__ = ["DESIGNS", "TRUE_B", "calibration_moves", "matrix_coverage"]

_COUNTS_PER_MM = DEFAULT_CPI / MM_PER_INCH
#: The simulated mouse's true forward matrix c = B r (counts/mm).
TRUE_B = _COUNTS_PER_MM * np.array([[1.02, 0.014], [-0.012, 0.985]])
#: Move lengths of the calibration protocol (mm).
_LENGTHS_MM = (5.0, 10.0, 15.0, 20.0, 40.0)
#: Move directions of each design: both ways along x and y, or one way only.
DESIGNS = {"both directions": ((1, 0), (-1, 0), (0, 1), (0, -1)), "one direction": ((1, 0), (0, 1))}


def calibration_moves(
    rng: np.random.Generator,
    n: int,
    design: str,
    *,
    offset_counts: float = 0.6,
    noise_counts: float = 0.3,
    travel_sd_mm: float = 0.01,
    b: np.ndarray = TRUE_B,
) -> tuple[np.ndarray, np.ndarray]:
    """Reference displacements (n, 2) mm and simulated count increments (n, 2) of one calibration run.

    The reference's travel scatters by ``travel_sd_mm`` about its stated length (a calibrated axis repeats to some
    um; 10 um is 0.3 counts), so no length's sub-count phase is fixed from run to run."""
    directions = np.array(DESIGNS[design], dtype=float)
    k = np.arange(n)
    unit = directions[k % len(directions)]
    lengths = np.array(_LENGTHS_MM)[(k // len(directions)) % len(_LENGTHS_MM)]
    reference = unit * lengths[:, None]
    start_counts = rng.uniform(0.0, 1.0, (n, 2))  # where within a count each move starts
    travel = reference + unit * rng.normal(0.0, travel_sd_mm, (n, 1))
    true_counts = travel @ b.T + offset_counts * unit
    increments = np.floor(start_counts + true_counts) - np.floor(start_counts)
    return reference, increments + rng.normal(0.0, noise_counts, (n, 2))


def matrix_coverage(
    fit: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    n: int,
    design: str,
    *,
    trials: int,
    seed: int,
    offset_counts: float = 0.6,
) -> np.ndarray:
    """Share of ``trials`` runs in which |Â - A| <= U(Â), per element of A (2, 2).

    ``fit(reference_mm, counts)`` returns (Â, U(Â)) in mm/count; the truth is A = B⁻¹ of :data:`TRUE_B`.
    """
    rng = np.random.default_rng(seed)
    truth = np.linalg.inv(TRUE_B)
    covered = np.zeros((2, 2))
    for _ in range(trials):
        estimate, expanded = fit(*calibration_moves(rng, n, design, offset_counts=offset_counts))
        covered += np.abs(estimate - truth) <= expanded
    return covered / trials
