"""The registry of sensor kinds: one record per kind of instrument a station can name, the one place that lists them.

Every part of bench that treats sensors differently asks this registry: the station file (its table, the spec's
parser, the devices it names, the robots and fixtures it serves, the capabilities it gives), the rig builder (the
opener of its instrument or of the operator that answers readings, whether the robot is homed first and the frame
registered), ``bench station check`` (its device check), a rehearsal (``--sim``: the simulator that stands in for
it) and the store (the columns, with units, its captures add to a sample kind). A record names code of higher
layers by ``"module:attribute"`` strings, resolved on first use, so listing the sensors imports nothing heavy and this
module imports no layer of bench (:mod:`bench.robot_kinds` is its model).

Adding a sensor (docs/extending.md): write its driver (``bench/sensors/<sensor>.py``), its instrument and station
table (``bench/rigs/<sensor>.py``: a spec dataclass with its parser, an opener, a check), its stand-in
(``bench/simulators/``), then register it with one :func:`register` call below. ``tests/test_sensor_kinds.py`` adds
a toy sensor through :func:`register` alone and runs a rehearsed protocol with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.columns import Column
from bench.errors import ConfigError
from bench.robot_kinds import resolve_field

__all__ = [
    "SENSOR_KINDS",
    "SensorKind",
    "capability_sources",
    "register",
    "sensor_columns",
    "sensor_kind",
    "sensor_names",
]


@dataclass(frozen=True)
class SensorKind:
    """What bench needs to know about one kind of sensor.

    Attributes
    ----------
    name : str
        Its station table (``[mice]``), the key of its settings in a run, and the prefix of its device keys
        (``mice.xy``).
    title : str
        What it is, in a line.
    spec : str
        ``"module:callable"`` ``(table: bench.rigs.station.StationTable) -> spec``: reads its station table (every
        key checked, one line per mistake) into a frozen spec dataclass.
    provides : tuple of str
        The capabilities it gives a station (``pose``, ``arrival``, ``grid_hit``, ``reading``, ...): what a protocol's
        captures and prompts ask for (:func:`bench.protocols.plan.required_capabilities`).
    robots : tuple of str or None
        The robots it serves (None: any); a station of another robot that names it is refused, with ``robots_why``.
    robots_why : str
        Why only those robots, for that refusal.
    fixtures : tuple of str or None
        The controller fixtures it measures in (None: any); in another it is neither opened nor a capability.
    devices : tuple of str
        The spec's attributes that name a device (a port, an event device, a video device); an empty one names none.
    instrument : str or None
        ``"module:callable"`` ``(opening: bench.rigs.opening.SensorOpening) -> Instrument``: opens it as the rig's
        instrument (captures). Where a station names several, the first registered is the rig's.
    operator : str or None
        ``"module:callable"`` ``(opening, operator) -> Operator``: a sensor that answers reading prompts (a serial
        calliper) wraps the operator.
    zeroed_at_home : bool
        Its frame starts at the robot's home: the builder brings the robot home before opening it.
    relative : bool
        It measures displacement only: registered at home and verified at the check pose before anything is stored
        (:mod:`bench.rigs.registration`).
    check : str or None
        ``"module:callable"`` ``(station, spec) -> list[bench.rigs.check.DeviceCheck]`` for ``bench station check``.
    stand_in : str or None
        ``"module:callable"`` ``(station, spec, *, folder, truth_path) -> (spec, simulator options)``: its simulator
        in a rehearsal (``--sim``), a spec naming the simulated device and the robot simulator's options it needs.
    columns : tuple of Column
        The value columns (unit in the name) its captures add to the samples of ``sample_kinds``.
    sample_kinds : tuple of str
        The sample kinds whose samples may carry ``columns``.
    stream_speed_factor : float or None
        The highest speed factor at which its stand-in's streamed captures (``arrival``) hold the move: they count
        the rig's seconds, in which the host's turnaround after a move lasts the factor times its wall time. A
        rehearsal of a protocol that streams runs at most this fast unless ``--speed-factor`` says otherwise.
    """

    name: str
    title: str
    spec: str
    provides: tuple[str, ...] = ()
    robots: tuple[str, ...] | None = None
    robots_why: str = ""
    fixtures: tuple[str, ...] | None = None
    devices: tuple[str, ...] = ()
    instrument: str | None = None
    operator: str | None = None
    zeroed_at_home: bool = False
    relative: bool = False
    check: str | None = None
    stand_in: str | None = None
    columns: tuple[Column, ...] = ()
    sample_kinds: tuple[str, ...] = ("pose",)
    stream_speed_factor: float | None = None

    def resolved(self, field: str) -> Any:
        """The object a ``"module:attribute"`` field names (``kind.resolved("spec")(table)``)."""
        return resolve_field(self, field, f"sensor {self.name!r}")

    def named_devices(self, spec: Any) -> dict[str, str]:
        """The devices ``spec`` names, by station key (``{"mice.xy": "/dev/input/..."}``)."""
        return {f"{self.name}.{attr}": str(getattr(spec, attr)) for attr in self.devices if getattr(spec, attr)}

    def serves(self, robot: str, fixture: str) -> bool:
        """Whether it measures on ``robot`` in ``fixture``."""
        return (self.robots is None or robot in self.robots) and (self.fixtures is None or fixture in self.fixtures)


#: Name -> record, in registration order (the order stations list them and the builder prefers instruments).
SENSOR_KINDS: dict[str, SensorKind] = {}


def register(kind: SensorKind) -> SensorKind:
    """Add ``kind`` to the registry (a name registered twice with another record is a mistake: refused)."""
    if kind.name in SENSOR_KINDS and SENSOR_KINDS[kind.name] != kind:
        raise ValueError(f"sensor kind {kind.name!r} is registered already")
    SENSOR_KINDS[kind.name] = kind
    return kind


def sensor_names() -> tuple[str, ...]:
    """The registered sensors' station tables, in registration order."""
    return tuple(SENSOR_KINDS)


