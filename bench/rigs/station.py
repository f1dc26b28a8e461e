"""Station files: one TOML file describes one physical bench, the way a lab describes its instruments once.

Modelled on QCoDeS station files and bluesky profiles: the robot and its controller port, each sensor with its
device and role, and who and what is being tested. :func:`load_station` validates the whole file before anything
is opened; every problem is one line naming the key, the value and what was expected (unknown keys included, so a
typo never silently drops a device). A station says what it *can* do as capabilities (:meth:`Station.capabilities`);
a protocol asks for capabilities (:func:`bench.protocols.plan.required_capabilities`) and the rig builder refuses a
station that lacks one before anything moves, naming the station key that would provide it.

The tables of sensors (``[mice]``, ``[camera]``, ``[laser_grid]``, ``[calliper]``, and any other) are those of the
sensor registry (:mod:`bench.sensor_kinds`): each is read by the spec parser its record names, into
:attr:`Station.sensors`, and gives the capabilities its record lists.

Example (``examples/stations/`` holds one per seed setup)::

    [station]
    name = "lab-a-pkm5"            # the bench's name, stored with every run
    lab = "Robotics lab A"
    operator = "J. Doe"

    [robot]
    kind = "pkm5"                  # pkm5 | delta4
    serial = "PKM5-0001"           # device under test, for the report
    asset = "INV-4711"

    [controller]
    port = "/dev/serial/by-id/usb-Arduino_Mega_2560-if00"
    baud = 115200                  # default: the robot's documented rate (pkm5 115200, delta4 9600)
    fixture = "assembled"          # or "actuator-bench": the pkm5's actuators free-standing

    [mice]                         # the dissertation's two optical mice (pkm5 pose tests)
    xy = "/dev/input/by-id/usb-Logitech_M100-event-mouse"   # measures x and y
    xz = "/dev/input/by-id/usb-Dell_MS116-event-mouse"      # measures x and z
    cpi = 800                      # nominal resolution, in force unless a stored calibration is named:
    calibration = 3                # the stored mouse calibration version in force (bench store calibrations)
    xz_mount = "guided"            # the x-z mouse on vertical guides, pushed by the end effector: sees z only
                                   # (default "platform": it rides the end effector and sees x and z)

    [calliper]                     # readings the operator takes
    kind = "typed"                 # typed | serial
    resolution_mm = 0.01

    [lab_store]                    # the lab's PostgreSQL store (docs/lab-store.md)
    url = "postgresql://bench@lab-server/lab"   # password from ~/.pgpass or PGPASSWORD, or in the URL
    auto_sync = true               # sync after every run ends (default); false: only `bench sync`
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, overload

from bench.errors import ConfigError
from bench.robot_kinds import robot_kind, robot_names
from bench.sensor_kinds import SENSOR_KINDS, capability_sources, sensor_kind, sensor_names

__all__ = [
    "ControllerSpec",
    "Identity",
    "LabStoreSpec",
    "Station",
    "StationTable",
    "capability_source",
    "capture_capabilities",
    "load_station",
    "parse_station",
    "station_identity",
]

#: Every fixture a controller can be in; which a robot supports is its registry record's ``fixtures``.
FIXTURES = ("assembled", "actuator-bench")

#: The baud rates a serial port takes: pySerial's span on Linux (custom rates between them too); beyond it an
#: opening fails deep in termios (2**63 baud overflowed its ioctl with a traceback), 0 hangs the line up.
BAUD_RANGE = (50, 4_000_000)

#: The capabilities a fixture provides, and the key that provides it; the sensors' are in their registry records.
_FIXTURE_CAPABILITIES = {
    "actuator_bench": '[controller] fixture = "actuator-bench"',
    "assembled": '[controller] fixture = "assembled"',
}


def capability_source(capability: str) -> str:
    """The station key that provides ``capability`` (named when a protocol needs it): a fixture, or the tables of the
    registered sensors that provide it (:func:`bench.sensor_kinds.capability_sources`); ``""`` when none does."""
    return _FIXTURE_CAPABILITIES.get(capability) or capability_sources(capability)


def capture_capabilities() -> frozenset[str]:
    """The capabilities a capture needs (the others are readings and fixtures): those of the registered sensors
    that open as the rig's instrument. A rig without one has no instrument."""
    return frozenset(need for kind in SENSOR_KINDS.values() if kind.instrument is not None for need in kind.provides)


def _fail(source: str, key: str, value: Any, expected: str) -> ConfigError:
    return ConfigError(f"{source}: {key} = {value!r}, expected {expected}")


