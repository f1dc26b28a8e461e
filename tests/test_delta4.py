"""Tests of motion.delta4 against the golden vectors of shared/reference/delta4-lasergrid.md §3 (thesis §8.2.1,
§8.2.2, Fig. 60), the computed workspace table of §1.7, and independent computations.

The document works in cm; values are converted to mm here, tolerances scaled with them (1e-4 cm = 1e-3 mm).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from doctests import run_doctests
from hypothesis import given, settings
from hypothesis import strategies as st

import motion.delta4.error_models
import motion.delta4.geometry
import motion.delta4.kinematics
from motion.delta4 import (
    NOMINAL,
    THESIS,
    Geometry,
    coord_from_servo_deg,
    forward_kinematics,
    inverse_kinematics,
    jacobian_deg_per_mm,
    servo_from_coord_deg,
)
from motion.delta4.error_models import (
    adc_counts,
    legacy_command_byte,
    quantise_thesis_deg,
    servo_deg_from_counts,
    vibration_envelope,
)
from motion.delta4.workspace import reachable_square_half_width_mm, workspace_samples, workspace_volume
from motion.errors import MotionInputError

CM = 10.0  # mm per cm
ANGLE_TOL = 1e-4  # deg, printed 4th decimal
LENGTH_TOL = 1e-4 * CM  # mm
NO_KNEE_MARGIN = dataclasses.replace(THESIS, knee_limits_deg=(0.0, 180.0))


def thesis_table_ik(point_cm):
    """Independent IK: the thesis' per-leg c1, c2, D table (reference §2.2) with the printed constants, in cm."""
    x0, y0, z0 = point_cm
    base = x0**2 + y0**2 + z0**2 - 300.607
    rows = [  # (c1, c2, D-sign of 20 c1 c2, thigh q_T)
        ((5.55 - x0) / z0, (base + 8.9 * x0) / (2 * z0), -1, 10.0),
        ((-5.55 - y0) / z0, (base - 8.9 * y0) / (2 * z0), +1, -10.0),
        ((-5.55 - x0) / z0, (base - 8.9 * x0) / (2 * z0), +1, -10.0),
        ((5.55 - y0) / z0, (base + 8.9 * y0) / (2 * z0), -1, 10.0),
    ]
    angles = []
    for c1, c2, sign, q_thigh in rows:
        disc = 100 + sign * 20 * c1 * c2 - c2**2
        outward = 1 if q_thigh > 0 else -1  # q+ for legs 1, 4; q- for legs 2, 3
        q = (-c1 * c2 + q_thigh + outward * np.sqrt(disc)) / (c1**2 + 1)
        angles.append(np.degrees(np.arctan2(c1 * q + c2, q - q_thigh)) % 360)
    return np.array(angles)


# --- golden vectors -----------------------------------------------------------------------------------------------


def test_tv1_ik_of_minus7_6_minus20_cm_matches_printed_angles_and_knees():
    result = inverse_kinematics([-7 * CM, 6 * CM, -20 * CM], THESIS)
    np.testing.assert_allclose(result.coord_deg[0], [275.7000, 261.6058, 208.7283, 326.4105], atol=ANGLE_TOL)
    np.testing.assert_allclose(result.servo_deg[0], [129.3000, 126.6058, 73.7283, 78.5895], atol=ANGLE_TOL)
    knees_cm = [[10.9932, 0, -9.9506], [0, -11.4598, -9.8929], [-18.7691, 0, -4.8066], [0, 18.3302, -5.5324]]
    np.testing.assert_allclose(result.knees_mm[0], np.array(knees_cm) * CM, atol=LENGTH_TOL)
    assert result.reachable[0] and result.reason[0] is None
    # Reference §2.4: knee angles 120.9, 119.4, 93.0, 95.0 deg.
    np.testing.assert_allclose(result.knee_angle_deg[0], [120.9, 119.4, 93.0, 95.0], atol=0.05)


