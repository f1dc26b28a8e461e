"""The PKM behind the common robot-model interface (motion.model), in mm and degrees."""

import numpy as np

from motion.model import RobotModel, robot_models


def test_pkm5_model_round_trip_and_jacobian():
    model = robot_models()["pkm5"]
    assert isinstance(model, RobotModel)
    poses, reachable = model.workspace_samples(3000, seed=5)
    poses = poses[reachable][:60]
    assert len(poses) == 60
    assert (poses[:, 3] != 0).any() and (poses[:, 4] != 0).any()
    ik = model.ik(poses)
    assert ik.joints.shape == (60, 6) and ik.reachable.all() and all(r is None for r in ik.reason)
    fk = model.fk(ik.joints)
    np.testing.assert_allclose(fk.pose, poses, atol=1e-8)
    assert fk.ok.all()
    # Jacobian in mm/mm and mm/deg against central differences, in each pose's own mode
    jac = model.jacobian(poses)
    h = 1e-5
    for col in range(5):
        step = np.zeros(5)
        step[col] = h
        numeric = (model.ik(poses + step).joints - model.ik(poses - step).joints) / (2 * h)
        in_mode = np.ones(len(poses), bool) if col < 3 else (poses[:, 7 - col] == 0)
        scale = np.abs(jac[in_mode, :, col]).max()
        assert np.abs(jac[in_mode, :, col] - numeric[in_mode]).max() / scale < 1e-6


def test_unreachable_pose_reason():
    ik = robot_models()["pkm5"].ik([[300, 0, 300, 0, 0]])
    assert not ik.reachable[0] and ik.reason[0].startswith("leg 1 length 316.729 mm")
