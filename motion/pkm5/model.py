"""The 5-DOF PKM as a :class:`motion.model.RobotModel`: pose (x, y, z mm, alpha, beta deg), joints L1..L6 (mm)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from motion.model import JointSpec, ModelFK, ModelIK
from motion.pkm5.fk import forward_kinematics
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry
from motion.pkm5.ik import as_poses, inverse_kinematics
from motion.pkm5.jacobian import jacobian
from motion.pkm5.workspace import WORKSPACE_KINDS, _draw, feasible

__all__ = ["Pkm5Model", "MODEL"]

_DEG_COLS = slice(3, 5)


def _to_radians(pose_deg: ArrayLike) -> np.ndarray:
    poses = as_poses(pose_deg, "pose").copy()
    poses[:, _DEG_COLS] = np.radians(poses[:, _DEG_COLS])
    return poses


@dataclass(frozen=True)
class Pkm5Model:
    """PKM kinematics behind the common interface; FK is the least-squares fit over all six legs.

    The Jacobian's alpha and beta columns are meaningful only inside a pose's own mode (translation poses: both;
    alpha poses: alpha; beta poses: beta), since compound rotation is not modelled.
    """

    geometry: Geometry = DEFAULT_GEOMETRY
    name: str = "pkm5"
    pose_fields: tuple[str, ...] = ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg")
    joints: tuple[JointSpec, ...] = field(init=False)
    jacobian_joints: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        g = self.geometry
        specs = tuple(JointSpec(f"L{i + 1}_mm", "mm", g.leg_min_mm[i], g.leg_max_mm[i]) for i in range(6))
        object.__setattr__(self, "joints", specs)
        object.__setattr__(self, "jacobian_joints", tuple(spec.name for spec in specs))

    def ik(self, pose: ArrayLike) -> ModelIK:
        result = inverse_kinematics(_to_radians(pose), self.geometry)
        reasons = np.array([text or None for text in result.reasons], dtype=object)
        return ModelIK(joints=result.lengths_mm, reachable=result.reachable, reason=reasons)

    def fk(self, joints: ArrayLike) -> ModelFK:
        result = forward_kinematics(joints, self.geometry)
        pose = result.pose.copy()
        pose[:, _DEG_COLS] = np.degrees(pose[:, _DEG_COLS])
        return ModelFK(pose=pose, residual_mm=result.residual_mm, ok=result.converged)

    def jacobian(self, pose: ArrayLike) -> np.ndarray:
        """dL/d(x, y, z, alpha, beta) in mm/mm and mm/deg, (N, 6, 5)."""
        return jacobian(_to_radians(pose), self.geometry) * np.array([1, 1, 1, np.pi / 180, np.pi / 180])

    def workspace_samples(self, count: int, *, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
        """Uniform poses over the three sampling boxes of 000 Tables 6-1 to 6-3 (a third each), with reachability."""
        rng = np.random.default_rng(seed)
        kinds = list(WORKSPACE_KINDS.values())
        choice = rng.integers(0, len(kinds), count)
        poses = np.zeros((count, 5))
        for i, kind in enumerate(kinds):
            rows = np.flatnonzero(choice == i)
            poses[rows] = _draw(kind, rng, rows.size)
        reachable = feasible(poses, self.geometry)
        poses[:, _DEG_COLS] = np.degrees(poses[:, _DEG_COLS])
        return poses, reachable


MODEL = Pkm5Model()