def test_tv1_fk_returns_the_pose_and_its_angles():
    servo = inverse_kinematics([-70.0, 60.0, -200.0], THESIS).servo_deg
    for method in ("closed_form", "least_squares"):
        fk = forward_kinematics(servo, THESIS, method=method)
        np.testing.assert_allclose(fk.pose_mm[0], [-70.0, 60.0, -200.0], atol=1e-9)
        assert fk.residual_mm[0] < 1e-9 and fk.ok[0]


def test_tv2_closed_form_fk_of_quantised_angles_matches_printed_pose_knees_and_ik_check():
    servo = [129.25, 126.5, 73.7, 78.375]
    np.testing.assert_allclose(coord_from_servo_deg(np.array(servo)), [275.75, 261.5, 208.7, 326.625], atol=1e-12)
    fk = forward_kinematics(servo, THESIS, method="closed_form")
    np.testing.assert_allclose(fk.pose_mm[0], np.array([-6.9946, 6.0139, -19.9864]) * CM, atol=LENGTH_TOL)
    knees_cm = [[11.0019, 0, -9.9497], [0, -11.4781, -9.8902], [-18.7715, 0, -4.8022], [0, 18.3509, -5.5012]]
    np.testing.assert_allclose(fk.knees_mm[0], np.array(knees_cm) * CM, atol=LENGTH_TOL)
    # Legs 1 and 3 exact, legs 2 and 4 share one residual of +0.0151 cm (reference §2.6).
    np.testing.assert_allclose(fk.leg_residual_mm[0], [0, 0.151, 0, 0.151], atol=LENGTH_TOL)
    # Printed IK check of that point: legs 2 and 4 do not come back (over-determined FK).
    check = inverse_kinematics(fk.pose_mm, THESIS)
    np.testing.assert_allclose(check.coord_deg[0], [275.75, 261.6081, 208.7, 326.5304], atol=ANGLE_TOL)
    knees_cm = [[11.0019, 0, -9.9497], [0, -11.4594, -9.8929], [-18.7715, 0, -4.8022], [0, 18.3418, -5.5149]]
    np.testing.assert_allclose(check.knees_mm[0], np.array(knees_cm) * CM, atol=LENGTH_TOL)


def test_tv2_least_squares_fk_matches_reference_regression_vector():
    fk = forward_kinematics([129.25, 126.5, 73.7, 78.375], THESIS)  # least squares is the default
    np.testing.assert_allclose(fk.pose_mm[0], np.array([-6.9881, 6.0158, -19.9776]) * CM, atol=2e-4 * CM)
    np.testing.assert_allclose(fk.leg_residual_mm[0], np.array([-0.0093, 0.0090, -0.0042, 0.0046]) * CM, atol=2e-4 * CM)
    assert fk.residual_mm[0] == pytest.approx(0.0072 * CM, abs=1e-4 * CM)


def test_tv2_joint_space_least_squares_matches_reference_regression_vector():
    measured = np.array([129.25, 126.5, 73.7, 78.375])
    fk = forward_kinematics(measured, THESIS, method="joint_space")
    np.testing.assert_allclose(fk.pose_mm[0], np.array([-6.9894, 6.0144, -19.9774]) * CM, atol=2e-4 * CM)
    angle_residual = inverse_kinematics(fk.pose_mm, THESIS).servo_deg[0] - measured
    np.testing.assert_allclose(angle_residual, [-0.062, 0.060, -0.033, 0.035], atol=1e-3)
    assert fk.ok[0]


def test_tv3_ik_on_axis_and_fk_of_quantised_angles():
    result = inverse_kinematics([0.0, 0.0, -20 * CM], THESIS)
    np.testing.assert_allclose(result.coord_deg[0], [314.0378, 225.9622, 225.9622, 314.0378], atol=ANGLE_TOL)
    np.testing.assert_allclose(result.servo_deg[0], [90.9622] * 4, atol=ANGLE_TOL)
    knees = np.array([[16.9513, 0, -7.1888], [0, -16.9513, -7.1888], [-16.9513, 0, -7.1888], [0, 16.9513, -7.1888]])
    np.testing.assert_allclose(result.knees_mm[0], knees * CM, atol=LENGTH_TOL)
    np.testing.assert_allclose(result.knee_angle_deg[0], [91.7] * 4, atol=0.05)
    quantised = quantise_thesis_deg(result.servo_deg)
    np.testing.assert_allclose(quantised, [[90.75] * 4], atol=1e-12)
    for method in ("closed_form", "least_squares"):
        fk = forward_kinematics(quantised, THESIS, method=method)
        np.testing.assert_allclose(fk.pose_mm[0], [0.0, 0.0, -19.9482 * CM], atol=LENGTH_TOL)


