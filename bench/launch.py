"""How a face (the command line, the desktop window) opens the rig a person asked for.

A :class:`RigRequest` says where to run: a station file (hardware), the same station rehearsed on simulators
(``simulate``), the ``--port`` shorthand (a controller, two mice, typed readings), or nothing (the simulated default
rig: the simulator with its simulated sensors, as ``bench run --sim`` has always run). :func:`open_rig` turns it
into a rig; every station rig, rehearsed or real, is built by :func:`bench.rigs.builder.build_rig`. This module may
import :mod:`bench.simulators` (it starts them); the production packages below it never do.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from bench.calibration.compensate import NEWEST, choose_calibration, put_in_force
from bench.errors import ConfigError
from bench.metrology.mouse_calibration import MM_PER_INCH
from bench.rigs.builder import build_rig, check_capabilities
from bench.rigs.builder import open_mover as builder_open_mover
from bench.rigs.interfaces import Operator, Rig, SimulatorRecord
from bench.rigs.resume_identity import refuse_another_rig
from bench.rigs.station import Station, load_station, parse_station, station_identity
from bench.simulators import CAMPAIGN_KERNEL_WAIT_S, DEFAULT_SPEED_FACTOR

__all__ = [
    "CAMPAIGN_KERNEL_WAIT_S",
    "DEFAULT_SPEED_FACTOR",
    "RigRequest",
    "open_mover",
    "open_rig",
    "resuming",
    "simulated_rig_in",
]


@dataclass(frozen=True)
class RigRequest:
    """Where a run happens. ``seed`` and ``speed_factor`` apply to simulators (None: the stored run's own, or the
    defaults 0 and :data:`DEFAULT_SPEED_FACTOR`)."""

    station: str | None = None
    port: str | None = None
    mouse_xy: str | None = None
    mouse_xz: str | None = None
    #: how the x-z mouse is mounted (``[mice] xz_mount``: "platform" or "guided"); None: the station default
    mouse_xz_mount: str | None = None
    simulate: bool = False
    seed: int | None = None
    speed_factor: float | None = None
    #: how messages name the port shorthand (the CLI: ``--port``; the window: "serial port")
    port_label: str = "serial port"
    #: the kinematic calibration to command by: NEWEST (this robot's newest), OFF, or a calibration id
    kinematic_calibration: int | str = NEWEST
    #: the simulated pkm5 moves by this seed's true geometry (bench.simulators.true_geometry); None: it does not
    true_geometry_seed: int | None = None
    #: the simulated robot without its error model (backlash, noise, play): it errs by its geometry only
    ideal: bool = False

    @property
    def simulator_default(self) -> bool:
        """True for the simulated default rig (no station, no port): its operator answers from the truth."""
        return not self.station and self.port is None

    def describe(self) -> str:
        if self.station:
            return f"station {self.station}" + (" (rehearsal on simulators)" if self.simulate else "")
        return f"controller on {self.port}" if self.port else "simulator"


def open_rig(
    request: RigRequest,
    store: Any,
    *,
    robot: str,
    stored: dict[str, Any] | None = None,
    fixture: str = "assembled",
    requires: frozenset[str] = frozenset(),
    protocol: str = "the protocol",
    operator: Operator | None = None,
) -> Rig:
    """The rig ``request`` describes for a protocol on ``robot`` with ``fixture`` needing ``requires``.

    ``operator`` answers prompts on a station rig (default: the terminal); the simulated default rig answers them
    from the simulator's truth unless the caller replaces its ``answer``.
    """
    station = _station(request, robot, fixture)
    if stored:  # a resume: on the rig the run ran on, or refused before anything is opened or written
        named = bool(request.station) or request.port is not None or request.simulate
        refuse_another_rig("the resumed run", stored, station, request.simulate, named=named)
    stored = stored or {}
    serial = None if station is None else station_identity(station).get("dut_serial")
    kinematic = _kinematic_calibration(
        request, store, robot, stored, serial, fixture, simulated=station is None or request.simulate
    )
    if station is None:
        seed, speed = _simulation_settings(request, stored)
        rig = simulated_rig_in(
            store,
            robot,
            seed=seed,
            speed_factor=speed,
            fixture=fixture,
            true_geometry_seed=_true_geometry_seed(request, stored),
            ideal=request.ideal or bool(stored.get("simulator", {}).get("ideal")),
        )
        return put_in_force(rig, *kinematic)
    if not request.simulate:
        _refuse_simulator_options(request)
    if station.robot != robot:
        raise ConfigError(f"{station.source}: robot.kind = {station.robot!r}, expected {robot!r} for {protocol}")
    if station.controller.fixture != fixture:
        raise ConfigError(
            f"{station.source}: controller.fixture = {station.controller.fixture!r}, expected "
            f"{fixture!r} for {protocol}"
        )
    if request.station:
        store.bench = station.identity.bench  # runs are stored under the station's name (the lab store's key)
    if not request.simulate:
        rig = build_rig(station, store, requires=requires, protocol=protocol, operator=operator)
        return _synced_after(put_in_force(rig, *kinematic), station, store)
    check_capabilities(station, requires, protocol)  # before a simulator starts
    rig, rehearsal, seed = _on_rehearsal(
        station,
        request,
        stored,
        lambda devices, speed: build_rig(
            devices, store, requires=requires, protocol=protocol, speed_factor=speed, operator=operator
        ),
        default_speed=_rehearsal_speed_factor(station, requires),
    )
    rig.closers.insert(0, rehearsal.close)  # closed last: after the drivers let go of the simulators' devices
    rig.simulator = SimulatorRecord(
        seed,
        ideal=bool(rehearsal.settings.get("ideal")),
        true_geometry_seed=rehearsal.settings.get("true_geometry_seed"),
        station=station.source,
        truth_log=rehearsal.truth_path,
    )
    return _synced_after(put_in_force(rig, *kinematic), station, store)


@contextmanager
def resuming(store: Any, run_id: int) -> Iterator[Any]:
    """Hold run ``run_id`` while a face opens its rig and resumes it (``bench resume`` and the window's Resume
    alike, so a resume is refused or accepted the same way from both): the run is claimed first (one that another
    live process drives is refused before a port opens) and the store is told it is resuming (opening the rig writes
    no new calibration: a refused resume writes nothing). Yields the run's record. On leaving, the store resumes
    nothing and the run is released (the runner released it already if it took the run; a refusal before it did
    must not keep the run from ``bench resume`` while the window stays open)."""
    record = store.run(run_id)
    store.claim(run_id)
    store.resuming = run_id
    try:
        yield record
    finally:
        store.resuming = None
        store.release(run_id)


def _refuse_simulator_options(request: RigRequest) -> None:
    """A simulator's setting given for real hardware is refused in one line, never silently ignored: a user who
    asked for a seed or a speed factor on a real controller believes something about the run that is not true."""
    given = ["--ideal"] if request.ideal else []
    if request.true_geometry_seed is not None:
        given.append(f"--true-geometry-seed {request.true_geometry_seed}")
    if request.seed is not None:
        given.append(f"--seed {request.seed}")
    if request.speed_factor is not None:
        given.append(f"--speed-factor {request.speed_factor:g}")
    if given:
        raise ConfigError(f"{', '.join(given)}: only for a simulated rig (no --port; --station with --sim)")


def _synced_after(rig: Rig, station: Station, store: Any) -> Rig:
    """With ``[lab_store] auto_sync``, the store is synced when the rig closes (the run has ended, however it
    ended), after everything else the rig started has been released."""
    if station.lab_store is not None and station.lab_store.auto_sync:
        from bench.store.lab import sync_after_run

        url = station.lab_store.url
        rig.closers.insert(0, lambda: sync_after_run(store, url))
    return rig


def _kinematic_calibration(
    request: RigRequest,
    store: Any,
    robot: str,
    stored: dict[str, Any],
    serial: str | None,
    fixture: str,
    simulated: bool,
) -> tuple[Any, str]:
    """The kinematic calibration the request selects (:mod:`bench.calibration.compensate`) and why, decided before
    anything opens; a resumed run keeps its own unless another is named."""
    choice = request.kinematic_calibration
    if stored and choice == NEWEST:
        choice = (stored.get("kinematic_calibration") or {}).get("id")
        if choice is None:
            return None, "the run was made without one"
    return choose_calibration(store, robot, choice, serial, fixture, simulated)


def _true_geometry_seed(request: RigRequest, stored: dict[str, Any]) -> int | None:
    """The true-geometry seed of the simulated robot; a resumed run keeps its own (another is refused)."""
    own = stored.get("simulator", {}).get("true_geometry_seed")
    if request.true_geometry_seed is None:
        return own
    if stored and request.true_geometry_seed != own:
        raise ConfigError(
            f"--true-geometry-seed {request.true_geometry_seed}: the run was made with "
            f"{own}, expected the same (leave it out)"
        )
    return request.true_geometry_seed


def open_mover(request: RigRequest, robot: str) -> tuple[Any, Any]:
    """Only the robot ``request`` describes (for jogging): its mover and the function that releases everything."""
    station = _station(request, robot, "assembled")
    if station is None:
        from bench.simulators.rig import simulated_rig

        seed, speed = _simulation_settings(request, {})
        rig = simulated_rig(robot, seed=seed, speed_factor=speed)
        return rig.robot, rig.close
    if not request.simulate:
        return builder_open_mover(station)
    (mover, close), rehearsal, _ = _on_rehearsal(
        station, request, {}, lambda devices, speed: builder_open_mover(devices)
    )

    def close_all() -> None:
        close()
        rehearsal.close()

    return mover, close_all


def _on_rehearsal(
    station: Station,
    request: RigRequest,
    stored: dict[str, Any],
    build: Callable[[Station, float], Any],
    *,
    default_speed: float = DEFAULT_SPEED_FACTOR,
) -> tuple[Any, Any, int]:
    """Start a simulator for every device of ``station`` and ``build(simulated station, speed factor)`` on them;
    returns what was built, the rehearsal (the caller closes it with what it built) and the seed. The simulators
    are stopped again when the build fails."""
    from bench.simulators.station import rehearse

    seed, speed = _simulation_settings(request, stored, default_speed)
    rehearsal = rehearse(
        station,
        seed=seed,
        speed_factor=speed,
        ideal=request.ideal or bool(stored.get("simulator", {}).get("ideal")),
        true_geometry_seed=_true_geometry_seed(request, stored),
    )
    try:
        return build(rehearsal.station, speed), rehearsal, seed
    except BaseException:
        rehearsal.close()
        raise


def _rehearsal_speed_factor(station: Station, requires: frozenset[str]) -> float:
    """A rehearsal's speed factor unless one is asked: :data:`DEFAULT_SPEED_FACTOR`, or no more than a station
    sensor's :attr:`bench.sensor_kinds.SensorKind.stream_speed_factor` when the protocol streams from it
    (``arrival``), so its windows hold the moves."""
    from bench.sensor_kinds import sensor_kind

    streamed = set(requires) & {"arrival"}
    limits = [
        kind.stream_speed_factor
        for kind in map(sensor_kind, station.sensors)
        if kind.stream_speed_factor is not None and streamed & set(kind.provides)
    ]
    return min([DEFAULT_SPEED_FACTOR, *limits])


def _simulation_settings(
    request: RigRequest, stored: dict[str, Any], default_speed: float = DEFAULT_SPEED_FACTOR
) -> tuple[int, float]:
    """Seed and speed factor of the simulators (``default_speed`` unless asked or stored). A resumed run keeps its own (``stored``): a different value would
    mix two simulated robots, or two time bases, in one run, so it is refused."""
    stored_seed = stored.get("simulator", {}).get("seed")
    stored_speed = stored.get("speed_factor")
    if stored and request.seed is not None and stored_seed is not None and request.seed != stored_seed:
        raise ConfigError(
            f"seed = {request.seed}: the run was made with seed {stored_seed}, expected the same "
            "(a resume keeps the run's own; leave the seed out)"
        )
    if (
        stored
        and request.speed_factor is not None
        and stored_speed is not None
        and request.speed_factor != stored_speed
    ):
        raise ConfigError(
            f"speed factor = {request.speed_factor:g}: the run's time base is speed factor "
            f"{stored_speed:g}, expected the same (leave the speed factor out)"
        )
    seed = request.seed if request.seed is not None else (stored_seed if stored_seed is not None else 0)
    speed = request.speed_factor if request.speed_factor is not None else (stored_speed or default_speed)
    check_speed_factor(speed)
    return seed, speed


def check_speed_factor(speed: float) -> None:
    """Refuse a speed factor that is not a finite number > 0, naming the option (before any file or port opens).

    Raises
    ------
    ConfigError
    """
    if not 0 < speed < float("inf"):
        raise ConfigError(
            f"speed factor = {speed:g}, expected a finite number > 0 (--speed-factor, how much faster "
            "than real time the simulators run)"
        )


def _station(request: RigRequest, robot: str, fixture: str) -> Station | None:
    """The station named by ``request.station``, or the one the port and the mice describe, or None."""
    mice_named = request.mouse_xy or request.mouse_xz or request.mouse_xz_mount
    if mice_named and request.port is None:
        # the mice of a station are its [mice] table; the simulator has its own: never ignore what was named
        where = "a station (its [mice] table names them)" if request.station else "the simulator"
        raise ConfigError(f"mice: named with {where}, expected them with a {request.port_label} only")
    if request.station:
        return load_station(request.station)
    if request.port is None:
        return None
    table: dict[str, Any] = {
        "robot": {"kind": robot},
        "controller": {"port": request.port, "fixture": fixture},
        "calliper": {"kind": "typed"},
    }
    if request.mouse_xy or request.mouse_xz:
        if not (request.mouse_xy and request.mouse_xz):
            raise ConfigError("mice: only one mouse named, expected two event devices (the x-y and the x-z mouse)")
        table["mice"] = {"xy": request.mouse_xy, "xz": request.mouse_xz}
        if request.mouse_xz_mount is not None:
            table["mice"]["xz_mount"] = request.mouse_xz_mount
    elif request.mouse_xz_mount is not None:
        raise ConfigError(
            "mice: an x-z mount given without mice, expected two event devices (the x-y and the x-z mouse)"
        )
    return parse_station(table, source=request.port_label)


def simulated_rig_in(
    store: Any,
    robot: str,
    *,
    seed: int,
    speed_factor: float,
    fixture: str = "assembled",
    true_geometry_seed: int | None = None,
    ideal: bool = False,
    kernel_wait_s: float = 0.0,
):
    """A simulated rig whose mouse calibration is recorded (get-or-create) in ``store``; with
    ``true_geometry_seed`` the pkm5 moves by that seed's true geometry, ``ideal`` without the error model (both
    recorded in the simulator settings); ``kernel_wait_s``: the assembled pkm5's simulator serves its port once its
    compiled kernel is loaded, or after that long (:data:`CAMPAIGN_KERNEL_WAIT_S` for a timed campaign)."""
    from bench.simulators.rig import simulated_rig

    check_speed_factor(speed_factor)
    if true_geometry_seed is not None and fixture != "assembled":
        raise ConfigError(
            f"--true-geometry-seed {true_geometry_seed}: the {fixture} has no geometry, expected the assembled robot"
        )
    options = () if true_geometry_seed is None else ("--true-geometry-seed", str(true_geometry_seed))
    if kernel_wait_s > 0 and robot == "pkm5" and fixture == "assembled":
        options += ("--kernel-wait-s", f"{kernel_wait_s:g}")
    rig = simulated_rig(robot, seed=seed, speed_factor=speed_factor, fixture=fixture, options=options, ideal=ideal)
    rig.simulator = SimulatorRecord(seed, ideal=ideal, true_geometry_seed=true_geometry_seed)
    if fixture == "actuator-bench":
        return rig  # no calibration in force: the readings are typed-in gauge values
    if robot == "pkm5":
        params = {"cpi": rig.instrument.cpi, "mm_per_count": MM_PER_INCH / rig.instrument.cpi}
        rig.calibration_ids = (
            store.ensure_calibration(
                rig.instrument.calibration.calibration_id, params, notes="nominal calibration of the simulated mice"
            ).id,
        )
    else:
        rig.calibration_ids = (rig.instrument.record_geometry(store),)
    return rig
