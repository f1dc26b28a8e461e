"""Robot models for pre-flight and time estimates: reachability, joint limits and singularity proximity from motion/.

Targets are rows of mm and degrees: ``(x_mm, y_mm, z_mm, alpha_deg, beta_deg)`` for the pkm5 (a 3-column row
means alpha = beta = 0) and ``(x_mm, y_mm, z_mm)`` for the delta4. Nothing here talks to hardware.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError

__all__ = ["ROBOT_MODELS", "RobotModel", "TargetCheck", "robot_model"]

#: Inverse condition number below which a target is refused as too close to a singularity. With the units of
#: motion.pkm5.singularity_proximity the cube poses lie near 0.17-0.20 and the documents' beta test poses (000 Table
#: A.13, physically visited) go down to 0.016, so the default refuses only what is closer than any documented pose.
DEFAULT_SINGULARITY_THRESHOLD = 0.01


@dataclass(frozen=True)
class TargetCheck:
    """Pre-flight of N targets: ``reachable`` (N,), ``reason`` (N,) ('' when fine), ``proximity`` (N,) in [0, 1]."""

    reachable: np.ndarray
    reason: np.ndarray
    proximity: np.ndarray


@dataclass(frozen=True)
class RobotModel:
    """What the protocols need from a robot's kinematics."""

    name: str
    target_fields: tuple[str, ...]
    home: tuple[float, ...]
    check: Callable[[np.ndarray, float], TargetCheck]
    move_s: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]

    def as_targets(self, targets) -> np.ndarray:
        """Targets as float (N, len(target_fields)), short pkm5 rows padded with zero angles."""
        rows = [tuple(t) + (0.0,) * (len(self.target_fields) - len(t)) for t in targets]
        array = np.asarray(rows, dtype=float).reshape(len(rows), len(self.target_fields))
        return array


def _pkm5_check(targets: np.ndarray, threshold: float) -> TargetCheck:
    from motion import pkm5

    poses = targets.copy()
    poses[:, 3:] = np.radians(poses[:, 3:])
    ik = pkm5.inverse_kinematics(poses)
    proximity = pkm5.singularity_proximity(poses).inverse_condition
    reason = ik.reasons.copy()
    near = ik.reachable & (proximity < threshold)
    for i in np.flatnonzero(near):
        reason[i] = f"too close to a singularity (inverse condition {proximity[i]:.3g} < {threshold:g})"
    return TargetCheck(ik.reachable & ~near, reason, proximity)


def _pkm5_move_s(start: np.ndarray, end: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
    """Constant-speed MultiStepper moves: all legs arrive together, the longest leg at 100 % speed sets the time."""
    from motion import pkm5

    g = pkm5.DEFAULT_GEOMETRY

    def lengths(t: np.ndarray) -> np.ndarray:
        poses = t.copy()
        poses[:, 3:] = np.radians(poses[:, 3:])
        return pkm5.inverse_kinematics(poses, check_limits=False).lengths_mm

    steps = np.abs(lengths(end) - lengths(start)) / g.mm_per_step
    return steps.max(axis=1) / (g.max_speed_steps_per_s * velocity_pct / 100.0)


def _pkm5_home() -> tuple[float, ...]:
    # the documents' home (every actuator at 5 mm stroke): LS FK gives (88.649, 0, 300.937), alpha = beta = 0
    return (88.649, 0.0, 300.937, 0.0, 0.0)


def _delta4_check(targets: np.ndarray, threshold: float) -> TargetCheck:
    from motion import delta4

    ik = delta4.inverse_kinematics(targets)
    jac = delta4.jacobian_deg_per_mm(targets)
    singular = np.linalg.svd(np.nan_to_num(jac), compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore"):
        proximity = np.where(singular[:, 0] > 0, singular[:, -1] / singular[:, 0], 0.0)
    reason = np.array([r or "" for r in ik.reason], dtype=object)
    near = ik.reachable & (proximity < threshold)
    for i in np.flatnonzero(near):
        reason[i] = f"too close to a singularity (inverse condition {proximity[i]:.3g} < {threshold:g})"
    return TargetCheck(np.asarray(ik.reachable, bool) & ~near, reason, proximity)


#: Hobby servos of the delta robot: about 60 deg in 0.2 s at full speed.
_DELTA4_SERVO_DEG_PER_S = 300.0


def _delta4_move_s(start: np.ndarray, end: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
    from motion import delta4

    travel = np.abs(delta4.inverse_kinematics(end).servo_deg - delta4.inverse_kinematics(start).servo_deg)
    return np.nan_to_num(travel).max(axis=1) / (_DELTA4_SERVO_DEG_PER_S * velocity_pct / 100.0)


ROBOT_MODELS: dict[str, RobotModel] = {
    "pkm5": RobotModel("pkm5", ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"), _pkm5_home(), _pkm5_check,
                       _pkm5_move_s),
    "delta4": RobotModel("delta4", ("x_mm", "y_mm", "z_mm"), (0.0, 0.0, -200.0), _delta4_check, _delta4_move_s),
}


def robot_model(name: str) -> RobotModel:
    """The model of robot ``name``; ``ConfigError`` lists the known robots."""
    try:
        return ROBOT_MODELS[name]
    except KeyError:
        raise ConfigError(f"--robot {name}: expected one of {', '.join(ROBOT_MODELS)}") from None
