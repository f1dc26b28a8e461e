"""ISO 9283 8.5 cornering, 8.6 path velocity, 9 minimum positioning time, 7.2.3 orientation vAP: hand-computed
cases, the standard's step table, and hypothesis invariants."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bench.errors import ConfigError, InsufficientData
from bench.metrology import (
    MIN_POSITIONING_STEPS_MM,
    cornering_deviations,
    minimum_positioning_targets,
    minimum_positioning_time,
    orientation_accuracy,
    orientation_drift,
    orientation_multidirectional_variation,
    orientation_repeatability,
    path_orientation_characteristics,
    path_speed,
    path_velocity_characteristics,
)

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
small = st.floats(-5, 5, allow_nan=False, allow_infinity=False)
angle_clouds = st.integers(2, 12).flatmap(lambda n: arrays(float, (n, 3), elements=small))


# --- 8.5 cornering ----------------------------------------------------------------------------------------------


def test_cornering_hand_computed_round_off_and_overshoot():
    cut = [[-10, 0], [-2, 0], [0, 2], [0, 10]]  # chord 2 mm before and after the corner: CR = √2
    past = [[-10, 0], [0.3, 0], [0.3, 0.3], [0, 0.6], [0, 10]]  # runs 0.3 mm beyond the outgoing edge
    r = cornering_deviations([cut, past, cut], [0, 0], [-10, 0], [0, 10])
    assert r.cr_per_cycle_mm == pytest.approx((np.sqrt(2), 0.0, np.sqrt(2)))
    assert r.co_per_cycle_mm == pytest.approx((0.0, 0.3, 0.0))
    assert (r.cr_mm, r.co_mm) == pytest.approx((np.sqrt(2), 0.3))
    assert (r.mean_cr_mm, r.mean_co_mm) == pytest.approx((2 * np.sqrt(2) / 3, 0.1))
    assert r.n == 3


def test_cornering_round_off_is_measured_between_samples():
    # samples only at the ends of a chord: the nearest point is mid-chord, not a sample
    r = cornering_deviations([[[-3, 0], [0, 3]]], [0, 0], [-10, 0], [0, 10])
    assert r.cr_mm == pytest.approx(3 / np.sqrt(2))


def test_cornering_in_3d_at_an_obtuse_corner():
    # 135° turn in the x-z plane; the path runs 0.2 mm straight on past the corner, then joins the outgoing line
    u_out = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)
    path = [[-10, 5, 0], [0.2, 5, 0], [0.2 + 5 * u_out[0], 5, 0.2 + 5 * u_out[2] - 0.2], [10, 5, 10]]
    r = cornering_deviations([path], [0, 5, 0], [-10, 5, 0], [10, 5, 10])
    # n̂ = (u_in - (u_in·u_out) u_out)/|.| = (1, 0, -1)/√2; offset of (0.2, 0, 0) is 0.2/√2
    assert r.cr_mm == pytest.approx(0.0)
    assert r.co_mm == pytest.approx(0.2 / np.sqrt(2))


def test_cornering_refuses_a_straight_corner_and_no_cycles():
    with pytest.raises(ConfigError, match="parallel"):
        cornering_deviations([[[0, 0], [1, 0]]], [0, 0], [-1, 0], [1, 0])
    with pytest.raises(InsufficientData):
        cornering_deviations([], [0, 0], [-1, 0], [0, 1])


@settings(max_examples=60, deadline=None)
@given(
    st.integers(3, 20).flatmap(lambda n: arrays(float, (n, 3), elements=finite)),
    arrays(float, 3, elements=finite),
    st.floats(0.1, 3.0),
)
def test_cornering_nonnegative_and_translation_invariant(path, shift, turn):
    corner, start, end = np.zeros(3), np.array([-100.0, 0, 0]), np.array([100 * np.cos(turn), 100 * np.sin(turn), 0])
    r = cornering_deviations([path], corner, start, end)
    moved = cornering_deviations([path + shift], corner + shift, start + shift, end + shift)
    assert r.cr_mm >= 0 and r.co_mm >= 0
    assert r.cr_mm <= np.linalg.norm(path - corner, axis=1).min() + 1e-9  # the polyline is at least as near
    assert moved.cr_mm == pytest.approx(r.cr_mm, abs=1e-6)
    assert moved.co_mm == pytest.approx(r.co_mm, abs=1e-6)


# --- 8.6 path velocity --------------------------------------------------------------------------------------------


def test_path_velocity_hand_computed():
    r = path_velocity_characteristics([[10, 10], [12, 12]], 10.0)
    assert r.mean_speed_per_cycle_mm_s == (10.0, 12.0)
    assert r.av_pct == pytest.approx(10.0)
    assert r.rv_pct == pytest.approx(3 * np.sqrt(2) / 10 * 100)  # S_v = √(1² + 1²)/√1
    assert r.fv_mm_s == 0.0


def test_path_velocity_slow_robot_has_negative_av_and_fv_is_worst_cycle():
    r = path_velocity_characteristics([[9.0, 9.5, 8.5], [9.0, 10.0, 8.0]], 10.0)
    assert r.av_pct == pytest.approx(-10.0)
    assert r.fv_mm_s == pytest.approx(2.0)


def test_path_speed_from_sampled_positions_of_a_constant_velocity_line():
    t = np.linspace(0.0, 1.0, 11)
    position = np.column_stack([30 * t, 40 * t, np.zeros_like(t)])
    assert path_speed(t, position) == pytest.approx(np.full(10, 50.0))


def test_path_velocity_refuses_bad_input():
    with pytest.raises(ConfigError, match="commanded_mm_s"):
        path_velocity_characteristics([[1.0], [1.0]], 0.0)
    with pytest.raises(InsufficientData):
        path_velocity_characteristics([[1.0, 2.0]], 1.0)
    with pytest.raises(ConfigError, match="strictly increasing"):
        path_speed([0.0, 0.0], [[0.0], [1.0]])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(arrays(float, st.integers(1, 8), elements=st.floats(0.1, 500)), min_size=2, max_size=10),
    st.floats(1, 500),
    st.floats(0.001, 1000),
)
def test_path_velocity_invariants(speeds, commanded, scale):
    r = path_velocity_characteristics(speeds, commanded)
    scaled = path_velocity_characteristics([s * scale for s in speeds], commanded * scale)
    assert r.rv_pct >= 0 and r.fv_mm_s >= 0
    assert scaled.av_pct == pytest.approx(r.av_pct, rel=1e-9, abs=1e-9)  # percentages do not depend on the unit
    assert scaled.rv_pct == pytest.approx(r.rv_pct, rel=1e-6, abs=1e-9)
    assert scaled.fv_mm_s == pytest.approx(r.fv_mm_s * scale, rel=1e-9, abs=1e-9)


# --- 9 minimum positioning time -----------------------------------------------------------------------------------


def test_step_table_19_and_cumulative_targets():
    assert MIN_POSITIONING_STEPS_MM == (-10, 20, -50, 100, -200, 500, -1000)
    targets = minimum_positioning_targets([100.0, 0.0, 50.0])
    # iso9283.md §6.15 [R]: cumulative per-axis offsets −10, +10, −40, +60, −140, +360, −640 mm
    assert targets[:, 0].tolist() == [90, 110, 60, 160, -40, 460, -540]
    assert targets[:, 2].tolist() == [40, 60, 10, 110, -90, 410, -590]


def _step(t_leave, t_settle, distance, rate_s=0.01, overshoot_mm=0.0):
    """A 1-D step: at rest until t_leave, linear to the target until t_settle - 0.05, an overshoot, then at rest."""
    t = np.arange(0.0, t_settle + 0.5, rate_s)
    x = np.interp(t, [0.0, t_leave, t_settle - 0.05, t_settle + 1], [0, 0, distance, distance])
    x[(t > t_settle - 0.05) & (t < t_settle)] += overshoot_mm * np.sign(distance)
    return t, x


def test_minimum_positioning_time_per_step_mean_over_cycles():
    band = 0.1
    steps = [
        [_step(0.10, 0.60, -10, overshoot_mm=0.5), _step(0.10, 0.70, -10, overshoot_mm=0.5)],
        [_step(0.20, 1.20, 20), _step(0.20, 1.00, 20)],
    ]
    r = minimum_positioning_time(steps, band_mm=band)
    # leaves the 0.1 mm band one sample after t_leave, settles at t_settle for the overshoot steps and when the
    # ramp enters the band (0.1 mm before its end) for the others
    leave = [0.11, 0.21]
    ramp = 0.1 / 20 * (1.20 - 0.05 - 0.20), 0.1 / 20 * (1.00 - 0.05 - 0.20)
    expected = [[0.60 - leave[0], 0.70 - leave[0]], [1.15 - ramp[0] - leave[1], 0.95 - ramp[1] - leave[1]]]
    for got, want in zip(r.time_s_per_cycle, expected):
        assert got == pytest.approx(want, abs=0.011)  # one sample period
    assert r.mean_time_s == pytest.approx([np.mean(e) for e in expected], abs=0.011)
    assert r.max_time_s[0] == pytest.approx(max(expected[0]), abs=0.011)
    assert r.step_distance_mm == pytest.approx((10.0, 20.0))
    assert r.n == 2


def test_minimum_positioning_time_refuses_unequal_cycles_and_a_step_that_never_moves():
    t = np.linspace(0, 1, 11)
    with pytest.raises(ConfigError, match="cycles per step"):
        minimum_positioning_time([[_step(0.1, 0.5, 5)], [_step(0.1, 0.5, 5)] * 2], band_mm=0.1)
    with pytest.raises(InsufficientData, match="never leaves"):
        minimum_positioning_time([[(t, np.zeros(11))]], band_mm=0.1)


@pytest.mark.parametrize("distance", [0.15, 0.2])
def test_minimum_positioning_time_refuses_a_step_no_longer_than_twice_the_band(distance):
    # Issue 32 item 6: a 0.15 mm step in a 0.1 mm band entered the end band before leaving the start band and read
    # as -0.1 s; the two bands overlap, so there is no positioning time to give.
    with pytest.raises(InsufficientData, match="no longer than twice the 0.1 mm band"):
        minimum_positioning_time([[_step(0.10, 0.60, distance)]], band_mm=0.1)
    assert minimum_positioning_time([[_step(0.10, 0.60, 0.25)]], band_mm=0.1).mean_time_s[0] > 0


# --- 7.2.1 / 7.2.2 / 7.2.3 orientation ----------------------------------------------------------------------------


def test_orientation_vap_hand_computed_per_angle():
    directions = [
        [[1.0, 0.0, 10.0], [1.2, 0.0, 10.0]],  # means (1.1, 0, 10)
        [[0.9, 0.3, 10.0], [0.9, 0.5, 10.0]],  # (0.9, 0.4, 10)
        [[1.0, -0.2, 9.0]],
    ]  # (1.0, -0.2, 9)
    r = orientation_multidirectional_variation(directions)
    assert r.vap_deg == pytest.approx((0.2, 0.6, 1.0))
    assert r.mean_deg[1] == pytest.approx((0.9, 0.4, 10.0))


def test_orientation_vap_needs_two_directions():
    with pytest.raises(ConfigError, match="at least 2"):
        orientation_multidirectional_variation([[[0.0]]])


@settings(max_examples=60, deadline=None)
@given(angle_clouds, arrays(float, 3, elements=small), arrays(float, 3, elements=st.floats(-170, 170)))
def test_orientation_ap_invariant_to_a_common_offset_and_rp_nonnegative(cloud, command, offset):
    ap = orientation_accuracy(cloud, command).ap_deg
    shifted = orientation_accuracy(cloud + offset, command + offset).ap_deg
    rp = orientation_repeatability(cloud).rp_deg
    assert shifted == pytest.approx(ap, abs=1e-6)
    assert min(rp) >= 0
    assert orientation_repeatability(cloud + offset).rp_deg == pytest.approx(rp, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.lists(angle_clouds, min_size=2, max_size=4), arrays(float, 3, elements=st.floats(-170, 170)))
def test_orientation_vap_nonnegative_and_offset_invariant(clouds, offset):
    r = orientation_multidirectional_variation(clouds)
    assert min(r.vap_deg) >= 0
    assert orientation_multidirectional_variation([c + offset for c in clouds]).vap_deg == pytest.approx(
        r.vap_deg, abs=1e-6
    )


# --- 8.2 / 8.3 / 8.4 orientation along a path ---------------------------------------------------------------------


def test_path_orientation_hand_computed_on_a_reorientation_line():
    # three passes along x; angle a ramps 0 -> 10° over 100 mm as commanded, offset per cycle by +0.1, +0.3, +0.2°;
    # b is commanded 0 and wraps across ±180 in the samples of one cycle
    x = np.linspace(0.0, 100.0, 21)
    paths = [np.column_stack([x, np.full_like(x, y), np.zeros_like(x)]) for y in (0.05, -0.05, 0.0)]
    angles = [
        np.column_stack([0.1 * x + off, np.full_like(x, b)]) for off, b in ((0.1, 179.9), (0.3, -179.9), (0.2, 180.0))
    ]
    stations = np.column_stack([np.linspace(12.5, 87.5, 4), np.zeros(4), np.zeros(4)])
    commanded = np.column_stack([0.1 * stations[:, 0], np.full(4, 180.0)])
    r = path_orientation_characteristics(paths, angles, stations, commanded)
    assert r.at_per_station_deg[:, 0] == pytest.approx(np.full(4, 0.2))
    assert r.at_deg == pytest.approx((0.2, 0.0), abs=1e-9)
    assert r.rt_deg == pytest.approx((3 * 0.1, 3 * 0.1))  # S over {0.1, 0.3, 0.2} and {-0.1, 0.1, 0} is 0.1
    assert r.n_cycles == 3


def test_path_orientation_refuses_angles_not_sampled_with_the_positions():
    line = [[0.0, 0.0], [10.0, 0.0]]
    with pytest.raises(ConfigError, match="angles_deg\\[1\\] has 3 rows"):
        path_orientation_characteristics([line, line], [[[0], [1]], [[0], [1], [2]]], [[2, 0], [8, 0]], [[0], [0]])


# --- 7.6 drift of the orientation ---------------------------------------------------------------------------------


def test_orientation_drift_hand_computed_across_180():
    t = [0, 1, 2, 10, 11, 12]
    a = [[179.9, 0.0], [-179.9, 0.0], [180.0, 0.0], [179.5, 0.1], [179.7, 0.3], [179.6, 0.2]]
    r = orientation_drift(t, a, [180.0, 0.0], window_s=5.0)
    assert r.ap_deg[:, 0] == pytest.approx([0.0, -0.4], abs=1e-9)
    assert r.ap_deg[:, 1] == pytest.approx([0.0, 0.2], abs=1e-9)
    assert r.dap_deg == pytest.approx((0.4, 0.2))
    assert r.rp_deg[:, 0] == pytest.approx([0.3, 0.3])  # deviations -0.1, +0.1, 0 → S = 0.1
    assert r.drp_deg == pytest.approx((0.0, 0.3), abs=1e-9)
    assert r.n_per_window.tolist() == [3, 3]


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.05, 1.0),
    st.floats(0.3, 2.0),
    st.floats(0, 1e4),
    arrays(float, 3, elements=finite),
    st.floats(-20, 20).filter(lambda d: abs(d) > 1),
)
@example(1.0, 0.3, 0.0, np.array([64.0, 64.0, 64.0]), 3.0)  # found by Hypothesis: samples on both band edges
def test_positioning_time_is_invariant_to_the_clock_origin_and_the_place(t_leave, duration, t0, place, distance):
    t = np.round(np.arange(0.0, t_leave + duration + 0.5, 0.01), 6)
    x = np.interp(t, [0.0, t_leave, t_leave + duration, 1e9], [0.0, 0.0, distance, distance])
    step = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    r = minimum_positioning_time([[(t, step)]], band_mm=0.1)
    moved = minimum_positioning_time([[(t + t0, step + place)]], band_mm=0.1)
    assert r.mean_time_s[0] >= 0
    # a sample on a band edge (|x - x_start| or |x - x_end| = B to rounding, e.g. 1.5 mm in 0.3 s: 0.05 mm a sample)
    # may land on either side of it once moved, as the last bit falls: then the time may move by one sample an edge
    edges = sum(np.isclose(np.abs(x - end), 0.1, rtol=0, atol=1e-9).any() for end in (x[0], x[-1]))
    assert moved.mean_time_s[0] == pytest.approx(r.mean_time_s[0], abs=0.01 * edges + 1e-6)
    assert r.mean_time_s[0] == pytest.approx(duration * (1 - 0.2 / abs(distance)), abs=0.021)  # ramp minus 2 x B


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=2, max_size=6), st.floats(-170, 170))
def test_path_orientation_rt_nonnegative_and_at_invariant_to_a_common_offset(offsets, common):
    x = np.linspace(0.0, 10.0, 6)
    paths = [np.column_stack([x, np.zeros_like(x)]) for _ in offsets]
    angles = [np.column_stack([0.1 * x + o]) for o in offsets]
    stations, commanded = [[2.0, 0.0], [8.0, 0.0]], np.array([[0.2], [0.8]])
    r = path_orientation_characteristics(paths, angles, stations, commanded)
    shifted = path_orientation_characteristics(paths, [a + common for a in angles], stations, commanded + common)
    assert min(r.rt_deg) >= 0
    assert shifted.at_deg == pytest.approx(r.at_deg, abs=1e-6)
    assert shifted.rt_deg == pytest.approx(r.rt_deg, abs=1e-6)
    assert r.at_deg[0] == pytest.approx(abs(np.mean(offsets)), abs=1e-4)  # circular mean: ~ arithmetic for 1°
