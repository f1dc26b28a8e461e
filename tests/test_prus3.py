"""Tests of motion.prus3 against shared/reference/prus3.md §12 (test vectors, stand-in geometry a = 600,
b = 75, c = 100, stroke 0-1200 mm, n = 0), the paper's explicit equations (Eqs. 11, 12, 14, 36-39, source
004_3f60c4e3660a8655.txt) and independent numerical checks.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from doctests import run_doctests

import motion.prus3.jacobian
import motion.prus3.kinematics
import motion.prus3.trajectory
from motion.errors import MotionInputError
from motion.prus3 import (
    STAND_IN,
    STAND_IN_ORIGIN_MM,
    actuator_residual_mm,
    corners_mm,
    forward_kinematics,
    inverse_kinematics,
    paper_trajectory,
    pose_from_corners,
    rotation_matrix,
    slider_jacobian,
    workspace_samples,
    workspace_volume,
    workspace_volume_quadrature,
)
from motion.prus3.geometry import euler_deg_from_matrix
from motion.prus3.revolute import existence_margin, universal_from_revolute

HOME = [530.0, 0.0, -600.0, 0.0, 0.0, 0.0]
T1 = [450.0, 150.0, -600.0, 3.0, -4.0, 5.0]
TOL_MM, TOL_DEG = 1e-5, 1e-5


def random_reachable_poses(count: int, seed: int) -> np.ndarray:
    """Poses near T1 that pass the +1-branch IK (rejection sampling)."""
    rng = np.random.default_rng(seed)
    poses = np.column_stack(
        [rng.uniform([380, 50, -700], [520, 250, -500], (count * 4, 3)), rng.uniform(-8, 8, (count * 4, 3))]
    )
    return poses[inverse_kinematics(poses).reachable][:count]


# --- geometry and errata ------------------------------------------------------------------------------------------


def test_tv1_platform_corners_and_side():
    np.testing.assert_allclose(
        STAND_IN.platform_corners_mm, [[37.5, 0, 64.951905], [-75, 0, 0], [37.5, 0, -64.951905]], atol=1e-6
    )
    corners = corners_mm(np.array([T1]))[0][0]
    for i, j in ((0, 1), (1, 2), (0, 2)):
        assert np.linalg.norm(corners[i] - corners[j]) == pytest.approx(129.903811, abs=1e-6)


def test_erratum_e5_printed_eq12_matrix_is_not_a_rotation_and_rz_ry_rx_is():
    alpha, beta, gamma = 0.3, -0.2, 0.5
    ca, sa, cb, sb, cg, sg = (
        math.cos(alpha),
        math.sin(alpha),
        math.cos(beta),
        math.sin(beta),
        math.cos(gamma),
        math.sin(gamma),
    )
    printed = np.array(  # Eq. (12) exactly as printed
        [
            [cb * ca, cg * sa * sb - ca * sg, sa * sg + ca * cg * sb],
            [cb * sa, ca * cg + sa * sb * sg, ca * sb * sg - cg * sa],
            [-sb, cb * sg, cg * cb],
        ]
    )
    assert np.abs(printed.T @ printed - np.eye(3)).max() == pytest.approx(0.149058, abs=1e-6)
    assert np.linalg.det(printed) == pytest.approx(0.969620, abs=1e-6)
    rotation = rotation_matrix(np.degrees([[alpha, beta, gamma]]))[0]
    np.testing.assert_allclose(
        rotation,
        [[0.860089, -0.509536, -0.024882], [0.469869, 0.810239, -0.350336], [0.198669, 0.289629, 0.936293]],
        atol=1e-6,
    )
    assert np.abs(rotation.T @ rotation - np.eye(3)).max() < 1e-15


def test_corners_equal_the_explicit_eq14_formulas():
    rng = np.random.default_rng(2)
    b, delta = 75.0, math.radians(30)
    for pose in np.column_stack([rng.uniform(-500, 500, (20, 3)), rng.uniform(-40, 40, (20, 3))]):
        px, py, pz = pose[:3]
        ca, sa, cb, sb, cg, sg = (f(math.radians(v)) for v in pose[3:] for f in (math.cos, math.sin))
        sd, cd = math.sin(delta), math.cos(delta)
        expected = [
            [
                px + b * sd * cb * cg + b * cd * (sa * sg + ca * cg * sb),
                py + b * sd * cb * sg + b * cd * (ca * sb * sg - cg * sa),
                pz - sb * b * sd + b * cd * ca * cb,
            ],
            [px - b * cb * cg, py - b * cb * sg, pz + b * sb],
            [
                px + b * sd * cb * cg - b * cd * (sa * sg + ca * cg * sb),
                py + b * sd * cb * sg - b * cd * (ca * sb * sg - cg * sa),
                pz - sb * b * sd - b * cd * ca * cb,
            ],
        ]
        np.testing.assert_allclose(corners_mm(pose[None])[0][0], expected, atol=1e-9)


def test_erratum_e3_corrected_eq11_equals_the_forward_kinematics_and_printed_k1x_does_not():
    rng = np.random.default_rng(5)
    a, c = 600.0, 100.0
    s = rng.uniform(0, 1200, (10, 3))
    x2, x3, x4 = (rng.uniform(-0.7, 0.7, (10, 3)) for _ in range(3))
    fit = forward_kinematics(s, np.degrees(x2), np.degrees(np.stack([x3, x4], axis=-1)))
    corners = corners_mm(fit.pose)[0]
    y = np.array([-c, 0.0, c])
    corrected = np.stack(
        [
            a * np.cos(x2) * np.cos(x4) + a * np.sin(x2) * np.sin(x3) * np.sin(x4),
            a * np.cos(x3) * np.sin(x4) + y,
            a * np.cos(x2) * np.sin(x3) * np.sin(x4) - a * np.cos(x4) * np.sin(x2) - s,
        ],
        axis=-1,
    )
    # Random joints do not close the loop: compare the corners the FK was fed through its own residual.
    np.testing.assert_allclose(
        fit.residual_mm, np.sqrt(np.mean(np.sum((corners - corrected) ** 2, axis=2), axis=1)), atol=1e-9
    )
    printed_k1x = a * np.cos(x2[:, 0]) * np.cos(x2[:, 0]) + a * np.sin(x2[:, 0]) * np.sin(x3[:, 0]) * np.sin(x4[:, 0])
    assert np.abs(printed_k1x - corrected[:, 0, 0]).max() > 1.0


def test_erratum_e1_corrected_tip_offsets_map_onto_the_platform_corners():
    b, n = 75.0, 0.0
    offsets = np.array([[0, n, b], [0.866 * b, n, -0.5 * b], [-0.866 * b, n, -0.5 * b]])  # L, M, R corrected
    mapped = np.column_stack([offsets[:, 2], offsets[:, 1], -offsets[:, 0]])  # x_P = z_7, y_P = y_7, z_P = -x_7
    expected = STAND_IN.platform_corners_mm[[1, 0, 2]] * -1  # corner-to-tip is minus tip-to-corner
    np.testing.assert_allclose(mapped, expected, atol=0.01)
    printed_r = np.array([0.866 * b, n, -0.5 * b])  # Eq. (6) as printed repeats leg L's offset
    assert np.allclose(printed_r, offsets[1])


def test_erratum_e11_corrected_lagrange_multiplier_satisfies_the_acceleration_constraint():
    rng = np.random.default_rng(21)
    size, constraints = 21, 3
    root = rng.normal(size=(size, size))
    mass = root @ root.T + size * np.eye(size)
    coriolis, gravity, torque = rng.normal(size=(size, size)), rng.normal(size=size), rng.normal(size=size)
    psi, psi_dot, q_dot = (
        rng.normal(size=(constraints, size)),
        rng.normal(size=(constraints, size)),
        rng.normal(size=size),
    )
    inverse = np.linalg.inv(mass)
    rhs = torque - coriolis @ q_dot - gravity
    corrected = np.linalg.solve(psi @ inverse @ psi.T, psi_dot @ q_dot + psi @ inverse @ rhs)
    printed = -np.linalg.solve(psi @ inverse @ psi.T, psi_dot @ np.ones(size) + psi_dot @ inverse @ rhs)
    for multiplier, ok in ((corrected, True), (printed, False)):
        q_ddot = inverse @ (rhs - psi.T @ multiplier)
        assert bool(np.abs(psi @ q_ddot + psi_dot @ q_dot).max() < 1e-10) is ok


# --- inverse kinematics -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("pose", "plus", "minus"),
    [
        (HOME, [702.211936500, 991.120186132, 832.115747068], [367.884252932, 208.879813868, 497.788063500]),
        (T1, [786.485461661, 1050.695470943, 1001.494762965], [278.873026383, 159.768000119, 322.683277930]),
    ],
    ids=["TV-2 home", "TV-3 T1"],
)
def test_slider_positions_on_both_branches(pose, plus, minus):
    np.testing.assert_allclose(inverse_kinematics(pose, branch=(1, 1, 1)).sliders_mm[0], plus, atol=1e-6)
    np.testing.assert_allclose(inverse_kinematics(pose, branch=(-1, -1, -1)).sliders_mm[0], minus, atol=1e-6)


def test_tv3_link_directions_conventions_and_margin():
    ik = inverse_kinematics(T1)
    np.testing.assert_allclose(
        ik.corners_mm[0],
        [
            [483.055182, 149.479649, -532.679244],
            [375.467399, 143.479242, -605.231736],
            [491.477419, 157.041109, -662.089020],
        ],
        atol=TOL_MM,
    )
    np.testing.assert_allclose(
        ik.link_dir[0],
        [
            [0.805091970, 0.415799415, 0.423010363],
            [0.625778998, 0.239132071, 0.742439559],
            [0.819129032, 0.095068515, 0.565676238],
        ],
        atol=1e-9,
    )
    np.testing.assert_allclose(ik.revolute_deg[0], [-27.718275, -45, -34.628282], atol=TOL_DEG)
    np.testing.assert_allclose(
        ik.universal_deg[0], [[0, 24.569670], [19.032488, 14.652766], [0, 5.455263]], atol=TOL_DEG
    )
    assert ik.ik_margin[0] == pytest.approx(0.423010, abs=1e-6)
    balanced = inverse_kinematics(T1, revolute_convention="balanced")
    np.testing.assert_allclose(balanced.revolute_deg[0], [-24.738558, -38.554125, -31.299557], atol=TOL_DEG)
    np.testing.assert_allclose(
        balanced.universal_deg[0], [[6.486586, 24.738558], [38.554125, 17.805564], [31.299557, 6.388020]], atol=TOL_DEG
    )
    zero = inverse_kinematics(T1, revolute_convention="x3_zero")
    np.testing.assert_allclose(zero.revolute_deg[0], [-27.718275, -49.873512, -34.628282], atol=TOL_DEG)
    np.testing.assert_allclose(zero.universal_deg[0, :, 1], [24.569670, 13.835320, 5.455263], atol=TOL_DEG)
    mirrored = inverse_kinematics(T1, branch=(-1, -1, -1))
    np.testing.assert_allclose(mirrored.revolute_deg, -ik.revolute_deg, atol=1e-9)
    np.testing.assert_allclose(mirrored.universal_deg[..., 0], -ik.universal_deg[..., 0], atol=1e-9)
    np.testing.assert_allclose(mirrored.universal_deg[..., 1], ik.universal_deg[..., 1], atol=1e-9)


def test_tv2_home_pose_conventions():
    ik = inverse_kinematics(HOME)
    np.testing.assert_allclose(ik.revolute_deg[0], [-16.412961, -40.682512, -16.412961], atol=TOL_DEG)
    np.testing.assert_allclose(ik.universal_deg[0], [[0, 9.594068], [0, 0], [0, -9.594068]], atol=TOL_DEG)
    balanced = inverse_kinematics(HOME, revolute_convention="balanced")
    np.testing.assert_allclose(balanced.revolute_deg[0], [-13.997936, -40.682512, -13.997936], atol=TOL_DEG)
    np.testing.assert_allclose(
        balanced.universal_deg[0], [[13.997936, 9.890595], [0, 0], [-13.997936, -9.890595]], atol=TOL_DEG
    )


def test_tv4_failures_report_reasons_and_stay_finite():
    ik = inverse_kinematics([[700.0, 0, -600, 0, 0, 0], [300.0, 0, -600, 0, 0, 0]])
    assert ik.reason.tolist() == ["out_of_reach (leg 1)", "revolute_range (leg 1)"]
    assert ik.leg_reason.tolist() == [["out_of_reach"] * 3, ["revolute_range"] * 3]
    for field in dataclasses.fields(ik):
        value = getattr(ik, field.name)
        if value.dtype != object:
            assert np.all(np.isfinite(value)), field.name
    np.testing.assert_allclose(ik.sliders_mm[1], [1020.942887856, 1156.214886532, 1150.846698423], atol=1e-6)
    minus = inverse_kinematics([300.0, 0, -600, 0, 0, 0], branch=(-1, -1, -1)).sliders_mm[0]
    np.testing.assert_allclose(minus, [49.153301577, 43.785113468, 179.057112144], atol=1e-6)


def test_slider_stroke_is_reported():
    ik = inverse_kinematics([530.0, 0.0, 100.0, 0, 0, 0], branch=(-1, -1, -1))
    assert ik.reason[0] == "slider_stroke (leg 1)"


def test_malformed_input_raises_naming_the_field():
    with pytest.raises(MotionInputError, match=r"pose has shape \(5,\), expected \(N, 6\)"):
        inverse_kinematics([1, 2, 3, 4, 5])
    with pytest.raises(MotionInputError, match="branch = "):
        inverse_kinematics(T1, branch=(1, 0, 1))
    with pytest.raises(MotionInputError, match="revolute_convention = 'best'"):
        inverse_kinematics(T1, revolute_convention="best")
    with pytest.raises(MotionInputError, match="needs fixed_revolute_deg"):
        inverse_kinematics(T1, revolute_convention="fixed")


# --- redundancy and mobility --------------------------------------------------------------------------------------


def test_tv5_revolute_is_redundant_same_corner_for_any_x2():
    u = inverse_kinematics(T1).link_dir[0, 0]
    expected = {-20: (16.370274, 25.681493), 0: (45.492539, 36.380862), 20: (58.285565, 52.275819)}
    for x2_deg, (x3_deg, x4_deg) in expected.items():
        x3, x4 = universal_from_revolute(u, np.radians(x2_deg))
        np.testing.assert_allclose(np.degrees([x3, x4]), [x3_deg, x4_deg], atol=TOL_DEG)


def test_tv6_two_poses_with_identical_actuator_readings():
    pose_b = [455.0, 152.345624742, -607.743170732, 3.0, -4.0, -1.575812711]
    locked = [-27.718275, -45.0, -34.628282]
    a = inverse_kinematics(T1, revolute_convention="fixed", fixed_revolute_deg=locked)
    b = inverse_kinematics(pose_b, revolute_convention="fixed", fixed_revolute_deg=locked)
    np.testing.assert_allclose(b.sliders_mm, a.sliders_mm, atol=1e-8)
    np.testing.assert_allclose(
        b.universal_deg[0],
        np.column_stack([[-2.089857, 14.755022, -9.888117], [24.436257, 15.433153, 5.299168]]),
        atol=TOL_DEG,
    )
    np.testing.assert_allclose(
        b.corners_mm[0],
        [
            [487.778129, 148.043290, -540.422415],
            [380.210991, 154.403075, -612.974906],
            [497.010880, 154.590509, -669.832191],
        ],
        atol=TOL_MM,
    )
    # So the slider readings are only a consistency check of a measured pose, never an FK.
    np.testing.assert_allclose(
        actuator_residual_mm([T1, pose_b], np.vstack([a.sliders_mm, a.sliders_mm])), 0.0, atol=1e-8
    )
    assert np.abs(actuator_residual_mm([460.0, 150, -600, 3, -4, 5], a.sliders_mm)).max() > 1.0


def test_tv8_locked_closure_has_a_three_dimensional_platform_null_space():
    ik = inverse_kinematics(T1)
    sliders, locked_x2 = ik.sliders_mm[0], np.radians(ik.revolute_deg[0])

    def closure(unknowns):  # (x3, x4) x 3 and the pose; sliders and x2 locked
        x3, x4 = unknowns[:3], unknowns[3:6]
        pose = np.concatenate([unknowns[6:9], np.degrees(unknowns[9:])])
        d = np.array([0.0, 0, -1])
        u = np.stack(
            [
                np.cos(locked_x2) * np.cos(x4) + np.sin(locked_x2) * np.sin(x3) * np.sin(x4),
                np.cos(x3) * np.sin(x4),
                np.cos(locked_x2) * np.sin(x3) * np.sin(x4) - np.sin(locked_x2) * np.cos(x4),
            ],
            axis=-1,
        )
        from_legs = STAND_IN.rail_offsets_mm + sliders[:, None] * d + 600.0 * u
        return (from_legs - corners_mm(pose[None])[0][0]).ravel()

    start = np.concatenate(
        [np.radians(ik.universal_deg[0, :, 0]), np.radians(ik.universal_deg[0, :, 1]), T1[:3], np.radians(T1[3:])]
    )
    step = 1e-6
    jac = np.column_stack([(closure(start + step * e) - closure(start - step * e)) / (2 * step) for e in np.eye(12)])
    singular = np.linalg.svd(jac, compute_uv=False)
    assert np.sum(singular > 1e-8 * singular[0]) == 9  # rank 9, null space 3
    null = np.linalg.svd(jac)[2][9:]
    assert np.linalg.matrix_rank(null[:, 6:], tol=1e-6) == 3  # all three are platform motions


# --- forward kinematics -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("convention", ["clip", "x3_zero", "balanced", "x2_zero"])
@pytest.mark.parametrize("branch", [(1, 1, 1), (-1, -1, -1), (1, -1, 1), (-1, 1, 1)])
def test_round_trip_ik_per_leg_fk_pose_from_corners(convention, branch):
    poses = random_reachable_poses(40, seed=8)
    ik = inverse_kinematics(poses, branch=branch, revolute_convention=convention)
    for method in ("kabsch", "closed_form"):
        fit = forward_kinematics(ik.sliders_mm, ik.revolute_deg, ik.universal_deg, method=method)
        np.testing.assert_allclose(fit.pose[:, :3], poses[:, :3], atol=1e-9)
        np.testing.assert_allclose(fit.pose[:, 3:], poses[:, 3:], atol=1e-10)
        assert fit.residual_mm.max() < 1e-9


def test_tv7_kabsch_fit_of_a_perturbed_corner():
    corners = corners_mm(np.array([T1]))[0].copy()
    corners[0, 0, 0] += 0.3
    fit = pose_from_corners(corners)
    np.testing.assert_allclose(fit.pose[0], [450.1, 150, -600, 3.012218, -3.931548, 4.996666], atol=1e-6)
    assert fit.residual_mm[0] == pytest.approx(0.108927, abs=1e-6)


def test_tip_offset_round_trip():
    geometry = dataclasses.replace(STAND_IN, tip_offset_mm=40.0)
    poses = random_reachable_poses(10, seed=9)
    ik = inverse_kinematics(poses, geometry)
    fit = forward_kinematics(ik.sliders_mm, ik.revolute_deg, ik.universal_deg, geometry)
    np.testing.assert_allclose(fit.pose, poses, atol=1e-9)


# --- Jacobian and singularity --------------------------------------------------------------------------------------


def test_tv3_jacobian_rows_both_forms_and_branches():
    np.testing.assert_allclose(
        slider_jacobian(T1).matrix[0],
        [
            [-1.903244, -0.982953, -1, 55.676342, -100.523591, -33.482054],
            [-0.842869, -0.322090, -1, 0, -70.277553, 18.510035],
            [-1.448053, -0.168062, -1, -5.718897, 132.408759, 3.225131],
        ],
        atol=1e-6,
    )
    np.testing.assert_allclose(
        slider_jacobian(T1, form="twist").matrix[0],
        [
            [-1.903244, -0.982953, -1, 66.693508, -95.072649, -33.482054],
            [-0.842869, -0.322090, -1, 4.835670, -70.122936, 18.510035],
            [-1.448053, -0.168062, -1, -17.475896, 131.385596, 3.225131],
        ],
        atol=1e-6,
    )
    np.testing.assert_allclose(
        slider_jacobian(T1, branch=(-1, -1, -1)).matrix[0],
        [
            [1.903244, 0.982953, -1, -48.894263, 166.291681, 33.482054],
            [0.842869, 0.322090, -1, 0, -79.357054, -18.510035],
            [1.448053, 0.168062, -1, -1.063182, -48.542242, -3.225131],
        ],
        atol=1e-6,
    )
    np.testing.assert_allclose(slider_jacobian(T1).line_singular_values[0], [1.695503, 0.298377, 0.259257], atol=1e-6)
    np.testing.assert_allclose(
        slider_jacobian(HOME).matrix[0],
        [
            [-3.394873, -0.598215, -1, 38.855236, -183.003464, -22.433081],
            [-1.163325, 0, -1, 0, -75, 0],
            [-3.394873, 0.598215, -1, 38.855236, 258.003464, 22.433081],
        ],
        atol=1e-6,
    )


@pytest.mark.parametrize("branch", [(1, 1, 1), (-1, -1, -1)])
def test_euler_jacobian_matches_central_differences(branch):
    poses = random_reachable_poses(20, seed=12)
    jac = slider_jacobian(poses, branch=branch).matrix
    step = np.array([1e-4] * 3 + [np.degrees(1e-6)] * 3)  # mm, and 1e-6 rad in degrees
    numeric = np.stack(
        [
            (
                inverse_kinematics(poses + h * e, branch=branch).sliders_mm
                - inverse_kinematics(poses - h * e, branch=branch).sliders_mm
            )
            / (2 * (h if k < 3 else np.radians(h)))
            for k, (h, e) in enumerate(zip(step, np.eye(6)))
        ],
        axis=2,
    )
    assert np.abs(jac - numeric).max() / np.abs(numeric).max() < 1e-6
    np.testing.assert_allclose(jac[:, :, 2], -1.0, atol=1e-12)
    np.testing.assert_allclose(jac[:, 1, 3], 0.0, atol=1e-9)  # corner 2 on the body x axis


def test_twist_jacobian_matches_finite_rotations_about_base_axes():
    poses = random_reachable_poses(10, seed=13)
    jac = slider_jacobian(poses, form="twist").matrix
    rotations = rotation_matrix(poses[:, 3:])
    h = 1e-6
    for axis in range(3):
        moved = []
        for sign in (1, -1):
            rotvec = np.zeros(3)
            rotvec[axis] = sign * h
            small = rotation_matrix(np.degrees(rotvec)[None])[0]  # exact to O(h^2) for one axis
            turned = np.column_stack([poses[:, :3], euler_deg_from_matrix(small @ rotations)])
            moved.append(inverse_kinematics(turned).sliders_mm)
        numeric = (moved[0] - moved[1]) / (2 * h)
        assert np.abs(jac[:, :, 3 + axis] - numeric).max() / np.abs(jac).max() < 1e-6


def test_ik_margin_vanishes_at_the_reach_boundary_where_branches_merge():
    margins, gaps = [], []
    for x in (520.0, 540.0, 550.0, 553.0, 554.0):  # leg 1 loses reach at x = 554.1 mm
        pose = [x, 0.0, -600.0, 0, 0, 0]
        plus, minus = inverse_kinematics(pose), inverse_kinematics(pose, branch=(-1, -1, -1))
        margins.append(plus.ik_margin[0])
        gaps.append(np.abs(plus.sliders_mm - minus.sliders_mm).min())
    assert np.all(np.diff(margins) < 0) and margins[-1] < 0.05
    assert np.all(np.diff(gaps) < 0)


# --- existence test -----------------------------------------------------------------------------------------------


def test_existence_test_agrees_with_brute_force_over_x2():
    rng = np.random.default_rng(17)
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u = u[np.abs(u[:, 1]) > 0.02]  # avoid directions whose feasible x2 interval is narrower than the grid
    limit = np.radians(45)
    grid = np.radians(np.arange(-45, 45.0001, 0.01))
    x3, x4 = universal_from_revolute(u[:, None, :], grid[None, :])
    brute = ((np.abs(x3) <= limit + 1e-9) & (np.abs(x4) <= limit + 1e-9)).any(axis=1)
    margin = existence_margin(u, limit, limit)
    decided = np.abs(margin) > np.radians(0.02)
    assert np.array_equal((margin >= 0)[decided], brute[decided])
    assert brute.sum() > 20 and (~brute).sum() > 20


# --- workspace ----------------------------------------------------------------------------------------------------


def test_tv10_quadrature_volume_matches_reference():
    assert workspace_volume_quadrature(cells=1200) / 1e9 == pytest.approx(0.15769, abs=2e-5)
    assert workspace_volume_quadrature(cells=600, criterion="x3_zero") / 1e9 == pytest.approx(0.01930, abs=1e-4)


def test_monte_carlo_volume_agrees_with_quadrature_within_4_se_and_stays_off_the_box():
    estimate = workspace_volume(400_000, seed=1)
    assert abs(estimate.volume_mm3 / 1e9 - 0.15765) < 4 * estimate.standard_error_mm3 / 1e9
    poses, ok = workspace_samples(200_000, seed=2)
    accepted = poses[ok, :3]
    box = np.array([[150.0, 650.0], [-350.0, 350.0], [-1900.0, 700.0]])
    assert np.all(accepted > box[:, 0] + 5) and np.all(accepted < box[:, 1] - 5)


# --- trajectory ---------------------------------------------------------------------------------------------------


def test_trajectory_boundary_values_and_stated_angles():
    trajectory = paper_trajectory()
    assert len(trajectory.t_s) == 101
    np.testing.assert_allclose(trajectory.pose[0, :3], [40, 580, 360])
    np.testing.assert_allclose(trajectory.pose[-1, :3], [-60, 480, 640], atol=1e-9)
    np.testing.assert_allclose(trajectory.rate[[0, -1], :3], 0.0, atol=1e-12)
    at_1, at_4 = np.radians(paper_trajectory([1.0, 4.0]).pose[:, 3:])
    np.testing.assert_allclose(at_1, [0.5, 0.4236, 0.747], atol=5e-4)
    np.testing.assert_allclose(at_4, [-0.5, -0.3078, 0.747], atol=5e-4)


def test_trajectory_reference_samples_paper_frame():
    table = {  # reference §8.5: t -> (P, angles in rad)
        2.0: ([29.6, 569.6, 389.12], [0.309017, 0.497972, -0.461645]),
        2.5: ([24.375, 564.375, 403.75], [0, 0.370240, -0.785398]),
        5.0: ([-10, 530, 500], [0, -0.523599, 0]),
        7.5: ([-44.375, 495.625, 596.25], [0, 0.370240, 0.785398]),
    }
    trajectory = paper_trajectory(list(table))
    for row, (position, angles) in enumerate(table.values()):
        np.testing.assert_allclose(trajectory.pose[row, :3], position, atol=1e-9)
        np.testing.assert_allclose(np.radians(trajectory.pose[row, 3:]), angles, atol=1e-6)
    rate = paper_trajectory([5.0]).rate[0]
    np.testing.assert_allclose(rate[:3], [-15, -15, 42], atol=1e-9)
    np.testing.assert_allclose(np.radians(rate[3:]), [0.660653, 0, -1.480441], atol=1e-6)


def test_trajectory_in_o2_slider_table_and_rates():
    times = [0, 1, 2.5, 4, 5, 7.5, 10]
    expected = [
        [633.368831, 788.525362, 658.711142],
        [623.032609, 709.277401, 754.720819],
        [609.032991, 720.222459, 674.448295],
        [621.469128, 684.191873, 538.115374],
        [567.492938, 696.023430, 476.076537],
        [494.722042, 500.785923, 516.430226],
        [433.104883, 531.354431, 421.420706],
    ]
    trajectory = paper_trajectory(times, origin_mm=STAND_IN_ORIGIN_MM)
    ik = inverse_kinematics(trajectory.pose)
    np.testing.assert_allclose(ik.sliders_mm, expected, atol=1e-6)
    full = inverse_kinematics(paper_trajectory(origin_mm=STAND_IN_ORIGIN_MM).pose)
    assert full.reachable.all() and full.ik_margin.min() == pytest.approx(0.368896, abs=1e-6)
    at_5 = paper_trajectory([5.0], origin_mm=STAND_IN_ORIGIN_MM)
    jac = slider_jacobian(at_5.pose).matrix[0]
    rates = np.concatenate([at_5.rate[0, :3], np.radians(at_5.rate[0, 3:])])
    np.testing.assert_allclose(jac @ rates, [-43.175556, 5.802975, -102.073872], atol=1e-5)


@pytest.mark.parametrize(
    "module", [motion.prus3.kinematics, motion.prus3.jacobian, motion.prus3.trajectory], ids=lambda m: m.__name__
)
def test_docstring_examples(module):
    failures, tried = run_doctests(module)
    assert tried > 0 and failures == 0
