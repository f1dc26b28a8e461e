"""Optical-mouse calibration: dissertation Tables A.25-A.35 (App. A.7) and least-squares fits."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    fit_axis_scale,
    fit_matrix,
    increment_resolution,
    increments_from_positions,
)

# Table A.28, Y axis, mouse speed 4, 5 mm increments: cursor Y positions (pkm5.md §6.11).
A28_POSITIONS = [951, 926, 902, 877, 853, 829, 805, 780, 756, 731, 706, 682, 657, 633, 608, 584, 560, 537, 513]
DISTANCES_MM = (5.0, 10.0, 15.0, 20.0, 40.0)
# Tables A.26-A.35: printed average Δpixel per distance, printed resolution (mm/pixel) per distance.
SUMMARY_ROWS = {
    "A.26 Y2": ((3.11, 6.13, 9.11, 12.18, 24.25), (1.61, 1.63, 1.65, 1.64, 1.65)),
    "A.27 Y3": ((6.1, 12, 18.1, 24.33, 49.17), (0.82, 0.83, 0.83, 0.82, 0.81)),
    "A.29 Y5": ((48.41, 97.87, 146.9, 196.3, 394.71), (0.10,) * 5),
    "A.30 Y6": ((73.36, 147.55, 222.38, 293.57, 591.6), (0.07,) * 5),
    "A.31 X2": ((3, 6.13, 9.3, 12.45, 24.83), (1.67, 1.63, 1.61, 1.61, 1.61)),
    "A.32 X3": ((6.11, 12.56, 18.84, 24.91, 50), (0.82, 0.80, 0.80, 0.80, 0.80)),
    "A.33 X4": ((24.9, 50.06, 75, 100.44, 202.14), (0.20,) * 5),
    "A.34 X5": ((49.95, 100.28, 149.5, 201, 401), (0.10,) * 5),
    "A.35 X6": ((69.94, 138.5, 208.23077, 296.30769, 600), (0.07,) * 5),
}


def test_table_a28_fixture_reproduces_mean_resolution_and_three_sigma():
    deltas = increments_from_positions(A28_POSITIONS)
    assert deltas.tolist() == [25, 24, 25, 24, 24, 24, 25, 24, 25, 25, 24, 25, 24, 25, 24, 24, 23, 24]
    result = increment_resolution(5.0, deltas)
    assert result.n == 18
    assert result.mean_delta_counts == pytest.approx(24.33, abs=0.005)  # printed "Average 24.33"
    assert result.resolution_mm_per_count == pytest.approx(0.2055, abs=0.00005)  # printed 0.21
    assert result.three_sigma_counts == pytest.approx(1.78, abs=0.005)  # Table A.25, speed 4, Y, 5 mm
    assert result.tolerance_mm == pytest.approx(1.782 * 0.2055, abs=0.001)


def test_tolerance_of_the_dissertation():
    # App. A.7: 3σ of 5.32 px (X, 40 mm, speed 4) x 0.2 mm/px = 1.06 mm "tolerance".
    deltas = np.array([202.14 - 5.32 / 3, 202.14 + 5.32 / 3])  # n = 2: S = |Δ1 - Δ2| / √2
    result = increment_resolution(40.0, deltas)
    assert result.three_sigma_counts == pytest.approx(3 * (2 * 5.32 / 3) / np.sqrt(2))
    assert 5.32 * 0.2 == pytest.approx(1.064)


@pytest.mark.parametrize("table", sorted(SUMMARY_ROWS))
def test_summary_rows_resolution_is_distance_over_mean_delta(table):
    averages, printed = SUMMARY_ROWS[table]
    for distance, average, resolution in zip(DISTANCES_MM, averages, printed):
        computed = increment_resolution(distance, [average, average]).resolution_mm_per_count
        assert computed == pytest.approx(resolution, abs=0.005 + 1e-9), (table, distance)


def test_table_a28_15mm_prints_021_where_the_data_give_0203():
    # Disagreement kept as a fixture: 15 / 73.83 = 0.2032 mm/px rounds to 0.20, Table A.28 prints 0.21.
    assert 15 / 73.83 == pytest.approx(0.2032, abs=1e-4)


def test_one_rounded_resolution_reads_40mm_moves_wrongly():
    # iso9283.md §8.2(b): with 0.2 mm/px a 40 mm move reads 39.38 mm in Y (Table A.28) and 40.43 mm in X (A.33).
    assert 196.89 * 0.2 == pytest.approx(39.38, abs=0.005)
    assert 202.14 * 0.2 == pytest.approx(40.43, abs=0.005)
    y = np.mean([d / a for d, a in zip(DISTANCES_MM, (24.33, 48.69, 73.83, 98.67, 196.89))])
    x = np.mean([d / a for d, a in zip(DISTANCES_MM, SUMMARY_ROWS["A.33 X4"][0])])
    assert y == pytest.approx(0.204, abs=0.0005) and x == pytest.approx(0.1995, abs=0.0005)


def test_restart_markers_are_segment_breaks_not_zero():
    deltas = increments_from_positions([700, 703, 706, np.nan, 433, 426])
    assert deltas.tolist() == [3, 3, 7]


def test_increment_resolution_needs_two_increments():
    with pytest.raises(InsufficientData, match=r"increments_counts: 1 sample\(s\), at least 2"):
        increment_resolution(5.0, [24])
    with pytest.raises(ConfigError, match="distance_mm = 0"):
        increment_resolution(0.0, [24, 25])


def test_axis_fit_recovers_scale_and_offset():
    reference = np.repeat([5.0, 10, 15, 20, 40], 5)
    noise = np.tile([-1.0, 0.5, 0.0, 0.5, 0.0], 5)
    counts = 4.9 * reference + 2.0 + noise
    result = fit_axis_scale(reference, counts)
    slope, offset = np.polyfit(reference, counts, 1)  # independent computation
    assert result.slope_counts_per_mm == pytest.approx(slope)
    assert result.offset_counts == pytest.approx(offset)
    assert result.scale_mm_per_count == pytest.approx(1 / slope)
    assert result.residual_rms_counts == pytest.approx(
        np.sqrt(np.mean((counts - np.polyval([slope, offset], reference)) ** 2))
    )
    cov = np.polyfit(reference, counts, 1, cov="unscaled")[1] * np.sum(np.square(result.residuals_counts)) / (25 - 2)
    assert result.u_scale_mm_per_count == pytest.approx(np.sqrt(cov[0, 0]) / slope**2)


def test_axis_fit_refuses_a_single_length():
    with pytest.raises(ConfigError, match="same length"):
        fit_axis_scale([5, 5, 5], [24, 25, 24])


def _matrix_data(rng, b, noise):
    directions = np.array([[1, 0], [0, 1], [1, 1], [1, -1], [-1, 0], [0, -1]], dtype=float)
    lengths = np.array([5.0, 10, 20, 40])
    reference = np.array([d * s for d in directions for s in lengths])
    counts = reference @ b.T + rng.normal(0, noise, reference.shape)
    return reference, counts


def test_matrix_fit_recovers_rotation_scale_and_cross_talk():
    theta = np.deg2rad(3.0)
    rotation = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    a_true = rotation @ np.array([[0.2, 0.004], [0.004, 0.19]])  # mm/count, with shear
    reference, counts = _matrix_data(np.random.default_rng(0), np.linalg.inv(a_true), 0.0)
    result = fit_matrix(reference, counts)
    assert result.a_mm_per_count == pytest.approx(a_true, abs=1e-12)
    assert result.rotation_deg == pytest.approx(3.0, abs=1e-9)
    assert result.residuals_counts == pytest.approx(np.zeros_like(counts), abs=1e-9)
    assert result.scale_mm_per_count == pytest.approx(np.linalg.norm(a_true, axis=0))


def test_matrix_fit_uncertainty_matches_monte_carlo():
    rng = np.random.default_rng(42)
    b_true = np.array([[5.0, 0.2], [-0.1, 5.2]])
    fits = [fit_matrix(*_matrix_data(rng, b_true, 0.8)) for _ in range(400)]
    empirical = np.std([f.a_mm_per_count for f in fits], axis=0, ddof=1)
    predicted = np.mean([f.u_a_mm_per_count for f in fits], axis=0)
    assert predicted == pytest.approx(empirical, rel=0.2)


def test_matrix_fit_with_intercept_finds_lost_counts():
    reference, counts = _matrix_data(np.random.default_rng(1), np.eye(2) * 5, 0.0)
    result = fit_matrix(reference, counts + [3.0, -2.0], intercept=True)
    assert result.offset_counts == pytest.approx([3.0, -2.0])


def test_matrix_fit_needs_two_directions():
    reference = np.column_stack([np.arange(1.0, 6.0), np.zeros(5)])
    with pytest.raises(InsufficientData, match="non-parallel"):
        fit_matrix(reference, reference * 5)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 2.0), st.floats(-30, 30))
def test_matrix_fit_is_exact_on_noise_free_data(scale, angle_deg):
    theta = np.deg2rad(angle_deg)
    a_true = scale * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    reference, counts = _matrix_data(np.random.default_rng(0), np.linalg.inv(a_true), 0.0)
    result = fit_matrix(reference, counts)
    assert result.rotation_deg == pytest.approx(angle_deg, abs=1e-6)
    assert result.scale_mm_per_count == pytest.approx([scale, scale], rel=1e-9)