class StationTable:
    """Reads one table of the station file, refusing unknown keys and wrong types with the full key path (a
    sensor's spec parser reads its table with it: :attr:`bench.sensor_kinds.SensorKind.spec`)."""

    def __init__(self, source: str, name: str, data: Any) -> None:
        if not isinstance(data, Mapping):
            raise _fail(source, f"[{name}]", data, "a table")
        self.source, self.name, self.data = source, name, dict(data)
        self.used: set[str] = set()

    def _key(self, key: str) -> str:
        return f"{self.name}.{key}"

    def fail(self, key: str, value: Any, expected: str) -> ConfigError:
        """The one-line error for ``key = value`` of this table, saying what was ``expected``."""
        return _fail(self.source, self._key(key), value, expected)

    def get(
        self,
        key: str,
        kind: type | tuple[type, ...],
        default: Any = None,
        *,
        required: bool = False,
        expected: str = "",
        blank_ok: bool = False,
    ) -> Any:
        self.used.add(key)
        if key not in self.data:
            if required:
                raise ConfigError(f"{self.source}: {self._key(key)} missing, expected {expected or _kind_text(kind)}")
            return default
        value = self.data[key]
        kinds = kind if isinstance(kind, tuple) else (kind,)
        if isinstance(value, bool) and bool not in kinds or not isinstance(value, kinds):
            raise _fail(self.source, self._key(key), value, expected or _kind_text(kind))
        if isinstance(value, str) and not value.strip() and not blank_ok:
            raise _fail(self.source, self._key(key), value, expected or "a non-empty string")
        return value

    @overload
    def number(self, key: str, default: float, *, zero_allowed: bool = False) -> float: ...

    @overload
    def number(self, key: str, default: None, *, zero_allowed: bool = False) -> float | None: ...

    def number(self, key: str, default: float | None, *, zero_allowed: bool = False) -> float | None:
        expected = "a finite number >= 0" if zero_allowed else "a finite number > 0"
        value = self.get(key, (int, float), default, expected=expected)
        if value is not None and not ((value >= 0 if zero_allowed else value > 0) and value < float("inf")):
            raise _fail(self.source, self._key(key), value, expected)
        return None if value is None else float(value)

    def baud(self, key: str, default: int) -> int:
        """A serial port's baud rate, an integer in :data:`BAUD_RANGE`."""
        expected = f"a baud rate, an integer from {BAUD_RANGE[0]} to {BAUD_RANGE[1]:,}"
        value = self.get(key, int, default, expected=expected)
        if not BAUD_RANGE[0] <= value <= BAUD_RANGE[1]:
            raise _fail(self.source, self._key(key), value, expected)
        return int(value)

    def choice(self, key: str, choices: tuple[str, ...], default: str | None) -> str:
        value = self.get(key, str, default, required=default is None, expected=f"one of {', '.join(choices)}")
        if value not in choices:
            raise _fail(self.source, self._key(key), value, f"one of {', '.join(choices)}")
        return value

    def done(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise ConfigError(
                f"{self.source}: unknown key {self._key(unknown[0])!r}, expected one of {', '.join(sorted(self.used))}"
            )


def _kind_text(kind: type | tuple[type, ...]) -> str:
    names = {str: "a string", int: "an integer", float: "a number", bool: "true or false"}
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join(names.get(k, k.__name__) for k in kinds)


@dataclass(frozen=True)
class Identity:
    """Who tests what: the bench, the lab, the operator and the device under test (for the report)."""

    bench: str
    lab: str = ""
    operator: str = ""
    robot_serial: str = ""
    robot_asset: str = ""
    customer: str = ""
    order: str = ""


@dataclass(frozen=True)
class ControllerSpec:
    port: str
    baud: int
    fixture: str = "assembled"


@dataclass(frozen=True)
class LabStoreSpec:
    """The lab store this bench syncs into: a PostgreSQL URL, and whether every run is synced when it ends."""

    url: str
    auto_sync: bool = True


@dataclass(frozen=True)
class Station:
    """One bench. ``source`` is the file it was read from (for messages)."""

    robot: str
    controller: ControllerSpec
    identity: Identity
    #: station table -> its sensor's spec (:attr:`bench.sensor_kinds.SensorKind.spec`), in registration order
    sensors: dict[str, Any] = field(default_factory=dict, hash=False)
    lab_store: LabStoreSpec | None = None  #: never stored with the runs (its URL may hold a password)
    source: str = "station"
    simulated: bool = False  #: every device is a simulator standing in for the one named (``bench run --sim``)
    devices: dict[str, str] = field(default_factory=dict, compare=False)  #: station key -> device as written

    def sensor(self, name: str) -> Any:
        """The spec of the station's ``[name]`` sensor, or None when it names none."""
        return self.sensors.get(name)

    def with_sensor(self, name: str, **changes: Any) -> Station:
        """This station with fields of its ``[name]`` spec changed (``with_sensor("mice", xz="/dev/input/event7")``)."""
        return replace(self, sensors={**self.sensors, name: replace(self.sensors[name], **changes)})

    def capabilities(self) -> frozenset[str]:
        """What runs on this station: its fixture's, and those of its sensors that measure on its robot in its
        fixture (:attr:`bench.sensor_kinds.SensorKind.provides`)."""
        found = {self.controller.fixture.replace("-", "_")}
        for name in self.sensors:
            kind = sensor_kind(name)
            if kind.serves(self.robot, self.controller.fixture):
                found |= set(kind.provides)
        return frozenset(found)

    def missing(self, required: frozenset[str] | set[str]) -> list[str]:
        """The capabilities of ``required`` this station lacks, each with the key that would provide it."""
        lacking = sorted(set(required) - self.capabilities())
        return [
            f"{need} (add {capability_source(need)})" if capability_source(need) else f"{need} (no sensor provides it)"
            for need in lacking
        ]

    def settings(self) -> dict[str, Any]:
        """What a run stores about its station (devices as named in the file, identity)."""
        out: dict[str, Any] = {
            "source": self.source,
            "robot": self.robot,
            "simulated": self.simulated,
            "identity": {f.name: getattr(self.identity, f.name) for f in fields(Identity)},
            "controller": vars(self.controller),
        }
        for name, spec in self.sensors.items():
            out[name] = vars(spec)
        return out


def station_identity(station: Station) -> dict[str, str]:
    """The device under test and the people, as the report's page 1 reads them (``settings.dut``)."""
    identity = station.identity
    fields = {
        "dut_serial": identity.robot_serial or identity.robot_asset,
        "customer": identity.customer,
        "order": identity.order,
        "operator": identity.operator,
        "laboratory": identity.lab,
    }
    return {key: value for key, value in fields.items() if value}


def load_station(path: str | Path) -> Station:
    """Read and validate a station file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the station file ({getattr(exc, 'strerror', None) or exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not a valid TOML station file ({exc})") from None
    return parse_station(data, source=str(path))


def parse_station(data: Mapping[str, Any], *, source: str = "station") -> Station:
    """Validate a parsed station file; see the module docstring for the keys."""
    known = ("station", "robot", "controller", *sensor_names(), "lab_store")
    unknown = sorted(set(data) - set(known))
    if unknown:
        shown = repr(unknown[0])[1:-1]  # a quoted TOML name may hold a line break: escaped, the message stays one line
        raise ConfigError(
            f"{source}: unknown table [{shown}], expected one of {', '.join('[' + k + ']' for k in known)}"
        )
    for required, example in (("robot", 'kind = "pkm5" or "delta4"'), ("controller", 'port = "/dev/ttyUSB0"')):
        if required not in data:
            raise ConfigError(f"{source}: [{required}] missing, expected a table ({example})")
    head = StationTable(source, "station", data.get("station", {}))
    robot_table = StationTable(source, "robot", data["robot"])
    robot = robot_table.choice("kind", robot_names(), None)
    identity = Identity(
        bench=head.get("name", str, Path(source).stem),
        lab=head.get("lab", str, ""),
        operator=head.get("operator", str, ""),
        robot_serial=robot_table.get("serial", str, ""),
        robot_asset=robot_table.get("asset", str, ""),
        customer=head.get("customer", str, ""),
        order=head.get("order", str, ""),
    )
    head.done()
    robot_table.done()

    table = StationTable(source, "controller", data["controller"])
    controller = ControllerSpec(
        port=table.get("port", str, required=True, expected="a serial port, e.g. /dev/ttyUSB0"),
        baud=table.baud("baud", robot_kind(robot).baud),
        fixture=table.choice("fixture", FIXTURES, "assembled"),
    )
    table.done()
    if controller.fixture not in robot_kind(robot).fixtures:
        raise _fail(
            source,
            "controller.fixture",
            controller.fixture,
            f"one of the {robot}'s fixtures: {', '.join(robot_kind(robot).fixtures)}",
        )
    devices = {"controller.port": controller.port}

    sensors: dict[str, Any] = {}
    for kind in SENSOR_KINDS.values():
        if kind.name not in data:
            continue
        if kind.robots is not None and robot not in kind.robots:
            raise ConfigError(
                f"{source}: [{kind.name}] with robot.kind = {robot!r}, expected robot.kind = "
                + " or ".join(repr(r) for r in kind.robots)
                + (f" ({kind.robots_why})" if kind.robots_why else "")
            )
        table = StationTable(source, kind.name, data[kind.name])
        sensors[kind.name] = kind.resolved("spec")(table)
        table.done()
        devices.update(kind.named_devices(sensors[kind.name]))
    lab_store = None
    if "lab_store" in data:
        table = StationTable(source, "lab_store", data["lab_store"])
        expected = "a postgresql://USER@HOST/DBNAME URL"
        url = table.get("url", str, required=True, expected=expected)
        from bench.store.lab import check_lab_url  # (psycopg only for a station with a lab store)

        check_lab_url(url, f"{source}: lab_store.url =")  # one line, the password hidden
        lab_store = LabStoreSpec(url=url, auto_sync=table.get("auto_sync", bool, True))
        table.done()
    named: dict[str, str] = {}
    for key, device in devices.items():
        if device in named:
            raise ConfigError(
                f"{source}: {key} = {device!r}, expected a device of its own ({named[device]} names it too)"
            )
        named[device] = key
    return Station(
        robot=robot,
        controller=controller,
        identity=identity,
        sensors=sensors,
        lab_store=lab_store,
        source=source,
        devices=devices,
    )
