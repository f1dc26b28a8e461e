"""Monte Carlo coverage of the mouse matrix's stated U (issue 32, item 5): moves in both directions, and in one
direction, each with a 0.6-count start/stop offset, at n = 10 and n = 30 moves.

Before, the fit had no intercept and stated U = 2u: the offset went into A and U covered A's diagonal in 6-50 % of
runs. The production fit (one intercept per move direction, U from Student's t) removes the bias; this test holds
every element of A at >= 90 % coverage (the 95 +/- 2 % aim is not met everywhere yet: docs/sensors.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.metrology import fit_matrix
from bench.metrology.mouse_calibration import student_k95 as coverage_factor
from bench.simulators.mouse_calibration_mc import (
    DESIGNS,
    calibration_moves,
    matrix_coverage,
)

TRIALS = 600  # binomial SD of a 95 % coverage: 0.9 %


def _production(reference, counts):
    fit = fit_matrix(reference, counts, per_direction=True)
    return fit.a_mm_per_count, fit.expanded_a_mm_per_count


@pytest.mark.parametrize("n", [10, 30])
@pytest.mark.parametrize("design", list(DESIGNS))
def test_stated_u_of_the_mouse_matrix_covers_the_truth(n, design):
    coverage = matrix_coverage(_production, n, design, trials=TRIALS, seed=n)
    assert coverage.min() >= 0.90, coverage
    assert coverage.max() <= 0.995, coverage  # not padded into a promise that says nothing


def test_a_start_stop_offset_is_fitted_with_its_u_and_flagged():
    reference, counts = calibration_moves(np.random.default_rng(3), 30, "one direction", offset_counts=3.0)
    fit = fit_matrix(reference, counts, per_direction=True)
    assert fit.offset_labels == ("+x", "+y")
    # along each move's own sensor axis the offset is 3 counts; across it none
    assert fit.offsets_counts[0, 0] == pytest.approx(3.0, abs=3 * fit.u_offsets_counts[0, 0] + 0.1)
    assert fit.offsets_counts[1, 1] == pytest.approx(3.0, abs=3 * fit.u_offsets_counts[1, 1] + 0.1)
    assert fit.offsets_significant[0, 0] and fit.offsets_significant[1, 1]
    assert fit.u_offsets_counts.shape == (2, 2) and (fit.u_offsets_counts > 0).all()


def test_coverage_factor_is_students_t():
    assert coverage_factor(7) == pytest.approx(2.3646, abs=1e-4)  # t(0.975, 7), tables
    assert coverage_factor(27) == pytest.approx(2.0518, abs=1e-4)
