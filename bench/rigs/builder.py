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

Production code never imports :mod:`bench.simulators`; a simulated station is a station whose devices are
simulator processes (:func:`bench.simulators.station.rehearse`), built here by the same code as hardware.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from contextlib import ExitStack
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.errors import ConfigError, LinkError
from bench.rigs.gauges import CalliperOnly, GaugeOperator
from bench.rigs.interfaces import Instrument, Operator, Rig
from bench.rigs.movers import DeltaMover, LatchingMover, Pkm5Mover
from bench.rigs.registration import home_before_registering, register_at_home
from bench.rigs.station import CAPTURE_CAPABILITIES, Station
from bench.robot_kinds import robot_kind
from bench.robots.link import open_port

if TYPE_CHECKING:  # opened on first use: the camera's and the mice's modules import their device libraries
    from bench.rigs.camera import CameraSpotInstrument
    from bench.rigs.mice import MiceInstrument

__all__ = ["build_rig", "calibration_summary", "check_capabilities", "mouse_calibration", "open_mover"]

_log = logging.getLogger(__name__)

#: Read slice of the controller ports (the drivers poll in slices; deadlines are theirs).
_POLL_S = 0.05


def check_capabilities(station: Station, requires: frozenset[str] | set[str], protocol: str = "the protocol") -> None:
    """``ConfigError`` naming what ``station`` lacks for ``protocol`` (and the key to add), before anything opens."""
    missing = station.missing(requires)
    if missing:
        raise ConfigError(f"{station.source}: {protocol} needs {', '.join(missing)}")
    if station.robot not in ("pkm5", "delta4"):  # pragma: no cover - the station parser refuses other robots
        raise ConfigError(f"{station.source}: robot.kind = {station.robot!r}, expected pkm5 or delta4")


def mouse_calibration(
    store: Any, cpi: float, version: int | None = None, *, source: str = "station"
) -> tuple[Any, Any]:
    """The mouse calibration a station puts in force; returns (store record, :class:`CountsCalibration`).

    With ``version`` (``[mice] calibration``), that stored ``mouse`` calibration, per-axis scales where it has
    them; without, the nominal resolution at ``cpi``, recorded and flagged nominal. A measured calibration is never
    put in force because it is the newest: a warning names the newest measured one and the key that would use it.
    """
    from bench.sensors.calibration import MM_PER_INCH, CountsCalibration

    if version is not None:
        try:
            record = store.calibration("mouse", version)
        except ConfigError:
            stored = [str(c.version) for c in store.calibrations() if c.name == "mouse"]
            raise ConfigError(
                f"{source}: mice.calibration = {version}, expected a stored mouse calibration version "
                f"({', '.join(stored) or 'none stored yet'})"
            ) from None
    else:
        measured = [c for c in store.calibrations() if c.name == "mouse" and not c.params.get("nominal")]
        record = store.ensure_calibration(
            "mouse",
            {"mm_per_count": MM_PER_INCH / cpi, "nominal": True},
            notes=f"nominal {cpi:g} cpi (no [mice] calibration named)",
        )
        if measured:
            _log.warning(
                "%s: the nominal %g cpi is in force; stored calibration mouse-v%d is not used unless the "
                "station names it ([mice] calibration = %d)",
                source,
                cpi,
                measured[-1].version,
                measured[-1].version,
            )
    params = record.params
    matrix = params.get("matrix_mm_per_count") or np.diag(
        [params.get(f"{axis}_mm_per_count", params["mm_per_count"]) for axis in "xy"]
    )
    calibration = CountsCalibration(
        np.asarray(matrix, dtype=float),
        f"mouse-v{record.version}",
        record.created_utc[:10],
        nominal=bool(params.get("nominal", False)),
    )
    return record, calibration


def calibration_summary(record: Any) -> dict[str, Any]:
    """What a run records of the mouse calibration it used: version, nominal or not, and each scale with its u."""
    params = record.params
    summary: dict[str, Any] = {"version": record.version, "nominal": bool(params.get("nominal", False))}
    for axis in ("x", "y"):
        summary[f"{axis}_mm_per_count"] = params.get(f"{axis}_mm_per_count", params["mm_per_count"])
        if f"u_{axis}_mm_per_count" in params:
            summary[f"u_{axis}_mm_per_count"] = params[f"u_{axis}_mm_per_count"]
    return summary


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
        if station.robot == "pkm5" and station.controller.fixture == "assembled" and (station.mice or station.camera):
            home_before_registering(controller)
        instrument = _open_instrument(station, controller, store, requires, opened, calibration_ids)
        from bench.rigs.mice import MiceInstrument

        registration = None
        if isinstance(instrument, MiceInstrument):  # relative: verified at the check pose before anything is stored
            registration = register_at_home(controller, instrument, speed_factor=speed_factor)
        if station.calliper is not None and station.calliper.kind == "serial":
            operator = GaugeOperator(_open_calliper(station, opened), operator, timeout_s=station.calliper.timeout_s)
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


