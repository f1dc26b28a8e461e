"""Monte Carlo coverage of the mouse matrix's stated U (issue 32): moves in an out-and-back chain (both
directions, each move's end reading the next one's start, the protocol's order) and outward moves read at both ends
(one direction), each with a 0.6-count start/stop offset, at n = 10 and n = 30 moves, on a simulated mouse whose
counter keeps its sub-count remainder and reports whole counts (bench.simulators.mouse_calibration_mc).

The fit pooling each sensor axis's residual variance (ordinary least squares) covered the diagonal of A in 87 % of
runs: moves that share a reading share its quantisation and reference error, and the reference's error shows on
the moves along each sensor axis only. The production fit weighs both (a known quantisation component per reading,
REML for the rest, feasible GLS): this test holds every element at 93-97 % at n = 30 and >= 93 % at n = 10 (where
U is conservative: docs/sensors.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.metrology import fit_matrix
from bench.metrology.mouse_calibration import student_k95 as coverage_factor
from bench.metrology.mouse_variance import feasible_gls, move_error_structures, shared_reading_matrix
from bench.simulators.mouse_calibration_mc import DESIGNS, calibration_moves, matrix_coverage

TRIALS = 600  # binomial SD of a 95 % coverage: 0.9 %


def _production(reference, counts, readings):
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    return fit.a_mm_per_count, fit.expanded_a_mm_per_count


@pytest.mark.parametrize("design", DESIGNS)
def test_stated_u_of_the_mouse_matrix_covers_the_truth_95_percent_at_30_moves(design):
    coverage = matrix_coverage(_production, 30, design, trials=TRIALS, seed=30)
    assert coverage.min() >= 0.93, coverage
    assert coverage.max() <= 0.97, coverage


@pytest.mark.parametrize("design", DESIGNS)
def test_stated_u_of_the_mouse_matrix_covers_the_truth_at_10_moves(design):
    coverage = matrix_coverage(_production, 10, design, trials=TRIALS // 2, seed=10)
    assert coverage.min() >= 0.93, coverage


def test_the_simulated_mouse_reports_whole_counts_and_chains_its_readings():
    reference, counts, readings = calibration_moves(np.random.default_rng(2), 10, "both directions")
    assert (counts == np.round(counts)).all()  # a mouse reports integers
    # x chain +5 -5 +10 -10 +15, then y: each move starts at the previous move's end reading, but the first of each
    # (the unread move from the x chain's end to the y chain's start lies between readings 5 and 6)
    assert readings.tolist() == [[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [6, 7], [7, 8], [8, 9], [9, 10], [10, 11]]
    # out and back over the same length: the two increments sum to the two offsets' difference, never drift apart
    assert reference[:2, 0].tolist() == [5.0, -5.0] and abs(counts[0, 0] + counts[1, 0]) <= 3


def test_a_start_stop_offset_is_fitted_with_its_u_and_flagged():
    reference, counts, readings = calibration_moves(np.random.default_rng(3), 30, "one direction", offset_counts=3.0)
    fit = fit_matrix(reference, counts, per_direction=True, readings=readings)
    assert fit.offset_labels == ("+x", "+y")
    # along each move's own sensor axis the offset is 3 counts; across it none
    assert fit.offsets_counts[0, 0] == pytest.approx(3.0, abs=3 * fit.u_offsets_counts[0, 0] + 0.1)
    assert fit.offsets_counts[1, 1] == pytest.approx(3.0, abs=3 * fit.u_offsets_counts[1, 1] + 0.1)
    assert fit.offsets_significant[0, 0] and fit.offsets_significant[1, 1]
    assert fit.u_offsets_counts.shape == (2, 2) and (fit.u_offsets_counts > 0).all()


def test_feasible_gls_recovers_known_variance_components():
    """800 moves in chains of 10 with tracking noise 0.3 counts a move and a reference error of 0.2 counts a
    reading on the x moves, quantised readings: REML finds both variances, the quantisation taken as known."""
    rng = np.random.default_rng(4)
    size = 800
    x_moves = np.arange(size) % 20 < 10
    chained = np.arange(size) % 10 != 0
    starts_own = size + 1 + np.arange(size)  # a chain's first move starts at a reading of its own
    numbers = np.column_stack([np.where(chained, np.arange(size), starts_own), np.arange(1, size + 1)])
    on_x = np.concatenate([x_moves[:1], x_moves])  # reading j ends move j - 1 (and starts move j)
    readings = rng.uniform(-0.5, 0.5, size + 1) + 0.2 * on_x * rng.normal(size=size + 1)
    # one error a reading; a chain's first move starts at a reading of its own
    starts = np.where(chained, readings[:-1], rng.uniform(-0.5, 0.5, size) + 0.2 * x_moves * rng.normal(size=size))
    design = np.column_stack([np.linspace(1.0, 40.0, size), np.ones(size)])
    y = design @ [31.5, 0.6] + readings[1:] - starts + rng.normal(0.0, 0.3, size)
    fit = feasible_gls(y, design, *move_error_structures(numbers, x_moves))
    # SDs of the estimates about 0.007 and 0.01 (8 seeds); without the known quantisation the first would be 0.17
    assert fit.components[0] == pytest.approx(0.09, abs=0.02)
    assert fit.components[1] == pytest.approx(0.04, abs=0.03)
    assert fit.coefficients == pytest.approx([31.5, 0.6], abs=0.05)


def test_feasible_gls_with_known_covariance_is_the_whitened_least_squares():
    rng = np.random.default_rng(5)
    starts = np.where(rng.uniform(size=12) < 0.6, np.arange(12), 20 + np.arange(12))  # some chained, some not
    known = 0.1 * shared_reading_matrix(np.column_stack([starts, np.arange(1, 13)])) + 0.05 * np.eye(12)
    design = np.column_stack([rng.normal(size=12), np.ones(12)])
    y = rng.normal(size=12)
    whiten = np.linalg.inv(np.linalg.cholesky(known))  # L⁻¹ y = L⁻¹ X β + white noise
    expected = np.linalg.lstsq(whiten @ design, whiten @ y, rcond=None)[0]
    fit = feasible_gls(y, design, (), known)
    assert fit.coefficients == pytest.approx(expected, rel=1e-9)
    assert fit.covariance == pytest.approx(np.linalg.inv((whiten @ design).T @ (whiten @ design)), rel=1e-9)


def test_coverage_factor_is_students_t():
    assert coverage_factor(7) == pytest.approx(2.3646, abs=1e-4)  # t(0.975, 7), tables
    assert coverage_factor(27) == pytest.approx(2.0518, abs=1e-4)
