"""Kinematic compensation: which stored kinematic calibration (``pkm5_kinematics``, ``delta4_kinematics``) a run
commands by, and putting it in force.

A calibration in force replaces the documented geometry of the robot everywhere the run uses kinematics: the
driver's IK of every commanded target (pkm5: targets -> leg strokes, with its pre-flight of step targets: leg
windows, FK and IK reachability; delta4: targets -> servo angles, the closed-form IK of each calibrated leg, then
the servo mapping's window) and the plan's pre-flight (reach, joint limits, singularity proximity). The geometry is
the robot's ``compensation_geometry`` (:mod:`motion.pkm5.calibration`, :mod:`motion.delta4.calibration`): the
identified deviations with the instrument's registration folded into the base joints (servo axes), so a target in
the instrument's frame gives the joints whose predicted measurement is that target. Home stays the documented home
joints, where the instruments are registered as during the calibration run.

Which calibration (:data:`NEWEST` by default): the newest version of the robot's calibration made for this robot, i.e.
whose ``dut_serial`` equals the station's device-under-test serial (a rig without a serial: a calibration without
one) and made on a simulator exactly when the rig is one (``simulated``: a simulated robot's geometry never reaches
hardware); a calibration id chosen by the person; or :data:`OFF`. The record in force goes into the run's calibration
ids and its settings (``kinematic_calibration``), and none in force is recorded as such with the reason.
"""

from __future__ import annotations

from typing import Any

from bench.errors import ConfigError
from bench.robot_kinds import ROBOT_KINDS

__all__ = [
    "CALIBRATION_NAME",
    "CALIBRATION_NAMES",
    "NEWEST",
    "OFF",
    "calibrated_geometry",
    "calibration_name",
    "choose_calibration",
    "describe_in_force",
    "put_in_force",
    "select_calibration",
]

#: The store name of each robot's kinematic calibration (``bench calibrate`` writes versions of it), from the robots'
#: registry (bench.robot_kinds: ``calibration``, and ``calibration_model``, the module whose ``compensation_geometry``
#: turns its parameters into the geometry a run commands by).
CALIBRATION_NAMES = {name: kind.calibration for name, kind in ROBOT_KINDS.items() if kind.calibration}
_GEOMETRY_MODULES = {
    kind.calibration: kind.calibration_model
    for kind in ROBOT_KINDS.values()
    if kind.calibration and kind.calibration_model
}
#: The pkm5's (the window's calibration box lists these).
CALIBRATION_NAME = CALIBRATION_NAMES["pkm5"]


def calibration_name(robot: str) -> str:
    """The store name of ``robot``'s kinematic calibration; ``ConfigError`` for a robot without one."""
    try:
        return CALIBRATION_NAMES[robot]
    except KeyError:
        raise ConfigError(
            f"robot {robot!r}: no kinematic calibration exists for it, expected one of {', '.join(CALIBRATION_NAMES)}"
        ) from None


#: Choices besides a calibration id: the newest calibration of this robot, or none at all.
NEWEST, OFF = "newest", "off"


def select_calibration(
    store: Any, robot: str, choice: int | str = NEWEST, dut_serial: str | None = None, simulated: bool = False
):
    """The calibration record ``choice`` puts in force for ``robot`` (serial ``dut_serial``, a simulator or not), or
    None with why.

    Returns ``(record or None, reason)``. An explicit id that is not this robot's kinematic calibration
    (:data:`CALIBRATION_NAMES`), names another robot's serial, or was made on a simulator for hardware (or the
    reverse) raises ``ConfigError`` (one line).
    """
    if choice == OFF:
        return None, "--no-kinematic-calibration"
    name = CALIBRATION_NAMES.get(robot)
    if choice == NEWEST:
        if name is None:
            return None, f"no kinematic calibration exists for the {robot}"
        mine = [
            c
            for c in store.calibrations()
            if c.name == name
            and c.params.get("dut_serial") == dut_serial
            and bool(c.params.get("simulated")) == simulated
        ]
        if not mine:
            whose = (f"robot {dut_serial}" if dut_serial else "a robot without a serial") + (
                " (simulated)" if simulated else ""
            )
            return None, f"no {name} calibration for {whose} in {store.path}"
        return max(mine, key=lambda c: c.version), "the newest for this robot"
    if isinstance(choice, bool) or not isinstance(choice, int):
        raise ConfigError(f"--kinematic-calibration {choice!r}: expected a calibration id (bench calibrate prints it)")
    record = store.calibration_by_id(choice)
    if name is None:
        raise ConfigError(
            f"--kinematic-calibration {choice}: no kinematic calibration exists for the {robot}, expected none"
        )
    if record.name != name:
        raise ConfigError(
            f"--kinematic-calibration {choice}: calibration {record.name} v{record.version}, expected "
            f"a {name} calibration"
        )
    serial = record.params.get("dut_serial")
    if serial != dut_serial:
        raise ConfigError(
            f"--kinematic-calibration {choice}: made for robot {serial or '(no serial)'}, expected "
            f"one for robot {dut_serial or '(no serial)'}"
        )
    if bool(record.params.get("simulated")) != simulated:
        made, wanted = ("a simulated", "hardware") if not simulated else ("hardware", "a simulated")
        raise ConfigError(f"--kinematic-calibration {choice}: made on {made} robot, expected one for {wanted} robot")
    return record, "chosen"