def _open_port(station: Station, key: str, url: str, baud: int, opened: ExitStack) -> Any:
    """Open a port exclusively; a failure names the station key, the device and what to check."""
    try:
        port = open_port(url, baudrate=baud, timeout=_POLL_S, exclusive=True)
    except LinkError as exc:
        cause = exc.__cause__
        why = getattr(cause, "strerror", None) or str(cause or exc)
        raise LinkError(
            f"{station.source}: {key} = {url!r}: cannot open it ({why}); is the device plugged in, the "
            "name right and the port free? (bench station check)"
        ) from None
    opened.callback(port.close)
    return port


def _open_robot(station: Station, opened: ExitStack) -> tuple[LatchingMover, Any]:
    spec = station.controller
    port = _open_port(station, "controller.port", spec.port, spec.baud, opened)
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


def _open_instrument(
    station: Station,
    controller: Any,
    store: Any,
    requires: frozenset[str] | set[str],
    opened: ExitStack,
    calibration_ids: list[int],
) -> Instrument:
    needs_capture = bool(set(requires) & CAPTURE_CAPABILITIES) or not requires
    calliper = {} if station.calliper is None else {"calliper": vars(station.calliper)}
    if (
        station.robot == "pkm5"
        and station.mice is not None
        and station.controller.fixture == "assembled"
        and needs_capture
    ):
        return _open_mice(station, store, opened, calibration_ids)
    if station.camera is not None and needs_capture:
        return _open_camera(station, opened)
    if station.robot == "delta4" and station.laser_grid is not None and needs_capture:
        from bench.rigs.lasergrid import DEFAULT_DECODER, LaserGridInstrument

        decoder = {
            **DEFAULT_DECODER,
            "spot_half_width_mm": station.laser_grid.spot_half_width_mm,
            "gate_mm": station.laser_grid.gate_mm,
        }
        instrument = LaserGridInstrument(controller, decoder=decoder)
        calibration_ids.append(instrument.record_geometry(store))
        return instrument
    return CalliperOnly(calliper)


def _open_mice(station: Station, store: Any, opened: ExitStack, calibration_ids: list[int]) -> MiceInstrument:
    from bench.rigs.mice import MiceInstrument
    from bench.sensors.mouse import EvdevMouse

    spec = station.mice
    assert spec is not None
    record, calibration = mouse_calibration(store, spec.cpi, spec.calibration, source=station.source)
    calibration_ids.append(record.id)
    mice = {}
    for plane, path in (("xy", spec.xy), ("xz", spec.xz)):
        mice[plane] = EvdevMouse(path, calibration, label=f"mouse_{plane}", grab=spec.grab)
        opened.callback(mice[plane].close)
    # zeroed at the home pose (the robot was homed), then verified at the check pose (bench.rigs.registration)
    instrument = MiceInstrument(
        mice,
        _home("pkm5"),
        calibration,
        follow=True,
        noise_counts=spec.noise_counts,
        calibration_record=calibration_summary(record),
    )
    opened.callback(instrument.close)
    return instrument


def _open_camera(station: Station, opened: ExitStack) -> CameraSpotInstrument:
    from bench.rigs.camera import CameraSpotInstrument, load_plane_calibration, video_grab
    from bench.sensors.camera_spot import LaserSpotCamera

    spec = station.camera
    assert spec is not None
    calibration = load_plane_calibration(spec.calibration)
    grab, grab_next, release = video_grab(spec.device)
    opened.callback(release)
    return CameraSpotInstrument(
        LaserSpotCamera(grab, calibration, grab_next=grab_next),
        _home(station.robot),
        plane=spec.plane,
        frames=spec.frames,
    )


def _home(robot: str) -> tuple[float, ...]:
    return tuple(robot_kind(robot).resolved("home")())


def _open_calliper(station: Station, opened: ExitStack) -> Any:
    from bench.sensors.calliper import SerialCalliper

    spec = station.calliper
    assert spec is not None
    port = _open_port(station, "calliper.port", spec.port, spec.baud, opened)
    return SerialCalliper(port, request=spec.request.encode(), terminator=spec.terminator.encode())
