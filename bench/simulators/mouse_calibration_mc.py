"""Monte Carlo of the mouse matrix calibration: does its stated U cover the true A as often as it claims (95 %)?

Each trial simulates a calibration run of ``n`` moves of known length (the protocol's 5-40 mm) with a mouse whose
true forward matrix is :data:`TRUE_B` (800 cpi nominal, 2 % and -1.5 % scale errors, 0.8 degrees of rotation and
some cross-talk). The mouse is simulated as a real one counts: its counter holds the accumulated displacement and
reports whole counts, floor(S), keeping the sub-count remainder from move to move (the phase at a move's start is
what the earlier moves left, never a fresh random one); each physical move adds B · travel, a start/stop offset of
``offset_counts`` along its direction (the sensor's lag at starting and stopping) and the sensor's tracking noise
(``noise_counts`` per move, before the counts are whole: a mouse reports integers). The reference's error is one
per reading (a calliper reading, or where a calibrated axis arrived), so a move's travel error is the difference of
its two readings' errors. Moves that share a reading (the protocol's out-and-back chain) share its quantisation and
reference error. The fit's U(A) is compared element by element with the truth. Used by
``tests/test_mouse_calibration_coverage.py`` and ``benchmarks/bench_mouse_calibration_coverage.py``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bench.sensors.calibration import DEFAULT_CPI, MM_PER_INCH

__all__ = ["DESIGNS", "TRUE_B", "CalibrationRun", "calibration_moves", "matrix_coverage"]

_COUNTS_PER_MM = DEFAULT_CPI / MM_PER_INCH
#: The simulated mouse's true forward matrix c = B r (counts/mm).
TRUE_B = _COUNTS_PER_MM * np.array([[1.02, 0.014], [-0.012, 0.985]])
#: Move lengths of the calibration protocol (mm).
_LENGTHS_MM = (5.0, 10.0, 15.0, 20.0, 40.0)
#: Designs: "both directions" reads every move of an out-and-back chain per axis (the protocol: a move's end
#: reading is the next move's start), "one direction" reads each outward move at its start and end (the return
#: between them unread, so moves share no reading).
DESIGNS = ("both directions", "one direction")

CalibrationRun = tuple[np.ndarray, np.ndarray, np.ndarray]


def _readings(n: int, design: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stated positions (R, 2) mm of a run's readings in order, whether each reading ends a fitted move (R,), and
    the axis (0, 1) each reading's position is read along (R,)."""
    if design not in DESIGNS:
        raise ValueError(f"design {design!r}, expected one of {DESIGNS}")
    positions, ends_move, axes = [], [], []
    if design == "both directions":
        for axis, count in ((0, (n + 1) // 2), (1, n // 2)):
            positions.append(np.zeros(2))  # the chain's first reading
            ends_move.append(False)
            axes.append(axis)
            for k in range(count):  # out L1, back L1, out L2, back L2, ...
                position = np.zeros(2)
                if k % 2 == 0:
                    position[axis] = _LENGTHS_MM[(k // 2) % len(_LENGTHS_MM)]
                positions.append(position)
                ends_move.append(True)
                axes.append(axis)
    else:
        for k in range(n):  # +x L1, +y L1, +x L2, ...: a start and an end reading each
            axis, end = k % 2, np.zeros(2)
            end[axis] = _LENGTHS_MM[(k // 2) % len(_LENGTHS_MM)]
            positions += [np.zeros(2), end]
            ends_move += [False, True]
            axes += [axis, axis]
    return np.array(positions), np.array(ends_move), np.array(axes)


def calibration_moves(
    rng: np.random.Generator,
    n: int,
    design: str,
    *,
    offset_counts: float = 0.6,
    noise_counts: float = 0.3,
    reading_sd_mm: float = 0.01 / np.sqrt(2.0),
    b: np.ndarray = TRUE_B,
) -> CalibrationRun:
    """Reference displacements (n, 2) mm, simulated count increments (n, 2) and the numbers of each move's start
    and end reading (n, 2) of one calibration run.

    The reference's reading scatters by ``reading_sd_mm`` about the stated position along the step axis (7 um a
    reading, 10 um a move's travel: 0.3 counts), the sensor's tracking by ``noise_counts`` a move."""
    stated, ends_move, axes = _readings(n, design)
    true = stated.copy()
    true[np.arange(len(true)), axes] += rng.normal(0.0, reading_sd_mm, len(true))
    travel = np.diff(true, axis=0)
    direction = np.sign(travel) * (np.abs(travel) == np.abs(travel).max(axis=1, keepdims=True))
    steps = travel @ b.T + offset_counts * direction + rng.normal(0.0, noise_counts, travel.shape)
    counter = rng.uniform(0.0, 1.0, 2) + np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])
    whole = np.floor(counter)
    moves = np.flatnonzero(ends_move)
    reference = stated[moves] - stated[moves - 1]
    increments = whole[moves] - whole[moves - 1]
    return reference, increments, np.column_stack([moves - 1, moves])


def matrix_coverage(
    fit: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    n: int,
    design: str,
    *,
    trials: int,
    seed: int,
    offset_counts: float = 0.6,
) -> np.ndarray:
    """Share of ``trials`` runs in which |Â - A| <= U(Â), per element of A (2, 2).

    ``fit(reference_mm, counts, readings)`` returns (Â, U(Â)) in mm/count; the truth is A = B⁻¹ of :data:`TRUE_B`.
    """
    rng = np.random.default_rng(seed)
    truth = np.linalg.inv(TRUE_B)
    covered = np.zeros((2, 2))
    for _ in range(trials):
        estimate, expanded = fit(*calibration_moves(rng, n, design, offset_counts=offset_counts))
        covered += np.abs(estimate - truth) <= expanded
    return covered / trials