def test_tv4_gui_example_exact_and_whole_degree_paths():
    result = inverse_kinematics([3.05 * CM, -3.99 * CM, -15 * CM], THESIS)
    np.testing.assert_allclose(result.coord_deg[0], [345.4898, 189.0404, 225.6811, 310.3824], atol=ANGLE_TOL)
    np.testing.assert_allclose(result.servo_deg[0], [59.5102, 54.0404, 90.6811, 94.6176], atol=ANGLE_TOL)
    knees = [[19.6810, 0, -2.5055], [0, -19.8758, -1.5713], [-16.9865, 0, -7.1546], [0, 16.4789, -7.6174]]
    np.testing.assert_allclose(result.knees_mm[0], np.array(knees) * CM, atol=LENGTH_TOL)
    # Fig. 60 shows whole degrees (VB integer Mod): 345, 189, 226, 310 -> servo 60, 54, 91, 95.
    shown = np.round(result.coord_deg)
    np.testing.assert_array_equal(shown, [[345, 189, 226, 310]])
    np.testing.assert_allclose(servo_from_coord_deg(shown), [[60, 54, 91, 95]], atol=1e-12)


def test_tv6_vibration_reproduces_printed_envelope():
    vib = vibration_envelope([0.0, 0.0, -20 * CM], THESIS)
    assert len(vib.t_s) == 100 and vib.t_s[-1] == pytest.approx(0.004)
    # Printed to 10 decimals in cm.
    np.testing.assert_allclose(vib.min_mm[0, :2], [-0.2497405356 * CM] * 2, atol=1e-9 * CM)
    np.testing.assert_allclose(vib.max_mm[0, :2], [0.2497405356 * CM] * 2, atol=1e-9 * CM)
    assert vib.max_mm[0, 2] == pytest.approx(-19.9963264968 * CM, abs=1e-9 * CM)
    # The MATLAB code clamps z_min to start - 1e-7; unclamped it is -20 and the span 0.0036735032 cm.
    assert vib.min_mm[0, 2] == pytest.approx(-20 * CM, abs=1e-9 * CM)
    assert vib.span_mm[0, 2] == pytest.approx(0.0036735032 * CM, abs=1e-9 * CM)