def calibrated_geometry(record: Any):
    """The geometry a run commands by under calibration ``record`` (a :class:`motion.pkm5.Geometry`, or a
    :class:`motion.delta4.calibration.CalibratedGeometry`); ``ConfigError`` when it is not a kinematic calibration
    or its parameters are not one's."""
    import importlib

    from motion.errors import MotionInputError

    module = _GEOMETRY_MODULES.get(record.name)
    if module is None:
        raise ConfigError(
            f"calibration id {record.id} ({record.name} v{record.version}): expected a kinematic "
            f"calibration ({', '.join(_GEOMETRY_MODULES)})"
        )
    try:
        return importlib.import_module(module).compensation_geometry(record.params)
    except (MotionInputError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"calibration id {record.id} ({record.name} v{record.version}): {exc}") from None


def choose_calibration(
    store: Any,
    robot: str,
    choice: int | str = NEWEST,
    dut_serial: str | None = None,
    fixture: str = "assembled",
    simulated: bool = False,
):
    """:func:`select_calibration` for a rig with ``fixture``, decided before the rig opens (a refused choice starts
    no simulator and opens no port): the actuator bench commands no poses, so none is in force there."""
    if robot == "pkm5" and fixture != "assembled":
        if choice not in (NEWEST, OFF):
            raise ConfigError(f"--kinematic-calibration {choice}: the {fixture} commands no poses, expected none")
        return None, f"the {fixture} commands no poses"
    return select_calibration(store, robot, choice, dut_serial, simulated)


def put_in_force(rig: Any, record: Any, reason: str) -> Any:
    """Calibration ``record`` (None: none, for ``reason``) in force on ``rig``: its mover commands (and the runner
    pre-flights) by the calibrated geometry, its id joins ``rig.calibration_ids``, an instrument that judges its
    readings against the commanded motion learns the calibration's own error (``expect_calibrated_robot``, the mice's
    liveness check) and ``rig.kinematic_calibration`` records it (or none, and why). Returns ``rig``."""
    from bench.rigs.interfaces import KinematicCalibration

    if record is None:
        rig.kinematic_calibration = KinematicCalibration(reason)
        return rig
    try:
        rig.robot.use_geometry(calibrated_geometry(record))
    except BaseException:
        rig.close()
        raise
    rig.calibration_ids = tuple(rig.calibration_ids) + (record.id,)
    expect_calibrated_robot = getattr(rig.instrument, "expect_calibrated_robot", None)
    if expect_calibrated_robot is not None and record.params.get("ap_after_mm") is not None:
        # an instrument that judges its readings against the commanded motion (the mice) may now expect the small
        # error of a calibrated robot instead of an uncalibrated one's
        expect_calibrated_robot(float(record.params["ap_after_mm"]))
    rig.kinematic_calibration = KinematicCalibration(
        reason, id=record.id, name=record.name, version=record.version, source_run_id=record.source_run_id
    )
    return rig


def describe_in_force(rig: Any) -> str:
    """One line naming the kinematic calibration in force on ``rig`` (for stderr and the window's log)."""
    entry = rig.kinematic_calibration
    if entry is None:
        return "kinematic calibration: none (not selected)"
    if entry.id is None:
        return f"kinematic calibration: none ({entry.reason}); commanding by the documented geometry"
    source = f" from run {entry.source_run_id}" if entry.source_run_id is not None else ""
    return f"kinematic calibration in force: {entry.name} v{entry.version} (id {entry.id}{source}; {entry.reason})"
