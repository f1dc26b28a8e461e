"""A toy robot for tests/test_robot_kinds.py: a Cartesian gantry whose joints are its axes (x, y, z in mm, each
within +-100 mm), written as a new robot's author would, with nothing registered anywhere but its one record."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion.model import JointSpec, ModelFK, ModelIK
from motion.sampling import as_rows

LIMIT_MM = 100.0
#: Rated speed of every axis at 100 % (mm/s).
SPEED_MM_S = 50.0


@dataclass(frozen=True)
class GantryModel:
    name: str = "toy"
    pose_fields: tuple[str, ...] = ("x_mm", "y_mm", "z_mm")
    joints: tuple[JointSpec, ...] = tuple(JointSpec(f"{axis}_axis_mm", "mm", -LIMIT_MM, LIMIT_MM) for axis in "xyz")
    jacobian_joints: tuple[str, ...] = ("x_axis_mm", "y_axis_mm", "z_axis_mm")

    def ik(self, pose: object) -> ModelIK:
        rows = as_rows(pose, 3, "pose")
        inside = np.all(np.abs(rows) <= LIMIT_MM, axis=1)
        reason = np.array([None if ok else f"outside the +-{LIMIT_MM:g} mm travel" for ok in inside], dtype=object)
        return ModelIK(joints=rows.copy(), reachable=inside, reason=reason)

    def fk(self, joints: object) -> ModelFK:
        rows = as_rows(joints, 3, "joints")
        return ModelFK(pose=rows.copy(), residual_mm=np.zeros(len(rows)), ok=np.ones(len(rows), bool))

    def jacobian(self, pose: object) -> np.ndarray:
        return np.broadcast_to(np.eye(3), (len(as_rows(pose, 3, "pose")), 3, 3)).copy()

    def workspace_samples(self, count: int, *, seed: int | None = 0) -> tuple[np.ndarray, np.ndarray]:
        poses = np.random.default_rng(seed).uniform(-1.5 * LIMIT_MM, 1.5 * LIMIT_MM, (count, 3))
        return poses, np.all(np.abs(poses) <= LIMIT_MM, axis=1)


MODEL = GantryModel()


def home_pose() -> tuple[float, ...]:
    return (0.0, 0.0, 0.0)


def travel_s(kinematics: object, travel_mm: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
    """Axes move together at their rated speed: the longest travel sets the time."""
    return travel_mm.max(axis=1) / (SPEED_MM_S * velocity_pct / 100.0)
