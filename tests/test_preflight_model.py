"""bench.protocols.kinematics: the pre-flight models on top of motion.model, against independent computations."""

from __future__ import annotations

import numpy as np
import pytest

from bench.errors import ConfigError
from bench.protocols.kinematics import PreflightModel, inverse_condition, robot_model
from bench.robot_kinds import robot_names
from motion import delta4, pkm5
from motion.model import column_conditioning, robot_models
from motion.pkm5.jacobian import mode_columns


def _samples(name: str, count: int = 600) -> np.ndarray:
    poses, reachable = robot_models()[name].workspace_samples(count, seed=11)
    rng = np.random.default_rng(4)
    return np.vstack(
        [poses[reachable][:100], poses[~reachable][:100], poses[:50] + rng.normal(0, 15, (50, poses.shape[1]))]
    )


def test_models_are_the_motion_models_with_their_fields():
    for name in robot_names():
        model = robot_model(name)
        assert isinstance(model, PreflightModel) and robot_model(name) is model
        assert model.kinematics is robot_models()[name]
        assert model.target_fields == model.kinematics.pose_fields
        assert len(model.home) == len(model.target_fields)
    with pytest.raises(ConfigError, match="--robot scara: expected one of pkm5, delta4"):
        robot_model("scara")


def test_pkm5_check_equals_motion_pkm5_ik_and_singularity_proximity():
    targets = _samples("pkm5")
    check = robot_model("pkm5").check(targets, 0.05)
    radians = targets.copy()
    radians[:, 3:] = np.radians(radians[:, 3:])
    ik = pkm5.inverse_kinematics(radians)
    proximity = pkm5.singularity_proximity(radians).inverse_condition
    np.testing.assert_array_equal(check.proximity, proximity)
    near = ik.reachable & (proximity < 0.05)
    assert near.any() and (ik.reachable & ~near).any() and (~ik.reachable).any()  # every outcome is exercised
    np.testing.assert_array_equal(check.reachable, ik.reachable & ~near)
    assert list(check.reason[~ik.reachable]) == list(ik.reasons[~ik.reachable])
    assert all(r.startswith("too close to a singularity (inverse condition") for r in check.reason[near])
    assert set(check.reason[check.reachable]) == {""}


def test_delta4_check_equals_the_servo_jacobian_conditioning():
    targets = _samples("delta4")
    check = robot_model("delta4").check(targets, 0.3)
    ik = delta4.inverse_kinematics(targets)
    singular = np.linalg.svd(np.nan_to_num(delta4.jacobian_deg_per_mm(targets)), compute_uv=False)
    np.testing.assert_allclose(check.proximity, singular[:, -1] / singular[:, 0], rtol=1e-12)
    assert list(check.reason[~ik.reachable]) == list(ik.reason[~ik.reachable])
    assert check.reachable.any() and not check.reachable[~ik.reachable].any()


def test_pkm5_move_time_is_the_longest_leg_in_whole_steps_at_200_steps_per_s():
    model = robot_model("pkm5")
    start = model.as_targets([model.home, (110, 0, 320)])
    end = model.as_targets([(110, 0, 320), (111.31, -20, 310, 10, 0)])

    def steps(targets):
        radians = targets.copy()
        radians[:, 3:] = np.radians(radians[:, 3:])
        return pkm5.lengths_to_steps(pkm5.inverse_kinematics(radians).lengths_mm)

    expected = np.abs(steps(end) - steps(start)).max(axis=1) / (200 * np.array([1.0, 0.5]))
    np.testing.assert_allclose(model.move_s(start, end, np.array([100.0, 50.0])), expected, atol=1 / 100)


def test_delta4_move_time_is_the_longest_servo_turn_at_300_deg_per_s():
    model = robot_model("delta4")
    start, end = np.array([[0.0, 0.0, -200.0]]), np.array([[30.0, -20.0, -230.0]])
    turn = np.abs(delta4.inverse_kinematics(end).servo_deg - delta4.inverse_kinematics(start).servo_deg).max()
    assert model.move_s(start, end, np.array([25.0]))[0] == pytest.approx(turn / 75.0)


def test_inverse_condition_restricted_columns_and_degenerate_jacobians():
    jac = np.array(
        [
            [[2.0, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 1e-9]],
            [[0.0, 0.0, 0.0]] * 3,
            [[np.nan, 1.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 1.0]],
        ]
    )
    columns = np.array([[True, True, False], [True, True, True], [True, True, True]])
    proximity = inverse_condition(jac, columns)
    assert proximity[0] == pytest.approx(0.25)  # the third column is not in this target's mode
    assert proximity[1] == 0.0
    # NaN taken as 0: singular values of [[0, 1, 0], [0, 4, 0], [0, 0, 1]] are sqrt(17), 1, 0
    assert proximity[2] == pytest.approx(0.0, abs=1e-12)
    assert inverse_condition(jac[:1], np.ones((1, 3), bool))[0] == pytest.approx(1e-9 / 2)


def test_column_conditioning_is_each_targets_own_svd_over_its_mode_columns():
    from doctests import run_doctests

    import motion.model

    rng = np.random.default_rng(7)
    jac = rng.normal(size=(40, 6, 5))
    columns = rng.random((40, 5)) < 0.7
    columns[:, 0] = True  # every mode moves in x
    sigma_min, inverse = column_conditioning(jac, columns)
    for i in range(len(jac)):  # one SVD per target, no grouping
        singular = np.linalg.svd(jac[i][:, columns[i]], compute_uv=False)
        assert sigma_min[i] == pytest.approx(singular[-1], rel=1e-12)
        assert inverse[i] == pytest.approx(singular[-1] / singular[0], rel=1e-12)
    # the pkm5's index and the pre-flight's are this one computation
    targets = robot_model("pkm5").as_targets(
        [(110, 0, 320), (111.31, -20, 310, 10, 0), (124.47, -90.11, 287.16, 0, 10)]
    )
    radians = targets.copy()
    radians[:, 3:] = np.radians(radians[:, 3:])
    np.testing.assert_array_equal(
        pkm5.singularity_proximity(radians).sigma_min,
        column_conditioning(
            pkm5.jacobian(radians) * np.array([1, 1, 1, np.pi / 180, np.pi / 180]), mode_columns(radians)
        )[0],
    )
    assert run_doctests(motion.model).failed == 0
