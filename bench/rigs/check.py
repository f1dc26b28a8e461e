"""``bench station check``: open every device a station names, identify or read it once, and say per device
whether it is usable and, when not, what fixes it (the udev rule, the group, the cable)."""

from __future__ import annotations

import errno
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bench.errors import BenchError, LinkTimeout
from bench.rigs.station import Station
from bench.robots.link import open_port
from bench.sensor_kinds import sensor_kind

__all__ = ["DeviceCheck", "check_station", "guarded"]

_SERIAL_FIX = (
    "add yourself to the 'dialout' group (sudo usermod -aG dialout $USER, then log in again) or install "
    "the udev rule of docs/real-bench.md"
)
_INPUT_FIX = (
    "add yourself to the 'input' group (sudo usermod -aG input $USER, then log in again) or install the "
    "udev rule of docs/real-bench.md"
)


@dataclass(frozen=True)
class DeviceCheck:
    key: str  #: the station key, e.g. ``mice.xy``
    device: str
    ok: bool
    detail: str
    fix: str = ""

    def line(self) -> str:
        status = "ok" if self.ok else "problem"
        return f"{self.key:<16} {status:<8} {self.device}: {self.detail}" + (f" -> fix: {self.fix}" if self.fix else "")

    def as_dict(self) -> dict[str, Any]:
        return {"key": self.key, "device": self.device, "ok": self.ok, "detail": self.detail, "fix": self.fix}


def _missing_fix(path: str, kind: str) -> str:
    if kind == "input":
        return (
            "plug the mouse in and name it by /dev/input/by-id/... (ls -l /dev/input/by-id; bench sensors mouse-list)"
        )
    return "plug the controller in and name it by /dev/serial/by-id/... (ls -l /dev/serial/by-id)"


def _os_problem(key: str, path: str, exc: BaseException, kind: str) -> DeviceCheck:
    cause = exc.__cause__ if isinstance(exc.__cause__, OSError) else exc
    code = getattr(cause, "errno", None)
    if code in (errno.EACCES, errno.EPERM):
        return DeviceCheck(key, path, False, "permission denied", _INPUT_FIX if kind == "input" else _SERIAL_FIX)
    if code == errno.ENOENT or not os.path.exists(path):
        return DeviceCheck(key, path, False, "no such device", _missing_fix(path, kind))
    if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "exclusive" in str(exc).lower():
        return DeviceCheck(key, path, False, f"busy ({exc})", "close the program that holds it (fuser -v " + path + ")")
    return DeviceCheck(key, path, False, str(exc).splitlines()[0], "")


def guarded(key: str, path: str, kind: str, probe: Callable[[], str]) -> DeviceCheck:
    """``probe()``'s answer as a usable device, or the problem it raised with its fix (``kind``: ``serial``,
    ``input`` or ``video``, for the fix's wording)."""
    try:
        return DeviceCheck(key, path, True, probe())
    except (BenchError, OSError) as exc:
        return _os_problem(key, path, exc, kind)


def check_station(station: Station) -> list[DeviceCheck]:
    """One :class:`DeviceCheck` per device of ``station``, each opened, identified or read once and closed: the
    controller here, each sensor by the check its record names (:attr:`bench.sensor_kinds.SensorKind.check`)."""
    checks = [guarded("controller.port", station.controller.port, "serial", lambda: _controller(station))]
    for name, spec in station.sensors.items():
        kind = sensor_kind(name)
        if kind.check is not None:
            checks += kind.resolved("check")(station, spec)
    return checks


def _controller(station: Station) -> str:
    port = open_port(station.controller.port, baudrate=station.controller.baud, timeout=0.05, exclusive=True)
    try:
        if station.robot == "pkm5":
            from bench.robots.pkm5 import Pkm5Controller

            identity = Pkm5Controller(port).identify()
            return f"{identity.device} firmware {identity.firmware_version}, protocol v{identity.protocol_version}"
        from bench.robots.delta4 import Delta4Controller

        controller = Delta4Controller(port)
        frame = controller.start()
        detail = f"delta4 controller answering at {station.controller.baud} baud"
        if station.sensor("laser_grid") is not None:
            detail += f"; laser grid reporting ({len(frame.horizontal)} + {len(frame.vertical)} sensors lit)"
        try:  # this project's firmware reads the pots back; the documented original sends them nowhere (§7.3.4)
            pots = controller.read_pots()
            detail += "; pots at " + ", ".join(f"{deg:.1f}" for deg in pots.servo_deg) + " deg"
        except LinkTimeout:
            detail += "; no pot readback (firmware without the A query: positions are not read back)"
        fine = controller.probe_fine_references()
        detail += (
            f"; fine servo references ({fine.step_deg():.5f} deg a step)"
            if fine is not None
            else "; byte servo references only (no answer to C)"
        )
        controller.shutdown()
        return detail
    finally:
        port.close()
