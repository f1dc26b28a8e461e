"""The common robot-model interface (motion.model) for delta4 and prus3: shapes, units, round trips."""

from __future__ import annotations

import numpy as np
import pytest

from motion.model import RobotModel, robot_models

MODELS = robot_models()


def test_models_are_listed_and_satisfy_the_protocol():
    assert {"delta4", "prus3"} <= set(MODELS)
    for model in MODELS.values():
        assert isinstance(model, RobotModel)
        assert all(field.endswith(("_mm", "_deg")) for field in model.pose_fields)
        assert all(spec.name.endswith(f"_{spec.unit}") and spec.low < spec.high for spec in model.joints)


@pytest.mark.parametrize("name", ["delta4", "prus3"])
def test_ik_fk_round_trip_and_jacobian_by_finite_differences(name):
    model = MODELS[name]
    poses, reachable = model.workspace_samples(4000, seed=3)
    poses = poses[reachable][:30]
    assert len(poses) == 30
    ik = model.ik(poses)
    assert ik.joints.shape == (30, len(model.joints)) and ik.reachable.all()
    low = np.array([spec.low for spec in model.joints])
    high = np.array([spec.high for spec in model.joints])
    assert np.all((ik.joints >= low - 1e-9) & (ik.joints <= high + 1e-9))
    fk = model.fk(ik.joints)
    np.testing.assert_allclose(fk.pose, poses, atol=1e-7)
    assert fk.ok.all() and fk.residual_mm.max() < 1e-7
    rows = [i for i, spec in enumerate(model.joints) if spec.name in model.jacobian_joints]
    jac = model.jacobian(poses)
    assert jac.shape == (30, len(rows), len(model.pose_fields))
    h = 1e-5
    numeric = np.stack(
        [
            (model.ik(poses + h * e).joints[:, rows] - model.ik(poses - h * e).joints[:, rows]) / (2 * h)
            for e in np.eye(len(model.pose_fields))
        ],
        axis=2,
    )
    assert np.abs(jac - numeric).max() / np.abs(numeric).max() < 1e-6