def test_vibration_with_servo_angles_in_phase_moves_only_z():
    vib = vibration_envelope([0.0, 0.0, -20 * CM], THESIS, angle="servo")
    np.testing.assert_allclose(vib.span_mm[0, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose([vib.min_mm[0, 2], vib.max_mm[0, 2]], np.array([-20.2424, -19.7550]) * CM, atol=1e-3)


def test_tv7_quantisation_errors_at_both_poses():
    servo = inverse_kinematics([[-70.0, 60.0, -200.0], [0.0, 0.0, -200.0]], THESIS).servo_deg
    quantised = quantise_thesis_deg(servo)
    np.testing.assert_allclose(quantised[0], [129.25, 126.5, 73.7, 78.375], atol=1e-9)
    pose = forward_kinematics(quantised, THESIS, method="closed_form").pose_mm
    error_cm = np.abs(pose - [[-70.0, 60.0, -200.0], [0.0, 0.0, -200.0]]) / CM
    np.testing.assert_allclose(error_cm[0], [0.0054, 0.0139, 0.0136], atol=1e-4)
    np.testing.assert_allclose(error_cm[1], [0.0, 0.0, 0.0518], atol=1e-4)


def test_ik_equals_the_thesis_c1_c2_table_on_random_poses():
    rng = np.random.default_rng(4)
    points_cm = np.column_stack([rng.uniform(-7, 7, 200), rng.uniform(-7, 7, 200), rng.uniform(-23, -13, 200)])
    result = inverse_kinematics(points_cm * CM, THESIS)
    expected = np.array([thesis_table_ik(p) for p in points_cm])
    np.testing.assert_allclose(result.coord_deg, expected, atol=1e-9)


def test_nominal_and_thesis_constants_differ_by_at_most_1e_minus_4_deg():
    points = [[-70.0, 60.0, -200.0], [0.0, 0.0, -200.0], [30.5, -39.9, -150.0]]
    difference = inverse_kinematics(points, NOMINAL).servo_deg - inverse_kinematics(points, THESIS).servo_deg
    assert 0 < np.abs(difference).max() <= 1e-4


# --- conventions --------------------------------------------------------------------------------------------------


def test_servo_coordinate_transforms_match_document_examples_and_invert():
    # Thesis §4.3.2 d: theta_R1 = 0, 90, 180 -> theta_1 = 45, 315, 225; legs 2, 3: theta = 135 + theta_R.
    np.testing.assert_allclose(
        coord_from_servo_deg(np.array([[0.0, 0, 0, 90], [90, 10, 170, 180]])),
        [[45, 135, 135, 315], [315, 145, 305, 225]],
    )
    servo = np.random.default_rng(1).uniform(0, 180, (50, 4))
    np.testing.assert_allclose(servo_from_coord_deg(coord_from_servo_deg(servo)), servo, atol=1e-12)


def test_knee_positions_follow_the_unified_elevation_form():
    # theta_R = 45: arm horizontal outward; 135: straight down (reference §1.5 c).
    knees = motion.delta4.geometry.knees_mm(np.array([[45.0, 45.0, 135.0, 135.0]]))[0]
    np.testing.assert_allclose(knees, [[200, 0, 0], [0, -200, 0], [-100, 0, -100], [0, 100, -100]], atol=1e-12)


# --- reachability -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("point_mm", "reason"),
    [
        ([70.0, 0.0, -100.0], "servo_limit (leg 1)"),  # theta_R1 = 0.9 deg (reference §1.6)
        ([-75.0, 0.0, -135.0], "servo_limit (leg 3)"),  # theta_R3 = 29.55 deg (reference §1.7)
        ([0.0, 0.0, -50.0], "out_of_reach (leg 1)"),  # axis reach ends at -57.5 mm
        ([0.0, 0.0, -280.0], "out_of_reach (leg 1)"),  # and at -272.5 mm
        ([0.0, 0.0, 0.0], "out_of_reach (leg 1)"),  # z0 = 0 divides by zero in the thesis code
        ([0.0, 0.0, 200.0], "above_knee (leg 1)"),
        ([0.0, 0.0, -270.0], "singular (leg 1)"),  # kappa > 160 deg near full extension
    ],
)
def test_unreachable_poses_are_reported_with_reason_and_finite_values(point_mm, reason):
    result = inverse_kinematics(point_mm, NOMINAL)
    assert not result.reachable[0]
    assert result.reason[0] == reason
    for array in (result.servo_deg, result.coord_deg, result.knees_mm, result.knee_angle_deg):
        assert np.all(np.isfinite(array))


def test_servo_angle_of_limit_examples():
    assert inverse_kinematics([70.0, 0.0, -100.0], THESIS).servo_deg[0, 0] == pytest.approx(0.9, abs=0.05)
    assert inverse_kinematics([-75.0, 0.0, -135.0], THESIS).servo_deg[0, 2] == pytest.approx(29.55, abs=0.005)


def test_malformed_input_raises_motion_input_error_naming_the_field():
    with pytest.raises(MotionInputError, match=r"points_mm has shape \(2,\), expected \(N, 3\)"):
        inverse_kinematics([1.0, 2.0])
    with pytest.raises(MotionInputError, match="servo_deg contains NaN"):
        forward_kinematics([90.0, np.nan, 90.0, 90.0])
    with pytest.raises(MotionInputError, match="method = 'newton'"):
        forward_kinematics([90.0] * 4, method="newton")
    with pytest.raises(MotionInputError, match=r"Geometry.lower_arm_mm = -1"):
        Geometry(lower_arm_mm=-1)


def test_fk_of_inconsistent_angles_fails_cleanly_without_nan():
    # theta_R1 = theta_R3 = 45 + acos((n - m)/R1) = 168.7 deg puts x1 - x3 = 2n: the closed form's denominator
    # vanishes (reference §2.4). Arms horizontal on legs 1, 3 and down on 2, 4 leave no root below the knees.
    degenerate = 45 + np.degrees(np.arccos((44.5 - 100) / 100))
    servo = [[degenerate, 90, degenerate, 90], [45, 135, 45, 135]]
    fk = forward_kinematics(servo, NOMINAL, method="closed_form")
    assert np.all(np.isfinite(fk.pose_mm)) and np.all(np.isfinite(fk.residual_mm))
    assert fk.reason.tolist() == [
        "degenerate (x1 - x3 or y4 - y2 equals 2n)",
        "no_solution (end effector above a knee)",
    ]
    assert not fk.ok.any()
    ls = forward_kinematics(servo, NOMINAL)
    assert np.all(np.isfinite(ls.pose_mm)) and ls.residual_mm[1] > 10.0  # best fit, flagged by its residual


# --- round trips and Jacobian --------------------------------------------------------------------------------------


def test_ik_fk_round_trip_over_the_operating_box_both_fk_methods():
    rng = np.random.default_rng(7)
    points = rng.uniform([-60, -60, -230], [60, 60, -130], size=(500, 3))
    result = inverse_kinematics(points, NOMINAL)
    assert result.reachable.all()  # the [choice] operating box lies inside the workspace
    for method in ("closed_form", "least_squares"):
        fk = forward_kinematics(result.servo_deg, NOMINAL, method=method)
        np.testing.assert_allclose(fk.pose_mm, points, atol=1e-8)
        assert fk.ok.all() and fk.residual_mm.max() < 1e-8


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-60, 60),
    y=st.floats(-60, 60),
    z=st.floats(-230, -130),
    noise=st.lists(st.floats(-0.3, 0.3), min_size=4, max_size=4),
)
def test_property_round_trip_and_least_squares_optimality(x, y, z, noise):
    servo = inverse_kinematics([x, y, z]).servo_deg
    np.testing.assert_allclose(forward_kinematics(servo).pose_mm[0], [x, y, z], atol=1e-8)
    noisy = servo + np.array(noise)
    fit = forward_kinematics(noisy)
    closed = forward_kinematics(noisy, method="closed_form")
    assert fit.ok[0] and fit.residual_mm[0] <= closed.residual_mm[0] + 1e-12
    # At the optimum the gradient J^T r of the sphere residuals vanishes.
    legs = fit.pose_mm[0] + 44.5 * motion.delta4.geometry.LEG_OUTWARD - fit.knees_mm[0]
    unit = legs / np.linalg.norm(legs, axis=1, keepdims=True)
    assert np.abs(unit.T @ fit.leg_residual_mm[0]).max() < 1e-8


