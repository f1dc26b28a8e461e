"""ISO 9283 pose characteristics: hand-computed cases, dissertation tables, and hypothesis invariants."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    circular_mean_deg,
    distance_characteristics,
    exchangeability,
    multidirectional_variation,
    orientation_accuracy,
    orientation_repeatability,
    pose_accuracy,
    pose_repeatability,
)

# Dissertation 000 Table 8-3 (AP entire, AP x, AP y, AP z; mm; per-axis printed as absolute values), pkm5.md §6.8.
TABLE_8_3 = {
    "1-1": (1.63, 1.13, 0.81, 0.86),
    "1-2": (1.82, 1.09, 0.79, 1.22),
    "1-3": (1.51, 0.97, 0.84, 0.79),
    "2-1": (1.49, 0.89, 0.92, 0.77),
    "2-2": (1.34, 0.59, 0.91, 0.79),
    "2-3": (1.53, 0.83, 0.97, 0.85),
    "3-1": (1.17, 0.74, 0.27, 0.87),
    "3-2": (1.38, 0.72, 0.77, 0.89),
    "3-3": (1.33, 0.92, 0.74, 0.61),
    "4-1": (1.63, 0.94, 1.08, 0.78),
    "4-2": (1.78, 1.07, 1.03, 0.98),
    "4-3": (1.77, 0.95, 1.02, 1.09),
    "5-1": (1.91, 1.06, 1.13, 1.11),
    "5-2": (1.71, 1.1, 1.12, 0.69),
    "5-3": (1.83, 1.02, 1.25, 0.87),
}

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
clouds = st.integers(2, 12).flatmap(lambda n: arrays(float, (n, 3), elements=finite))


def test_pose_accuracy_hand_computed_against_command_not_first_sample():
    attained = [[10.0, 20.0, 30.0], [10.4, 20.2, 29.6], [10.2, 19.8, 30.2]]  # barycentre (10.2, 20, 29.933..)
    result = pose_accuracy(attained, [10.0, 21.0, 30.0])
    assert result.ap_axes_mm == pytest.approx((0.2, -1.0, -0.2 / 3))
    assert result.ap_mm == pytest.approx(np.sqrt(0.04 + 1.0 + (0.2 / 3) ** 2))
    assert result.barycentre_mm == pytest.approx((10.2, 20.0, 89.8 / 3))
    assert result.n == 3


def test_pose_repeatability_hand_computed():
    # Distances to the barycentre (0, 0, 0): 1, 1, 2, 2 -> l̄ = 1.5, S_l = sqrt(4 * 0.25 / 3)
    attained = [[1, 0, 0], [-1, 0, 0], [0, 2, 0], [0, -2, 0]]
    result = pose_repeatability(attained)
    s_l = np.sqrt(1.0 / 3.0)
    assert result.l_mean_mm == pytest.approx(1.5)
    assert result.s_l_mm == pytest.approx(s_l)
    assert result.rp_mm == pytest.approx(1.5 + 3 * s_l)
    assert result.spread_3s_axes_mm == pytest.approx(3 * np.std(attained, axis=0, ddof=1))


def test_rp_is_not_the_rss_of_per_axis_spreads():
    # Table 8-4 point 1-1 prints RP 2.71 mm against per-axis 2.16/1.92/1.73 (RSS 3.37): RP is l-based, not RSS.
    assert np.sqrt(2.16**2 + 1.92**2 + 1.73**2) == pytest.approx(3.37, abs=0.005)
    rng = np.random.default_rng(1)
    cloud = rng.normal(0.0, 0.5, size=(10, 3))
    result = pose_repeatability(cloud)
    assert result.rp_mm != pytest.approx(np.linalg.norm(result.spread_3s_axes_mm), rel=0.01)


@pytest.mark.parametrize("point", sorted(TABLE_8_3))
def test_table_8_3_ap_is_root_sum_square_of_axes(point):
    # Table 8-3: AP entire equals sqrt(APx² + APy² + APz²) within 0.005 mm on every row (iso9283.md §10.2 #19).
    ap, apx, apy, apz = TABLE_8_3[point]
    bary = np.array([[170.0 + apx, -91.0 - apy, 268.0 + apz]])
    assert pose_accuracy(bary, [170.0, -91.0, 268.0]).ap_mm == pytest.approx(ap, abs=0.005)


def test_planar_and_single_axis_variants():
    planar = pose_repeatability([[0, 0], [2, 0]])
    assert planar.rp_mm == pytest.approx(1.0)
    assert pose_accuracy([[1.0], [3.0]], [1.0]).ap_axes_mm == (1.0,)


def test_one_cycle_raises_insufficient_data_naming_count():
    with pytest.raises(InsufficientData, match=r"1 sample\(s\), at least 2 required"):
        pose_repeatability([[1.0, 2.0, 3.0]])


def test_nan_is_refused_not_propagated():
    with pytest.raises(ConfigError, match=r"attained_mm: row 1 .* expected finite numbers"):
        pose_accuracy([[0, 0, 0], [np.nan, 0, 0]], [0, 0, 0])


def test_command_of_wrong_length_is_refused():
    with pytest.raises(ConfigError, match=r"commanded_mm: shape \(2,\), expected \(3,\)"):
        pose_accuracy([[0, 0, 0]], [0, 0])


def test_orientation_wraps_across_180_degrees():
    # iso9283.md §10.2 #11: {179°, -179°} has mean ±180° and a small spread, never mean 0°.
    assert abs(circular_mean_deg([179.0, -179.0])) == pytest.approx(180.0)
    accuracy = orientation_accuracy([[179.0], [-179.0]], [180.0])
    assert accuracy.ap_deg[0] == pytest.approx(0.0, abs=1e-9)
    assert orientation_repeatability([[179.0], [-179.0]]).rp_deg[0] == pytest.approx(3 * np.sqrt(2.0))


def test_orientation_matches_arithmetic_formula_for_small_angles():
    angles = np.array([[1.0, -2.0, 0.5], [1.2, -2.1, 0.4], [0.9, -1.8, 0.7]])
    accuracy = orientation_accuracy(angles, [1.0, -2.0, 0.0])
    assert accuracy.ap_deg == pytest.approx(tuple(angles.mean(axis=0) - [1.0, -2.0, 0.0]), abs=1e-4)
    rp = orientation_repeatability(angles)
    assert rp.rp_deg == pytest.approx(tuple(3 * angles.std(axis=0, ddof=1)), rel=1e-4)


def test_multidirectional_variation_hand_computed():
    result = multidirectional_variation([[[0, 0, 0], [0, 0, 2]], [[3, 0, 1]], [[0, 4, 1], [0, 4, 1]]])
    assert result.barycentres_mm == ((0, 0, 1), (3, 0, 1), (0, 4, 1))
    assert result.vap_mm == pytest.approx(5.0)
    assert result.farthest_pair == (1, 2)
    assert exchangeability([[[0, 0, 0]], [[0, 0, 1]]]).vap_mm == pytest.approx(1.0)


def test_vap_needs_two_directions():
    with pytest.raises(ConfigError, match="at least 2"):
        multidirectional_variation([[[0, 0, 0]]])


def test_distance_accuracy_is_signed_and_per_axis():
    # Commanded P2 -> P4: D_c = |(100, 0, 0)| = 100; attained distances 99.8 and 99.6 -> AD = -0.3 (short).
    first = [[0, 0, 0], [0, 0, 0]]
    second = [[99.8, 0, 0], [99.6, 0, 0]]
    result = distance_characteristics(first, second, [0, 0, 0], [100, 0, 0])
    assert result.ad_mm == pytest.approx(-0.3)
    assert result.rd_mm == pytest.approx(3 * np.std([99.8, 99.6], ddof=1))
    assert result.ad_axes_mm == pytest.approx((-0.3, 0.0, 0.0))
    assert result.commanded_distance_mm == pytest.approx(100.0)


def test_distance_pairs_by_cycle():
    # iso9283.md §10.2 #5: shuffling only one side must change RD on a non-trivial fixture.
    first = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], dtype=float)
    second = first + [[100, 0, 0], [100.1, 0, 0], [100.3, 0, 0]]
    paired = distance_characteristics(first, second, [0, 0, 0], [100, 0, 0])
    shuffled = distance_characteristics(first, second[[2, 0, 1]], [0, 0, 0], [100, 0, 0])
    jointly = distance_characteristics(first[[2, 0, 1]], second[[2, 0, 1]], [0, 0, 0], [100, 0, 0])
    assert shuffled.rd_mm != pytest.approx(paired.rd_mm)
    assert jointly.rd_mm == pytest.approx(paired.rd_mm)


def test_distance_needs_equal_cycles():
    with pytest.raises(ConfigError, match="first_mm has 2 rows and second_mm has 3"):
        distance_characteristics(np.zeros((2, 3)), np.ones((3, 3)), [0, 0, 0], [1, 1, 1])


@settings(max_examples=60, deadline=None)
@given(clouds)
def test_rp_nonnegative_and_at_least_mean_distance(cloud):
    result = pose_repeatability(cloud)
    assert result.rp_mm >= 0.0
    assert result.rp_mm >= result.l_mean_mm - 1e-9


@settings(max_examples=60, deadline=None)
@given(clouds, arrays(float, 3, elements=finite), st.floats(0, 2 * np.pi), st.integers(0, 2))
def test_rp_invariant_under_rigid_motion(cloud, shift, angle, axis):
    rotation = np.eye(3)
    i, j = [k for k in range(3) if k != axis]
    rotation[[i, i, j, j], [i, j, i, j]] = [np.cos(angle), -np.sin(angle), np.sin(angle), np.cos(angle)]
    moved = cloud @ rotation.T + shift
    assert pose_repeatability(moved).rp_mm == pytest.approx(pose_repeatability(cloud).rp_mm, rel=1e-7, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(clouds, arrays(float, 3, elements=finite), arrays(float, 3, elements=finite))
def test_ap_translation_equivariant(cloud, command, shift):
    base = np.array(pose_accuracy(cloud, command).ap_axes_mm)
    assert np.array(pose_accuracy(cloud + shift, command).ap_axes_mm) == pytest.approx(base + shift, abs=1e-6)
    assert np.array(pose_accuracy(cloud + shift, command + shift).ap_axes_mm) == pytest.approx(base, abs=1e-6)


@settings(max_examples=40, deadline=None)
@given(arrays(float, 3, elements=finite), arrays(float, 3, elements=finite), st.integers(2, 30))
def test_identical_points_give_rp_zero_and_ap_distance_to_command(point, command, n):
    cloud = np.tile(point, (n, 1))
    assert pose_repeatability(cloud).rp_mm == pytest.approx(0.0, abs=1e-9)
    assert pose_accuracy(cloud, command).ap_mm == pytest.approx(np.linalg.norm(point - command), abs=1e-9)
    assert pose_accuracy(cloud, point).ap_mm == pytest.approx(0.0, abs=1e-9)  # a perfect robot has AP = 0


@settings(max_examples=40, deadline=None)
@given(clouds, st.randoms(use_true_random=False))
def test_permutation_invariance(cloud, random):
    order = list(range(len(cloud)))
    random.shuffle(order)
    assert pose_repeatability(cloud[order]).rp_mm == pytest.approx(pose_repeatability(cloud).rp_mm, abs=1e-9)
    assert pose_accuracy(cloud[order], [0, 0, 0]).ap_mm == pytest.approx(pose_accuracy(cloud, [0, 0, 0]).ap_mm)


@settings(max_examples=30, deadline=None)
@given(clouds)
def test_units_scale_linearly(cloud):
    # iso9283.md §10.2 #9: mm -> m scales AP and RP by exactly 1/1000.
    assert pose_repeatability(cloud / 1000).rp_mm == pytest.approx(pose_repeatability(cloud).rp_mm / 1000, abs=1e-9)
    assert pose_accuracy(cloud / 1000, [0, 0, 0]).ap_mm == pytest.approx(pose_accuracy(cloud, [0, 0, 0]).ap_mm / 1000)


@settings(max_examples=40, deadline=None)
@given(clouds, clouds)
def test_rd_ad_invariant_when_both_clouds_move_together(first, second):
    n = min(len(first), len(second))
    first, second = first[:n], second[:n]
    base = distance_characteristics(first, second, [0, 0, 0], [10, 0, 0])
    moved = distance_characteristics(first + 5.0, second + 5.0, [5, 0, 0], [15, 0, 0])
    assert base.rd_mm >= 0
    assert moved.rd_mm == pytest.approx(base.rd_mm, abs=1e-6)
    assert moved.ad_mm == pytest.approx(base.ad_mm, abs=1e-6)


# Delta thesis (003) Appendix D1, reconstructed column-by-column (delta4-lasergrid.md §7.2): errors dx dy dz (mm),
# 15 readings at each of 3 poses, 1 mm resolution. Regression vector: barycentre, AP, l̄, S_l, RP per pose.
D1_COLUMN = """
 1  2  1 -1  1 -1 -1 -2 -2  2  1  0  1  1  1
 2  2  1  0  1  1 -1 -1  1 -2 -2  1  1  2  0
