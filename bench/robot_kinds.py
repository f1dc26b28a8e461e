"""The registry of robot kinds: one record per robot a bench can drive, the one place that names its pieces.

Every part of bench that treats robots differently asks this registry: station files (the controller's baud, the
fixtures), pre-flight (home, move-time model, motion-mode columns), ``bench sim`` (the simulator), the rig builder
(home), calibration (the stored calibration's name, the commanded columns) and reports (the kinematic type). A record
names code of higher layers by ``"module:attribute"`` strings, resolved on first use (:func:`resolve`), so listing the
robots imports nothing heavy and this module imports no layer of bench.

Adding a robot (docs/extending.md): write its kinematics (``motion/<robot>/``, with a ``model.MODEL``), its driver
(``bench/robots/<robot>.py``), its simulator (``bench/simulators/<robot>.py``), then register it with one
:func:`register` call below. ``tests/test_robot_kinds.py`` adds a toy robot through :func:`register` alone.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from bench.errors import ConfigError

__all__ = ["ROBOT_KINDS", "RobotKind", "register", "resolve", "resolve_field", "robot_kind", "robot_names"]


@dataclass(frozen=True)
class RobotKind:
    """What bench needs to know about one kind of robot.

    Attributes
    ----------
    name : str
        The name stations, protocols and the store use (``"pkm5"``).
    title : str
        The kinematic type as a report states it.
    baud : int
        The controller's documented baud rate (a station's ``[controller] baud`` default and the driver's
        ``DEFAULT_BAUDRATE``: one home).
    model : str
        The module whose ``MODEL`` is the robot's :class:`motion.model.RobotModel`.
    home : str
        ``"module:callable"`` returning the home pose (a tuple in the model's pose fields, mm and degrees).
    travel_time : str
        ``"module:callable"`` ``(kinematics, travel, velocity_pct) -> seconds`` of the pre-flight's time estimate.
    simulator : str
        The module of its simulated controller (``bench sim <name>``), with ``DESCRIPTION``, ``add_arguments`` and
        ``build_device``.
    simulator_help : str
        One line for ``bench sim --help``.
    mode_columns : str or None
        ``"module:callable"`` ``targets -> (N, P) bool``: the pose columns a target moves in (None: all of them).
    calibration : str or None
        The name of its kinematic calibration in the store (``pkm5_kinematics``); None when it has none.
    calibration_model : str or None
        The module whose ``compensation_geometry`` turns a stored calibration's parameters into the geometry a run
        commands by (``motion.pkm5.calibration``).
    calibration_problem : str or None
        ``"module:callable"`` ``(store, run_id, uncertainty_mm) -> problem``: the identification problem
        :mod:`bench.calibration.identify` fits for a calibration run of this robot.
    commanded : tuple of str
        The commanded-pose columns of its samples, in pose-field order.
    fixtures : tuple of str
        The controller fixtures a station may name (``assembled``; the pkm5 also ``actuator-bench``).
    """

    name: str
    title: str
    baud: int
    model: str
    home: str
    travel_time: str
    simulator: str
    simulator_help: str
    mode_columns: str | None = None
    calibration: str | None = None
    calibration_model: str | None = None
    calibration_problem: str | None = None
    commanded: tuple[str, ...] = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")
    fixtures: tuple[str, ...] = ("assembled",)

    def resolved(self, field: str) -> Any:
        """The object a ``"module:attribute"`` field names (``kind.resolved("home")()``)."""
        return resolve_field(self, field, f"robot {self.name!r}")


#: Name -> record, in registration order (the order robots are listed in).
ROBOT_KINDS: dict[str, RobotKind] = {}


def register(kind: RobotKind) -> RobotKind:
    """Add ``kind`` to the registry (a name registered twice is a mistake: refused)."""
    if kind.name in ROBOT_KINDS and ROBOT_KINDS[kind.name] != kind:
        raise ValueError(f"robot kind {kind.name!r} is registered already")
    ROBOT_KINDS[kind.name] = kind
    return kind


def robot_names() -> tuple[str, ...]:
    """The registered robots, in registration order."""
    return tuple(ROBOT_KINDS)


def robot_kind(name: str, field: str = "--robot") -> RobotKind:
    """The record of robot ``name``; :class:`ConfigError` names ``field`` and lists the known robots."""
    try:
        return ROBOT_KINDS[name]
    except (KeyError, TypeError):
        raise ConfigError(f"{field} {name}: expected one of {', '.join(ROBOT_KINDS)}") from None


def resolve_field(record: object, field: str, owner: str) -> Any:
    """The object the ``"module:attribute"`` field ``field`` of a registry ``record`` names; :class:`ConfigError`
    naming ``owner`` when the record registers none."""
    reference = getattr(record, field)
    if reference is None:
        raise ConfigError(f"{owner}: no {field} registered")
    return resolve(reference)


def resolve(reference: str) -> Any:
    """Import ``"package.module:attribute"`` (or a bare module) and return the object it names."""
    module_name, _, attribute = reference.partition(":")
    module = importlib.import_module(module_name)
    return getattr(module, attribute) if attribute else module


# --- the registrations: one call per robot ---------------------------------------------------------------------

register(
    RobotKind(
        name="pkm5",
        title="parallel kinematic machine, 5 DOF (x, y, z, α, β)",
        baud=115200,
        model="motion.pkm5.model",
        home="bench.robots.pkm5_kinematics:home_pose",
        travel_time="bench.protocols.kinematics:stepper_travel_s",
        mode_columns="bench.protocols.kinematics:pkm5_mode_columns",
        simulator="bench.simulators.pkm5",
        simulator_help="5-DOF PKM controller (line protocol, docs/protocol-pkm5.md)",
        calibration="pkm5_kinematics",
        calibration_model="motion.pkm5.calibration",
        calibration_problem="bench.calibration.identify:pkm5_problem",
        commanded=("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg"),
        fixtures=("assembled", "actuator-bench"),
    )
)

register(
    RobotKind(
        name="delta4",
        title="4-RSS delta, 3 DOF",
        baud=9600,  # 003 §5.3 states none: 9600 8-N-1 is its first guess
        model="motion.delta4.model",
        home="bench.robots.delta4:home_pose",
        travel_time="bench.protocols.kinematics:servo_travel_s",
        simulator="bench.simulators.delta4",
        simulator_help="delta4 ATmega128 controller (ASCII protocol, docs/protocol-delta4.md)",
        calibration="delta4_kinematics",
        calibration_model="motion.delta4.calibration",
        calibration_problem="bench.calibration.identify:delta4_problem",
    )
)