def test_least_squares_fk_with_noisy_angles_reports_residual_and_beats_closed_form_on_average():
    rng = np.random.default_rng(11)
    points = rng.uniform([-60, -60, -230], [60, 60, -130], size=(300, 3))
    noisy = inverse_kinematics(points, NOMINAL).servo_deg + rng.normal(0, 0.275, (300, 4))
    ls = forward_kinematics(noisy, NOMINAL)
    closed = forward_kinematics(noisy, NOMINAL, method="closed_form")
    assert ls.ok.all() and np.all(ls.residual_mm > 0)
    assert np.all(ls.residual_mm <= closed.residual_mm + 1e-12)  # LS minimises exactly this figure
    ls_error = np.linalg.norm(ls.pose_mm - points, axis=1).mean()
    closed_error = np.linalg.norm(closed.pose_mm - points, axis=1).mean()
    assert ls_error < closed_error


def test_jacobian_matches_central_differences():
    rng = np.random.default_rng(3)
    points = rng.uniform([-60, -60, -230], [60, 60, -130], size=(50, 3))
    jac = jacobian_deg_per_mm(points, NOMINAL)
    step = 1e-4
    numeric = np.stack(
        [
            (
                inverse_kinematics(points + step * e, NOMINAL).servo_deg
                - inverse_kinematics(points - step * e, NOMINAL).servo_deg
            )
            / (2 * step)
            for e in np.eye(3)
        ],
        axis=2,
    )
    assert np.abs(jac - numeric).max() / np.abs(numeric).max() < 1e-6


