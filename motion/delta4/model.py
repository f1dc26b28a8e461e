"""The delta-4 as a :class:`motion.model.RobotModel`: pose (x, y, z) mm, joints the four servo angles (deg)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from motion.delta4.geometry import NOMINAL, Geometry
from motion.delta4.kinematics import forward_kinematics, inverse_kinematics, jacobian_deg_per_mm
from motion.delta4.workspace import workspace_samples
from motion.model import JointSpec, ModelFK, ModelIK
from motion.sampling import as_rows

__all__ = ["Delta4Model", "MODEL"]


@dataclass(frozen=True)
class Delta4Model:
    """Delta-4 kinematics behind the common interface; FK is the least-squares fit over all four legs.

    ``geometry`` is the documented :class:`~motion.delta4.geometry.Geometry` or a calibrated one
    (:class:`motion.delta4.calibration.CalibratedGeometry`, a kinematic calibration in force): IK, Jacobian and
    workspace solve its legs, FK closes them (``residual_mm`` then NaN: the calibrated fit reports no residual).
    """

    geometry: Geometry = NOMINAL
    name: str = "delta4"
    pose_fields: tuple[str, ...] = ("x_mm", "y_mm", "z_mm")
    joints: tuple[JointSpec, ...] = field(init=False)
    jacobian_joints: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        low, high = self.geometry.servo_limits_deg
        specs = tuple(JointSpec(f"servo{i}_deg", "deg", low, high) for i in range(1, 5))
        object.__setattr__(self, "joints", specs)
        object.__setattr__(self, "jacobian_joints", tuple(spec.name for spec in specs))

    def ik(self, pose: ArrayLike) -> ModelIK:
        result = inverse_kinematics(pose, self.geometry)
        return ModelIK(joints=result.servo_deg, reachable=result.reachable, reason=result.reason)

    def fk(self, joints: ArrayLike) -> ModelFK:
        if not isinstance(self.geometry, Geometry):
            pose = self.geometry.attained_mm(as_rows(joints, 4, "joints"))
            return ModelFK(pose=pose, residual_mm=np.full(len(pose), np.nan), ok=np.all(np.isfinite(pose), axis=1))
        result = forward_kinematics(joints, self.geometry)
        return ModelFK(pose=result.pose_mm, residual_mm=result.residual_mm, ok=result.ok)

    def jacobian(self, pose: ArrayLike) -> np.ndarray:
        return jacobian_deg_per_mm(pose, self.geometry)

    def workspace_samples(self, count: int, *, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
        return workspace_samples(count, self.geometry, seed=seed)


MODEL = Delta4Model()
