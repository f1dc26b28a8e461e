"""IK of the 5-DOF PKM against the dissertation's tables (shared/reference/pkm5.md §6)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pkm5_tables import LENGTHS, fk_table, ik_table

from motion import pkm5
from motion.errors import MotionInputError
from motion.pkm5 import Failure

# pkm5.md §6.1: IK at printed poses, to 1e-6 mm and 1e-4 deg.
ANCHORS = [
    ((87.82, 0, 295.83, 0, 0), [183.998750] * 4 + [191.996981] * 2, [68.1914] * 4 + [90.0] * 2),
    ((186.11, 0, 312.8, 0, 0), [244.000527] * 4 + [218.633989] * 2, [50.3243] * 4 + [90.0] * 2),
    (
        (126.98, -120.41, 290.84, 0, 0),
        [184.002220] * 2 + [244.005456] * 2 + [221.884678] * 2,
        [64.3286] * 2 + [42.8168] * 2 + [122.8655] * 2,
    ),
    (
        (111.31, -95.52, 312.28, 17.6, 0),
        [187.722605, 187.510298, 252.827358, 266.121991, 214.596012, 238.316768],
        [70.4963, 70.5938, 55.5779, 52.4597, 113.8715, 112.3411],
    ),
    (
        (111.31, -136.1, 274.14, -26.47, 0),
        [174.758169, 169.212237, 236.159787, 204.702678, 236.623689, 214.967658],
        [66.1088, 68.3239, 30.8104, 31.6921, 126.8582, 134.3691],
    ),
    (
        (133.68, -99.6, 280.91, 0, 15.38),
        [189.955978, 201.924662, 234.534580, 247.030085, 194.180705, 194.180705],
        [66.2541, 60.8287, 46.3985, 44.1845, 120.8588, 120.8588],
    ),
    (
        (177.17, -94.51, 280.85, 0, -6.44),
        [199.951895, 192.067831, 250.318173, 243.598587, 211.808937, 211.808937],
        [48.2219, 49.6439, 36.8418, 37.4279, 116.5004, 116.5004],
    ),
    (
        (111.36, -53.27, 311.04, 20, 0),
        [185.450719, 180.559391, 237.399914, 249.393509, 198.466404, 226.225768],
        [66.9907, 68.8948, 61.6179, 57.9251, 102.5610, 102.2466],
    ),
]


def pose_rad(x, y, z, alpha_deg=0.0, beta_deg=0.0):
    return np.array([[x, y, z, np.radians(alpha_deg), np.radians(beta_deg)]])


@pytest.mark.parametrize("pose, lengths, tilts", ANCHORS)
def test_high_precision_anchors(pose, lengths, tilts):
    result = pkm5.inverse_kinematics(pose_rad(*pose), check_limits=False)
    np.testing.assert_allclose(result.lengths_mm[0], lengths, atol=1e-6)
    np.testing.assert_allclose(result.tilt_deg[0], tilts, atol=1e-4)


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_tables_a8_a10_lengths(mode):
    """150 IK simulation poses (Tables A.8-A.10) against the [reconstructed] length columns rounded to 0.01 mm.
    The documents only print "largest error 0 or 0.01 mm" vs CAD; the CAD lengths themselves are not printed."""
    df, poses = ik_table(mode)
    result = pkm5.inverse_kinematics(poses, check_limits=False)
    assert np.abs(result.lengths_mm - df[LENGTHS].to_numpy()).max() <= 0.005 + 1e-9
    assert result.lengths_mm.shape == (50, 6)


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_tables_a15_a17_leg_angles_match_cad(mode):
    """theta_1, theta_3 of the 75 CAD poses within 0.01 deg; theta_5 against CAD only in alpha rows (the CAD angle of
    leg 5 differs by definition in translation/beta rows, up to 1.13 deg; there compare the converged value)."""
    df, poses = fk_table(mode)
    tilt = pkm5.inverse_kinematics(poses, check_limits=False).tilt_deg
    assert np.abs(tilt[:, 0] - df.true_theta1_deg).max() <= 0.01
    assert np.abs(tilt[:, 2] - df.true_theta3_deg).max() <= 0.01
    if mode == "alpha":
        assert np.abs(tilt[:, 4] - df.true_theta5_deg).max() <= 0.01
    else:
        assert np.abs(tilt[:, 4] - df.converged_theta5_deg).max() <= 0.07
        assert np.abs(tilt[:, 4] - df.true_theta5_deg).max() > 0.5  # the definitional difference is real


@pytest.mark.parametrize("mode", ["translation", "alpha", "beta"])
def test_fk_table_lengths(mode):
    df, poses = fk_table(mode)
    lengths = pkm5.inverse_kinematics(poses, check_limits=False).lengths_mm
    assert np.abs(lengths - df[LENGTHS].to_numpy()).max() <= 0.005 + 1e-9


def test_bracket_constants_of_the_nr_scripts():
    """000 App. B.3.2: DC1 = (45.7182, 36.8625), DC3 = (38.6652, 44.2041), DC5 = (18.6792, 19.5535) at the pose the
    script solves, (111.297, -23.680, 312.354), alpha = -9.9985 deg (pkm5.md §4.4), within 0.006."""
    brackets = pkm5.bracket_vectors(pose_rad(111.297, -23.680, 312.354, -9.9985))
    np.testing.assert_allclose(brackets["cd1"][0], (45.7182, 36.8625), atol=0.006)
    np.testing.assert_allclose(brackets["cd3"][0], (38.6652, 44.2041), atol=0.006)
    np.testing.assert_allclose(brackets["cd5"][0], (18.6792, 19.5535), atol=0.006)


def test_design_brackets_in_translation():
    brackets = pkm5.bracket_vectors(pose_rad(150, 20, 300))
    np.testing.assert_array_equal(brackets["cd1"][0], (43, 40))
    np.testing.assert_array_equal(brackets["cd2"][0], (63, -40))


@pytest.mark.parametrize(
    "bound, pose, active",
    [
        # pkm5.md §5.4: extremes of Table 6-1 and the constraints active there
        ("x max", (235.13, 0, 262.08), {"L14": 244, "L56": 192, "phi14": 34.18}),
        ("x min", (46.50, 0, 305.45), {"L14": 184, "phi14": 78.73}),
        ("z max", (97.59, 0, 356.68), {"L14": 244, "L56": 252}),
    ],
)
def test_table_6_1_extremes_are_limit_corners(bound, pose, active):
    result = pkm5.inverse_kinematics(pose_rad(*pose), check_limits=False)
    checks = {"L14": result.lengths_mm[0, :4], "L56": result.lengths_mm[0, 4:], "phi14": result.tilt_deg[0, :4]}
    for name, value in active.items():
        np.testing.assert_allclose(checks[name], value, atol=0.02, err_msg=f"{bound}: {name}")


def test_limits_and_reasons():
    result = pkm5.inverse_kinematics(
        np.vstack(
            [
                pose_rad(150, 0, 300),  # centre of the workspace
                pose_rad(300, 0, 300),  # far outside
                pose_rad(111.31, 0, 300, 10, 5),  # compound rotation
                pose_rad(130, 0, 300, 10),  # alpha off its plane
                pose_rad(111.31, 0, 300, 40),  # alpha beyond 35.73 deg
            ]
        )
    )
    assert result.reachable.tolist() == [True, False, False, False, False]
    assert result.reason(0) is None
    assert Failure.LEG_LENGTH in Failure(int(result.failure[1]))
    assert "leg 1 length 316.729 mm outside (184, 244) mm" in result.reason(1)
    assert Failure.MODE in Failure(int(result.failure[2]))
    assert "not modelled" in result.reason(2)
    assert Failure(int(result.failure[3])) & Failure.ALPHA_PLANE
    assert "x = 130.0000 mm but alpha poses need x = 111.31 mm" in result.reason(3)
    assert Failure(int(result.failure[4])) & Failure.ORIENTATION_RANGE
    assert list(result.reasons[:2]) == ["", result.reason(1)]


def test_tilt_of_leg_6_is_checked():
    """000 App. B.4 tests phi5 twice and never phi6 (pkm5.md §2.4); a roll that over-tilts leg 6 only is refused."""
    result = pkm5.inverse_kinematics(pose_rad(111.31, -136.1, 274.14, -26.47))
    assert not result.tilt_ok[0, 5]
    assert "leg 6 tilt 134.369 deg" in result.reason(0)


def test_full_retraction_just_outside_the_window():
    result = pkm5.inverse_kinematics(pose_rad(87.82, 0, 295.83))
    assert not result.reachable[0]
    assert result.length_ok[0].tolist() == [False] * 6


def test_bad_shape_is_a_clear_error():
    with pytest.raises(MotionInputError, match=r"shape \(3,\), expected \(N, 5\) or \(5,\)"):
        pkm5.inverse_kinematics([1, 2, 3])
    with pytest.raises(MotionInputError, match="NaN or infinity"):
        pkm5.inverse_kinematics([np.nan, 0, 300, 0, 0])


translations = st.tuples(st.floats(50, 230), st.floats(-130, 130), st.floats(265, 355))


@settings(max_examples=60, deadline=None)
@given(translations, st.floats(-0.6, 0.47), st.sampled_from(["translation", "alpha", "beta"]))
def test_invariants_and_mirror_symmetry(position, angle, mode):
    """L1 = L2, L3 = L4, L5 = L6 in translation; L5 = L6 in beta; mirror about the x-z plane (pkm5.md §3.7):
    IK(x, -y, z, -alpha, beta) swaps (L1, L2) <-> (L3, L4) and L5 <-> L6, and phi5 <-> 180 deg - phi6."""
    x, y, z = position
    alpha = angle if mode == "alpha" else 0.0
    beta = angle if mode == "beta" else 0.0
    result = pkm5.inverse_kinematics(np.array([[x, y, z, alpha, beta], [x, -y, z, -alpha, beta]]), check_limits=False)
    lengths, tilt = result.lengths_mm, result.tilt_deg
    if mode == "translation":
        np.testing.assert_allclose(lengths[0, [0, 2, 4]], lengths[0, [1, 3, 5]], rtol=0, atol=1e-9)
    if mode == "beta":
        assert abs(lengths[0, 4] - lengths[0, 5]) < 1e-9
    np.testing.assert_allclose(lengths[1], lengths[0, [2, 3, 0, 1, 5, 4]], atol=1e-9)
    np.testing.assert_allclose(tilt[1, :4], tilt[0, [2, 3, 0, 1]], atol=1e-9)
    np.testing.assert_allclose(tilt[1, 4], 180.0 - tilt[0, 5], atol=1e-9)


def test_steps_and_lengths():
    """000 App. C.2: 50 mm on actuator 1 is 8000 steps (0.00625 mm/step); App. B.2 firmware example
    {-5582, -5582, -5549, -5549, -9254, -9254} steps are |dL| = 34.8875, 34.68125, 28.91875 mm."""
    steps = pkm5.lengths_to_steps([[234, 184, 184, 184, 192, 192]])
    assert steps.tolist() == [[8000, 0, 0, 0, 0, 0]]
    stroke = pkm5.steps_to_lengths([[-5582, -5582, -5549, -5549, -9254, -9254]]) - np.array(
        pkm5.DEFAULT_GEOMETRY.leg_length_offset_mm
    )
    np.testing.assert_allclose(np.abs(stroke[0]), [34.8875] * 2 + [34.68125] * 2 + [28.91875] * 2, atol=1e-12)
    geometry = pkm5.DEFAULT_GEOMETRY.replace(microsteps=8, step_direction=(-1, 1, 1, 1, 1, -1))
    lengths = np.array([[200.0, 210.0, 220.0, 230.0, 240.0, 250.0]])
    np.testing.assert_allclose(pkm5.steps_to_lengths(pkm5.lengths_to_steps(lengths, geometry), geometry), lengths)


def test_geometry_validation():
    with pytest.raises(ValueError, match="step_direction"):
        pkm5.DEFAULT_GEOMETRY.replace(step_direction=(1, 1, 1, 1, 1, 0))
    with pytest.raises(ValueError, match="leg_min_mm"):
        pkm5.DEFAULT_GEOMETRY.replace(leg_min_mm=(184, 184))
