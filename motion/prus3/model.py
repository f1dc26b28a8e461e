"""The 3-PRUS as a :class:`motion.model.RobotModel`.

Pose (x, y, z mm; alpha, beta, gamma deg). Joints: the three sliders (mm), the three actuated revolutes x2
(deg, by the ``clip`` convention), then the passive universal angles x3, x4 of each leg (deg): the FK needs
all twelve, because the six actuators leave three platform freedoms free. The Jacobian rows are the sliders
only: the revolutes do not move the platform (reference ``prus3.md`` §2, §6.4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from motion.model import JointSpec, ModelFK, ModelIK
from motion.prus3.geometry import STAND_IN, Geometry
from motion.prus3.jacobian import slider_jacobian
from motion.prus3.kinematics import forward_kinematics, inverse_kinematics
from motion.prus3.workspace import workspace_samples
from motion.sampling import as_rows

__all__ = ["Prus3Model", "MODEL"]


@dataclass(frozen=True)
class Prus3Model:
    """3-PRUS kinematics behind the common interface, on one slider branch per leg (default (+1, +1, +1))."""

    geometry: Geometry = STAND_IN
    branch: tuple[int, int, int] = (1, 1, 1)
    name: str = "prus3"
    pose_fields: tuple[str, ...] = ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg", "gamma_deg")
    joints: tuple[JointSpec, ...] = field(init=False)
    jacobian_joints: tuple[str, ...] = ("s1_mm", "s2_mm", "s3_mm")

    def __post_init__(self) -> None:
        low, high = self.geometry.stroke_mm
        limit, limit2 = self.geometry.revolute_limit_deg, self.geometry.actuated_limit_deg
        sliders = tuple(JointSpec(f"s{i}_mm", "mm", low, high) for i in range(1, 4))
        revolutes = tuple(JointSpec(f"x2_leg{i}_deg", "deg", -limit2, limit2) for i in range(1, 4))
        universal = tuple(
            JointSpec(f"{name}_leg{i}_deg", "deg", -limit, limit, actuated=False)
            for i in range(1, 4)
            for name in ("x3", "x4")
        )
        object.__setattr__(self, "joints", sliders + revolutes + universal)

    def ik(self, pose: ArrayLike) -> ModelIK:
        result = inverse_kinematics(pose, self.geometry, branch=self.branch)
        joints = np.concatenate([result.sliders_mm, result.revolute_deg, result.universal_deg.reshape(-1, 6)], axis=1)
        return ModelIK(joints=joints, reachable=result.reachable, reason=result.reason)

    def fk(self, joints: ArrayLike) -> ModelFK:
        values = as_rows(joints, 12, "joints")
        fit = forward_kinematics(values[:, :3], values[:, 3:6], values[:, 6:].reshape(-1, 3, 2), self.geometry)
        return ModelFK(pose=fit.pose, residual_mm=fit.residual_mm, ok=np.ones(len(values), dtype=bool))

    def jacobian(self, pose: ArrayLike) -> np.ndarray:
        matrix = slider_jacobian(pose, self.geometry, branch=self.branch).matrix.copy()
        matrix[:, :, 3:] *= math.pi / 180.0  # mm/rad -> mm/deg
        return matrix

    def workspace_samples(self, count: int, *, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
        poses, _ = workspace_samples(count, self.geometry, seed=seed)
        return poses, self.ik(poses).reachable  # on this model's branch, unlike the any-branch workspace


MODEL = Prus3Model()