-1  3 -2 -2  1  1  1  1  1 -1  1  1  0  0  1
 0  1  1 -2  0  1  2  1  1  1 -2 -2  2  2  2
-2 -2  1  1  2 -1 -1 -1  2  2 -2 -3  2  2  1
 1  1  2  1 -2 -2 -1  2  3 -3 -2  1  1  1  0
 2 -2  2  2  1  0  0 -1 -1  1  1  1  1 -2  1
 1  1  0  0  0  1 -1 -1 -1  1  2  1  2 -3  1
 2  2  1  1 -2 -2 -2  2  2  2  1  1 -3  2  1
"""
D1_EXPECTED = {  # pose: (barycentre, AP, l̄, S_l, RP)
    0: ((0.2667, 0.4000, 0.3333), 0.5850, 2.1008, 0.8309, 4.5935),
    1: ((0.5333, 0.0667, 0.2000), 0.5735, 2.7524, 0.7287, 4.9386),
    2: ((0.4000, 0.2667, 0.5333), 0.7180, 2.3695, 0.9276, 5.1524),
}


@pytest.mark.parametrize("pose", sorted(D1_EXPECTED))
def test_delta_thesis_appendix_d1_regression(pose):
    errors = np.array(D1_COLUMN.split(), dtype=float).reshape(9, 15)[3 * pose : 3 * pose + 3].T
    barycentre, ap, l_mean, s_l, rp = D1_EXPECTED[pose]
    accuracy = pose_accuracy(errors, [0.0, 0.0, 0.0])
    repeatability = pose_repeatability(errors)
    assert accuracy.barycentre_mm == pytest.approx(barycentre, abs=5e-5)
    assert accuracy.ap_mm == pytest.approx(ap, abs=5e-5)
    assert repeatability.l_mean_mm == pytest.approx(l_mean, abs=5e-5)
    assert repeatability.s_l_mm == pytest.approx(s_l, abs=5e-5)
    assert repeatability.rp_mm == pytest.approx(rp, abs=5e-5)


def test_orientation_distance_per_angle_and_wrap():
    from bench.metrology import orientation_distance_characteristics

    # Command a: 170° -> -170° is a 20° move across ±180°; attained moves of 19.5° and 20.3°.
    result = orientation_distance_characteristics([[170.0], [170.1]], [[-170.5], [-169.6]], [170.0], [-170.0])
    assert result.ad_deg == pytest.approx(((19.5 + 20.3) / 2 - 20.0,))
    assert result.rd_deg == pytest.approx((3 * np.std([19.5, 20.3], ddof=1),))