# --- error models -------------------------------------------------------------------------------------------------


def test_adc_and_legacy_byte_mappings():
    # Reference §5.8: legacy byte 160 -> 215, 30 -> 40; ADC spans 140 deg over 0..255.
    np.testing.assert_array_equal(legacy_command_byte([30.0, 100.0, 160.0]), [40, 134, 215])
    with pytest.raises(MotionInputError, match="170.0, expected 30 <= angle <= 160"):
        legacy_command_byte([170.0])
    np.testing.assert_array_equal(adc_counts([30.0, 100.0, 170.0, 10.0]), [0, 128, 255, 0])
    np.testing.assert_array_equal(adc_counts([30.0, 170.0], direction=-1), [255, 0])
    angles = np.linspace(30, 170, 1001)
    error = servo_deg_from_counts(adc_counts(angles)) - angles
    assert np.abs(error).max() <= 140 / 255 / 2 + 1e-12  # 0.2745 deg, the thesis' "0.275"
    np.testing.assert_allclose(
        servo_deg_from_counts(adc_counts(angles, direction=-1), direction=-1), angles, atol=0.275
    )


# --- workspace ----------------------------------------------------------------------------------------------------


def test_reachable_square_half_width_matches_reference_table():
    z_cm = np.array([-27, -26, -25, -24, -22, -20, -18, -16, -15, -14, -13, -12, -10, -8])
    expected_cm = [1.25, 3.5, 5.0, 6.25, 8.0, 9.5, 10.5, 11.25, 11.75, 8.25, 6.25, 4.75, 2.25, 0.75]
    np.testing.assert_allclose(reachable_square_half_width_mm(z_cm * CM, NO_KNEE_MARGIN), np.array(expected_cm) * CM)


def test_spec_square_of_plus_minus_6cm_is_reachable_for_z_from_minus_24_25_to_minus_13_cm():
    z_mm = np.arange(-255.0, -117.5, 2.5)
    good = z_mm[reachable_square_half_width_mm(z_mm, NO_KNEE_MARGIN, max_mm=62.5) >= 60.0]
    assert (good.min(), good.max()) == (-242.5, -130.0)
    assert np.all(np.diff(good) == 2.5)


def test_monte_carlo_volume_agrees_with_a_grid_count_and_stays_inside_the_box():
    estimate = workspace_volume(100_000, NOMINAL, seed=5)
    axes = [np.arange(-245.0, 250.0, 10.0), np.arange(-245.0, 250.0, 10.0), np.arange(-295.0, 0.0, 10.0)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    grid_volume = inverse_kinematics(grid, NOMINAL).reachable.sum() * 1000.0
    assert abs(estimate.volume_mm3 - grid_volume) < 4 * estimate.standard_error_mm3 + 0.02 * grid_volume
    points, reachable = workspace_samples(100_000, NOMINAL, seed=5)
    inside = points[reachable]
    assert np.all(inside[:, :2] > -240) and np.all(inside[:, :2] < 240) and np.all(inside[:, 2] > -290)


# --- docstring examples -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "module", [motion.delta4.geometry, motion.delta4.kinematics, motion.delta4.error_models], ids=lambda m: m.__name__
)
def test_docstring_examples(module):
    failures, tried = run_doctests(module)
    assert tried > 0 and failures == 0