def sensor_kind(name: str) -> SensorKind:
    """The record of sensor ``name``; :class:`ConfigError` lists the known sensors."""
    try:
        return SENSOR_KINDS[name]
    except KeyError:
        raise ConfigError(f"sensor {name!r}: expected one of {', '.join(SENSOR_KINDS)}") from None


def sensor_columns(sample_kind: str) -> tuple[Column, ...]:
    """The columns registered sensors add to samples of ``sample_kind``, in registration order."""
    return tuple(c for kind in SENSOR_KINDS.values() if sample_kind in kind.sample_kinds for c in kind.columns)


def capability_sources(capability: str) -> str:
    """The station tables that provide ``capability``, as a message names them: ``[mice] (pkm5), [camera], or
    [laser_grid] (delta4)`` (the robots named only where several tables provide it), or ``""`` for none."""
    sources = [kind for kind in SENSOR_KINDS.values() if capability in kind.provides]
    named = [
        f"[{kind.name}]" + (f" ({', '.join(kind.robots)})" if kind.robots and len(sources) > 1 else "")
        for kind in sources
    ]
    if len(named) < 2:
        return "".join(named)
    return ", ".join(named[:-1]) + (", or " if len(named) > 2 else " or ") + named[-1]


# --- the registrations: one call per sensor --------------------------------------------------------------------

register(
    SensorKind(
        name="mice",
        title="two optical mice, x-y and x-z (the dissertation's instrument)",
        spec="bench.rigs.mice_station:parse_mice",
        provides=("pose", "mouse_counts", "arrival"),
        robots=("pkm5",),
        robots_why="the mice are mounted on the pkm5's platform",
        fixtures=("assembled",),
        devices=("xy", "xz"),
        instrument="bench.rigs.mice_station:open_mice",
        zeroed_at_home=True,
        relative=True,
        check="bench.rigs.mice_station:check_mice",
        stand_in="bench.simulators.mice_feed:stand_in",
        columns=tuple(
            Column(
                f"mouse_{plane}_{axis}_counts",
                "counts",
                "float",
                f"accumulated counts of the {plane} mouse along {axis}",
            )
            for plane, axis in (("xy", "x"), ("xy", "y"), ("xz", "x"), ("xz", "z"))
        ),
        sample_kinds=("mouse",),
        # a few ms of host turnaround x 20 is a tenth of a 2 s path segment
        stream_speed_factor=20.0,
    )
)

register(
    SensorKind(
        name="camera",
        title="a camera watching a laser spot on a plane (sensors.md §7)",
        spec="bench.rigs.camera:parse_camera",
        provides=("pose",),
        devices=("device",),
        instrument="bench.rigs.camera:open_camera",
        zeroed_at_home=True,
        check="bench.rigs.camera:check_camera",
        stand_in="bench.simulators.camera_feed:stand_in",
    )
)

register(
    SensorKind(
        name="laser_grid",
        title="the delta4's laser grid, read by its controller",
        spec="bench.rigs.lasergrid:parse_laser_grid",
        provides=("pose", "grid_hit"),
        robots=("delta4",),
        robots_why="the grid is read by the delta4 controller",
        instrument="bench.rigs.lasergrid:open_laser_grid",
        columns=(
            Column("horizontal_valid", "1", "int", "laser grid: 1 when the horizontal screen decoded", False),
            Column("vertical_valid", "1", "int", "laser grid: 1 when the vertical screen decoded", False),
            Column("horizontal_hits", "1", "int", "laser grid: lasers lit on the horizontal screen", False),
            Column("vertical_hits", "1", "int", "laser grid: lasers lit on the vertical screen", False),
            Column("y_disagreement_mm", "mm", "float", "laser grid: difference of the two screens' y readings", False),
        ),
    )
)

register(
    SensorKind(
        name="calliper",
        title="a calliper or depth gauge: readings typed at the prompt, or sent by a serial gauge",
        spec="bench.rigs.gauges:parse_calliper",
        provides=("reading",),
        devices=("port",),
        operator="bench.rigs.gauges:calliper_operator",
        check="bench.rigs.gauges:check_calliper",
        stand_in="bench.simulators.calliper:stand_in",
    )
)
