"""The one rig builder: a station (real devices, or simulators standing in for them) -> a :class:`Rig`.

The command line (``bench run --station``) and the desktop app build rigs here and nowhere else. The builder

1. refuses, before anything is opened, a station that lacks a capability the protocol needs, naming the protocol,
   the capability and the station key that would provide it;
2. opens every port through :func:`bench.robots.link.open_port`, exclusively (a second process on the same port is
   refused by the operating system's lock), identifies and enables the controller;
3. records the calibrations in force get-or-create in the store (a nominal one, flagged as such, when none was
   measured yet), so every sample names them;
4. registers relative instruments (the mice) at home and verifies them at a check pose before anything is measured
   (:mod:`bench.rigs.registration`; the record is the rig's ``registration``);
5. closes everything it opened, newest first, when a later device fails.

Each sensor is opened by the opener its record in :mod:`bench.sensor_kinds` names (given a :class:`SensorOpening`);
the builder itself names no sensor.

Production code never imports :mod:`bench.simulators`; a simulated station is a station whose devices are
simulator processes (:func:`bench.simulators.station.rehearse`), built here by the same code as hardware.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from contextlib import ExitStack
from typing import Any

from bench.errors import ConfigError
from bench.rigs.gauges import CalliperOnly
from bench.rigs.interfaces import Instrument, Operator, Rig
from bench.rigs.movers import DeltaMover, LatchingMover, Pkm5Mover
from bench.rigs.opening import SensorOpening, open_station_port
from bench.rigs.registration import home_before_registering, register_at_home
from bench.rigs.station import Station, capture_capabilities
from bench.sensor_kinds import SensorKind, sensor_kind

__all__ = ["SensorOpening", "build_rig", "check_capabilities", "open_mover"]

_log = logging.getLogger(__name__)


def check_capabilities(station: Station, requires: frozenset[str] | set[str], protocol: str = "the protocol") -> None:
    """``ConfigError`` naming what ``station`` lacks for ``protocol`` (and the key to add), before anything opens."""
    missing = station.missing(requires)
    if missing:
        raise ConfigError(f"{station.source}: {protocol} needs {', '.join(missing)}")
    if station.robot not in ("pkm5", "delta4"):  # pragma: no cover - the station parser refuses other robots
        raise ConfigError(f"{station.source}: robot.kind = {station.robot!r}, expected pkm5 or delta4")


def build_rig(
    station: Station,
    store: Any,
    *,
    operator: Operator | None = None,
    requires: frozenset[str] | set[str] = frozenset(),
    protocol: str = "the protocol",
    speed_factor: float = 1.0,
) -> Rig:
    """The rig of ``station`` for a protocol that ``requires`` these capabilities.

    ``operator`` answers the prompts (default: the person at the terminal); a serial calliper answers the reading
    prompts itself. ``speed_factor`` is 1 for hardware and the simulators' factor for a rehearsal.
    """
    check_capabilities(station, requires, protocol)
    if operator is None:
        from bench.rigs.operators import ConsoleOperator

        operator = ConsoleOperator()
    calibration_ids: list[int] = []
    with ExitStack() as opened:
        mover, controller = _open_robot(station, opened)
        serving = _serving(station)
        if (
            station.robot == "pkm5"
            and station.controller.fixture == "assembled"
            and any(kind.zeroed_at_home for kind, _ in serving)
        ):
            home_before_registering(controller)
        kind, instrument = _open_instrument(station, controller, store, requires, opened, calibration_ids, speed_factor)
        registration = None
        if kind is not None and kind.relative:  # verified at the check pose before anything is stored
            registration = register_at_home(controller, instrument, speed_factor=speed_factor)
        for kind, spec in serving:
            if kind.operator is not None:  # a gauge that answers the reading prompts itself
                opening = SensorOpening(station, spec, controller, store, opened, calibration_ids)
                operator = kind.resolved("operator")(opening, operator)
        closers = opened.pop_all()
    return Rig(
        mover,
        instrument,
        operator,
        speed_factor=speed_factor,
        calibration_ids=tuple(calibration_ids),
        closers=[closers.close],
        station=station,
        registration=registration,  # the runner files it as the run's (or the segment's)
    )


def open_mover(station: Station) -> tuple[LatchingMover, Callable[[], None]]:
    """Only the robot of ``station`` (jogging): its mover and the function that releases it."""
    with ExitStack() as opened:
        mover, _ = _open_robot(station, opened)
        closers = opened.pop_all()
    return mover, closers.close


def _open_robot(station: Station, opened: ExitStack) -> tuple[LatchingMover, Any]:
    spec = station.controller
    port = open_station_port(station, "controller.port", spec.port, spec.baud, opened)
    if station.robot == "pkm5":
        from bench.robots.pkm5 import Pkm5Controller

        controller = Pkm5Controller(port, fixture=spec.fixture)
        opened.callback(controller.shutdown)
        controller.identify()
        if controller.position().state == "MOVING":
            # a move no host is waiting for (a host killed mid-move, a controller without the link watchdog):
            # never inherit motion; it is stopped, and the robot is homed before anything is measured
            _log.warning("pkm5 still moving an earlier host's command: stopping it before enabling")
            controller.stop()
        controller.enable()
        return Pkm5Mover(controller), controller
    from bench.robots.delta4 import Delta4Controller

    delta = Delta4Controller(port)
    opened.callback(delta.shutdown)
    delta.start()
    delta.probe_fine_references()  # fine references only if the firmware answers (the run settings say)
    return DeltaMover(delta), delta


def _serving(station: Station) -> list[tuple[SensorKind, Any]]:
    """The station's sensors that measure on its robot in its fixture, with their specs, in registration order."""
    serving = [(sensor_kind(name), spec) for name, spec in station.sensors.items()]
    return [(kind, spec) for kind, spec in serving if kind.serves(station.robot, station.controller.fixture)]


def _open_instrument(
    station: Station,
    controller: Any,
    store: Any,
    requires: frozenset[str] | set[str],
    opened: ExitStack,
    calibration_ids: list[int],
    speed_factor: float = 1.0,
) -> tuple[SensorKind | None, Instrument]:
    """The rig's instrument: the first registered sensor of the station that opens as one and provides what the
    protocol captures (any, when it says nothing of what it needs); else the calliper-only instrument, which refuses
    captures."""
    captures = set(requires) & capture_capabilities()
    if captures or not requires:
        for kind, spec in _serving(station):
            if kind.instrument is not None and (captures & set(kind.provides) or not requires):
                opening = SensorOpening(station, spec, controller, store, opened, calibration_ids, speed_factor)
                return kind, kind.resolved("instrument")(opening)
    readers = {kind.name: vars(spec) for kind, spec in _serving(station) if kind.operator is not None}
    return None, CalliperOnly(readers)
