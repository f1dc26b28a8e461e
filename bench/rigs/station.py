"""Station files: one TOML file describes one physical bench, the way a lab describes its instruments once.

Modelled on QCoDeS station files and bluesky profiles: the robot and its controller port, each sensor with its
device and role, and who and what is being tested. :func:`load_station` validates the whole file before anything
is opened; every problem is one line naming the key, the value and what was expected (unknown keys included, so a
typo never silently drops a device). A station says what it *can* do as capabilities (:meth:`Station.capabilities`);
a protocol asks for capabilities (:func:`bench.protocols.plan.required_capabilities`) and the rig builder refuses a
station that lacks one before anything moves, naming the station key that would provide it.

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

__all__ = [
    "CAPABILITY_KEYS",
    "CAPTURE_CAPABILITIES",
    "CalliperSpec",
    "CameraSpec",
    "ControllerSpec",
    "Identity",
    "LabStoreSpec",
    "LaserGridSpec",
    "MiceSpec",
    "Station",
    "load_station",
    "parse_station",
    "station_identity",
]

#: Every fixture a controller can be in; which a robot supports is its registry record's ``fixtures``.
FIXTURES = ("assembled", "actuator-bench")
CALLIPER_KINDS = ("typed", "serial")

#: What a station can provide, and the station key that provides it (named when a protocol needs it).
CAPABILITY_KEYS = {
    "pose": "[mice] (pkm5), [camera], or [laser_grid] (delta4)",
    "mouse_counts": "[mice]",
    "arrival": "[mice]",
    "grid_hit": "[laser_grid]",
    "reading": "[calliper]",
    "actuator_bench": '[controller] fixture = "actuator-bench"',
    "assembled": '[controller] fixture = "assembled"',
}


#: The capabilities a capture needs (the others are readings and fixtures): a rig without one has no instrument.
CAPTURE_CAPABILITIES = frozenset({"pose", "mouse_counts", "arrival", "grid_hit"})


def _fail(source: str, key: str, value: Any, expected: str) -> ConfigError:
    return ConfigError(f"{source}: {key} = {value!r}, expected {expected}")


class _Table:
    """Reads one table of the station file, refusing unknown keys and wrong types with the full key path."""

    def __init__(self, source: str, name: str, data: Any) -> None:
        if not isinstance(data, Mapping):
            raise _fail(source, f"[{name}]", data, "a table")
        self.source, self.name, self.data = source, name, dict(data)
        self.used: set[str] = set()

    def _key(self, key: str) -> str:
        return f"{self.name}.{key}"

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


def _calibration_version(table: _Table) -> int | None:
    """``[mice] calibration``: a stored calibration version, an integer >= 1 (or absent)."""
    expected = "a stored mouse calibration version, an integer >= 1"
    value = table.get("calibration", int, None, expected=expected)
    if value is not None and value < 1:
        raise _fail(table.source, table._key("calibration"), value, expected)
    return value


@dataclass(frozen=True)
class MiceSpec:
    """Two optical mice by event device: ``xy`` measures x and y, ``xz`` measures x and z."""

    xy: str
    xz: str
    cpi: float = 800.0
    noise_counts: float | None = None  #: reading noise per count, when measured; stated in the report's budget
    grab: bool = True  #: take the mice exclusively (EVIOCGRAB) so the desktop pointer does not move
    #: the stored ``mouse`` calibration version in force; None: the nominal ``cpi`` (a stored one is never put in
    #: force because it is the newest)
    calibration: int | None = None


@dataclass(frozen=True)
class CalliperSpec:
    """Readings the operator takes: typed at the prompt, or sent by a serial calliper (data button or request)."""

    kind: str = "typed"
    port: str = ""
    baud: int = 9600
    request: str = ""  #: sent before each reading by interfaces that answer requests; empty for push-button cables
    terminator: str = "\n"
    resolution_mm: float = 0.01
    timeout_s: float = 60.0


@dataclass(frozen=True)
class LaserGridSpec:
    """The delta4's laser grid (its screens are read by the delta4 controller) and the decoder's options."""

    spot_half_width_mm: float = 1.0
    gate_mm: float = 3.75


@dataclass(frozen=True)
class CameraSpec:
    """A camera looking at the laser spot on a plane: ``device`` is a video device, an index or a stream URL;
    ``calibration`` a JSON file with the plane calibration (:class:`bench.sensors.camera_spot.PlaneCalibration`)."""

    device: str
    calibration: str
    plane: str = "xy"  #: the two pose coordinates the camera's plane measures
    #: frames averaged into one reading: the spot centroid's noise falls as 1/sqrt(frames) (a reading that corrects
    #: a command copies its noise into it, so iterative correction to the camera's uncertainty needs a few)
    frames: int = 1


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
    mice: MiceSpec | None = None
    calliper: CalliperSpec | None = None
    laser_grid: LaserGridSpec | None = None
    camera: CameraSpec | None = None
    lab_store: LabStoreSpec | None = None  #: never stored with the runs (its URL may hold a password)
    source: str = "station"
    simulated: bool = False  #: every device is a simulator standing in for the one named (``bench run --sim``)
    devices: dict[str, str] = field(default_factory=dict, compare=False)  #: station key -> device as written

    def capabilities(self) -> frozenset[str]:
        """What runs on this station: the keys of :data:`CAPABILITY_KEYS` it provides."""
        found = {self.controller.fixture.replace("-", "_")}
        if self.mice is not None:
            found |= {"mouse_counts", "arrival"} | ({"pose"} if self.robot == "pkm5" else set())
        if self.camera is not None:
            found.add("pose")
        if self.laser_grid is not None:
            found |= {"grid_hit", "pose"}
        if self.calliper is not None:
            found.add("reading")
        return frozenset(found)

    def missing(self, required: frozenset[str] | set[str]) -> list[str]:
        """The capabilities of ``required`` this station lacks, each with the key that would provide it."""
        return [f"{need} (add {CAPABILITY_KEYS[need]})" for need in sorted(set(required) - self.capabilities())]

    def settings(self) -> dict[str, Any]:
        """What a run stores about its station (devices as named in the file, identity)."""
        out: dict[str, Any] = {
            "source": self.source,
            "robot": self.robot,
            "simulated": self.simulated,
            "identity": {f.name: getattr(self.identity, f.name) for f in fields(Identity)},
            "controller": vars(self.controller),
        }
        for key in ("mice", "calliper", "laser_grid", "camera"):
            spec = getattr(self, key)
            if spec is not None:
                out[key] = vars(spec)
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
    known = ("station", "robot", "controller", "mice", "calliper", "laser_grid", "camera", "lab_store")
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ConfigError(
            f"{source}: unknown table [{unknown[0]}], expected one of {', '.join('[' + k + ']' for k in known)}"
        )
    for required, example in (("robot", 'kind = "pkm5" or "delta4"'), ("controller", 'port = "/dev/ttyUSB0"')):
        if required not in data:
            raise ConfigError(f"{source}: [{required}] missing, expected a table ({example})")
    head = _Table(source, "station", data.get("station", {}))
    robot_table = _Table(source, "robot", data["robot"])
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

    table = _Table(source, "controller", data["controller"])
    controller = ControllerSpec(
        port=table.get("port", str, required=True, expected="a serial port, e.g. /dev/ttyUSB0"),
        baud=int(table.get("baud", int, robot_kind(robot).baud, expected="a baud rate (integer)")),
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

    mice = calliper = grid = camera = None
    if "mice" in data:
        table = _Table(source, "mice", data["mice"])
        mice = MiceSpec(
            xy=table.get("xy", str, required=True, expected="the x-y mouse's event device"),
            xz=table.get("xz", str, required=True, expected="the x-z mouse's event device"),
            cpi=table.number("cpi", 800.0),
            noise_counts=table.number("noise_counts", None, zero_allowed=True),
            grab=table.get("grab", bool, True),
            calibration=_calibration_version(table),
        )
        table.done()
        devices.update({"mice.xy": mice.xy, "mice.xz": mice.xz})
    if "calliper" in data:
        table = _Table(source, "calliper", data["calliper"])
        kind = table.choice("kind", CALLIPER_KINDS, "typed")
        calliper = CalliperSpec(
            kind=kind,
            port=table.get(
                "port", str, "", required=kind == "serial", expected='the calliper\'s serial port (kind = "serial")'
            ),
            baud=int(table.get("baud", int, 9600)),
            request=table.get("request", str, "", blank_ok=True),
            terminator=table.get("terminator", str, "\n", blank_ok=True),
            resolution_mm=table.number("resolution_mm", 0.01),
            timeout_s=table.number("timeout_s", 60.0),
        )
        table.done()
        if kind == "serial":
            devices["calliper.port"] = calliper.port
    if "laser_grid" in data:
        if robot != "delta4":
            raise ConfigError(
                f"{source}: [laser_grid] with robot.kind = {robot!r}, expected robot.kind = 'delta4' "
                "(the grid is read by the delta4 controller)"
            )
        table = _Table(source, "laser_grid", data["laser_grid"])
        grid = LaserGridSpec(
            spot_half_width_mm=table.number("spot_half_width_mm", 1.0), gate_mm=table.number("gate_mm", 3.75)
        )
        table.done()
    if "camera" in data:
        table = _Table(source, "camera", data["camera"])
        camera = CameraSpec(
            device=str(
                table.get("device", (str, int), required=True, expected="a video device, camera index or stream URL")
            ),
            calibration=table.get("calibration", str, required=True, expected="the plane calibration JSON file"),
            plane=table.choice("plane", ("xy", "xz", "yz"), "xy"),
            frames=table.get("frames", int, 1, expected="an integer 1-100 (frames averaged per reading)"),
        )
        if not 1 <= camera.frames <= 100:
            raise _fail(source, "camera.frames", camera.frames, "an integer 1-100 (frames averaged per reading)")
        table.done()
        if not Path(camera.calibration).is_absolute() and source != "station":  # relative to the station file
            camera = replace(camera, calibration=str(Path(source).parent / camera.calibration))
        devices["camera.device"] = camera.device
    lab_store = None
    if "lab_store" in data:
        table = _Table(source, "lab_store", data["lab_store"])
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
        mice=mice,
        calliper=calliper,
        laser_grid=grid,
        camera=camera,
        lab_store=lab_store,
        source=source,
        devices=devices,
    )
