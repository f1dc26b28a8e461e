"""Pre-flight models: what the protocols need from a robot's kinematics, on top of :mod:`motion.model`.

A :class:`PreflightModel` adds to a robot's :class:`motion.model.RobotModel` (IK with joint limits and reasons,
Jacobian) what a campaign needs before anything moves: the check of every target (reachability, joint limits,
singularity proximity), a move-time estimate, the robot's home and the target fields. Targets are rows of mm and
degrees in the model's pose fields: ``(x_mm, y_mm, z_mm, alpha_deg, beta_deg)`` for the pkm5 (a 3-column row means
alpha = beta = 0) and ``(x_mm, y_mm, z_mm)`` for the delta4. Nothing here talks to hardware.

The kinematics module (``motion.<robot>.model``) is imported on first use, so listing the robots stays cheap.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from bench.errors import ConfigError
from bench.robot_kinds import robot_kind
from motion.model import column_conditioning

__all__ = [
    "DEFAULT_SINGULARITY_THRESHOLD",
    "PreflightModel",
    "TargetCheck",
    "inverse_condition",
    "pkm5_mode_columns",
    "robot_model",
    "servo_travel_s",
    "stepper_travel_s",
]

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


def inverse_condition(jacobian: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """sigma_min / sigma_max of each (J, P) Jacobian restricted to its ``columns`` (N, P) bool, in [0, 1].

    A Jacobian without any non-zero singular value (or made of NaN) gives 0: as close to a singularity as it gets.
    """
    # NaN (a target the IK cannot reach) taken as 0
    return column_conditioning(np.nan_to_num(np.asarray(jacobian, dtype=float)), columns)[1]


def _all_columns(targets: np.ndarray) -> np.ndarray:
    return np.ones(targets.shape, bool)


@dataclass(frozen=True)
class PreflightModel:
    """Pre-flight check, move-time estimate, home and target fields of robot ``name``.

    Parameters
    ----------
    name : str
        The robot (:mod:`bench.robot_kinds`); its kinematics are the ``MODEL`` of its registered ``model`` module
        (a :class:`motion.model.RobotModel`).
    home_of : callable
        ``home_of()``: where the robot starts and ends a campaign, in the target fields (read once, as
        :attr:`home`: the pkm5's comes from its forward kinematics, which listing the robots should not pay for).
    travel_s : callable
        ``travel_s(kinematics, travel, velocity_pct)``: seconds of moves whose actuated joints travel ``travel``
        (N, J) in joint units, at ``velocity_pct`` (N,) % of the rated speed.
    mode_columns : callable
        ``mode_columns(targets)``: the pose columns (N, P) bool each target moves in, i.e. the columns of the
        Jacobian its singularity proximity is computed over (default: all).
    """

    name: str
    home_of: Callable[[], tuple[float, ...]]
    travel_s: Callable[[object, np.ndarray, np.ndarray], np.ndarray]
    mode_columns: Callable[[np.ndarray], np.ndarray] = _all_columns
    #: the geometry to check by instead of the documented one (a kinematic calibration in force)
    geometry: object = None

    @cached_property
    def home(self) -> tuple[float, ...]:
        """Where the robot starts and ends a campaign, in the target fields."""
        return tuple(self.home_of())

    @cached_property
    def kinematics(self):
        """The robot's :class:`motion.model.RobotModel` (imported on first use), of :attr:`geometry` if given."""
        module = robot_kind(self.name).model
        model = importlib.import_module(module).MODEL
        if model.name != self.name:
            raise ConfigError(f"{module}.MODEL is named {model.name!r}, expected {self.name!r}")
        return model if self.geometry is None else replace(model, geometry=self.geometry)

    @property
    def target_fields(self) -> tuple[str, ...]:
        """The pose fields of a target, with their units (``x_mm``, ``alpha_deg``)."""
        return self.kinematics.pose_fields

    @property
    def joints(self):
        """The joints with their units and limits (:class:`motion.model.JointSpec`)."""
        return self.kinematics.joints

    def as_targets(self, targets) -> np.ndarray:
        """Targets as float (N, len(target_fields)), short pkm5 rows padded with zero angles."""
        width = len(self.target_fields)
        rows = [tuple(t) + (0.0,) * (width - len(t)) for t in targets]
        return np.asarray(rows, dtype=float).reshape(len(rows), width)

    def check(self, targets: np.ndarray, threshold: float = DEFAULT_SINGULARITY_THRESHOLD) -> TargetCheck:
        """Reachability (IK with joint limits) and singularity proximity of targets (N, P) in mm and degrees.

        A reachable target whose inverse condition number is below ``threshold`` is refused as too close to a
        singularity; ``reason`` says why each refused target is refused.
        """
        ik = self.kinematics.ik(targets)
        proximity = inverse_condition(self.kinematics.jacobian(targets), self.mode_columns(targets))
        reason = np.array([text or "" for text in ik.reason], dtype=object)
        reachable = np.asarray(ik.reachable, bool)
        near = reachable & (proximity < threshold)
        for i in np.flatnonzero(near):
            reason[i] = f"too close to a singularity (inverse condition {proximity[i]:.3g} < {threshold:g})"
        return TargetCheck(reachable & ~near, reason, proximity)

    def move_s(self, start: np.ndarray, end: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
        """Estimated seconds of the moves ``start`` -> ``end`` (N, P) at ``velocity_pct`` (N,) %."""
        actuated = [spec.actuated for spec in self.joints]
        travel = np.abs(self.kinematics.ik(end).joints - self.kinematics.ik(start).joints)[:, actuated]
        return self.travel_s(self.kinematics, np.nan_to_num(travel), velocity_pct)


def stepper_travel_s(kinematics, travel_mm: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
    """Constant-speed MultiStepper moves: all legs arrive together, the leg with the most steps runs at the set
    speed (100 % = the firmware's maximum, 200 steps/s) and sets the time."""
    g = kinematics.geometry
    steps = travel_mm / g.mm_per_step
    return steps.max(axis=1) / (g.max_speed_steps_per_s * velocity_pct / 100.0)


#: Hobby servos of the delta robot: about 60 deg in 0.2 s at full speed.
_DELTA4_SERVO_DEG_PER_S = 300.0


def servo_travel_s(kinematics, travel_deg: np.ndarray, velocity_pct: np.ndarray) -> np.ndarray:
    """Hobby servos turn together at their own speed: the longest turn sets the time."""
    return travel_deg.max(axis=1) / (_DELTA4_SERVO_DEG_PER_S * velocity_pct / 100.0)


def pkm5_mode_columns(targets: np.ndarray) -> np.ndarray:
    """The pkm5's motion mode: x, y, z always, alpha or beta when non-zero (pkm5.md §5.2)."""
    from motion.pkm5.jacobian import mode_columns

    return mode_columns(targets)


def robot_model(name: str) -> PreflightModel:
    """The pre-flight model of robot ``name`` (its :mod:`bench.robot_kinds` record), one per robot; ``ConfigError``
    lists the known robots."""
    robot_kind(name)  # an unknown (or unhashable) name is refused here, before the cache sees it
    return _preflight_model(name)


@functools.cache
def _preflight_model(name: str) -> PreflightModel:
    kind = robot_kind(name)
    mode_columns = kind.resolved("mode_columns") if kind.mode_columns else _all_columns
    return PreflightModel(name, kind.resolved("home"), kind.resolved("travel_time"), mode_columns)
