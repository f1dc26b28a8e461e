"""``bench station check``: open every device a station names, identify or read it once, and say per device
whether it is usable and, when not, what fixes it (the udev rule, the group, the cable)."""

from __future__ import annotations

import errno
import functools
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bench.errors import BenchError, LinkTimeout
from bench.rigs.station import Station
from bench.robots.link import open_port

__all__ = ["DeviceCheck", "check_station"]

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


def _guarded(key: str, path: str, kind: str, probe: Callable[[], str]) -> DeviceCheck:
    try:
        return DeviceCheck(key, path, True, probe())
    except (BenchError, OSError) as exc:
        return _os_problem(key, path, exc, kind)


def check_station(station: Station) -> list[DeviceCheck]:
    """One :class:`DeviceCheck` per device of ``station``, each opened, identified or read once and closed."""
    checks = [_guarded("controller.port", station.controller.port, "serial", lambda: _controller(station))]
    mice, calliper, camera = station.mice, station.calliper, station.camera
    if mice is not None:
        for plane, path in (("xy", mice.xy), ("xz", mice.xz)):
            checks.append(_guarded(f"mice.{plane}", path, "input", functools.partial(_mouse, path, mice.grab)))
    if calliper is not None:
        if calliper.kind == "serial":
            probe = functools.partial(_serial_opens, calliper.port, calliper.baud)
            checks.append(_guarded("calliper.port", calliper.port, "serial", probe))
        else:
            checks.append(DeviceCheck("calliper", "typed", True, "readings typed at the prompt"))
    if camera is not None:
        probe = functools.partial(_camera, camera.device, camera.calibration)
        checks.append(_guarded("camera.device", camera.device, "video", probe))
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
        if station.laser_grid is not None:
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


def _mouse(path: str, grab: bool) -> str:
    from bench.sensors.calibration import CountsCalibration
    from bench.sensors.mouse import EvdevMouse

    with EvdevMouse(path, CountsCalibration.from_cpi(800), label=path, grab=grab) as mouse:
        frames = mouse.read_frames()
        kind = "event device" if mouse.binding.is_device else "FIFO or file (not an event device)"
        return f"{kind} {mouse.binding.name or ''}".rstrip() + f", {len(frames)} reports waiting"


def _serial_opens(port_name: str, baud: int) -> str:
    open_port(port_name, baudrate=baud, timeout=0.05, exclusive=True).close()
    return f"opened at {baud} baud (press the data button during a run)"


def _camera(device: str, calibration: str) -> str:
    from bench.extras import require

    cv2 = require("cv2")

    if not os.path.exists(calibration):
        raise OSError(errno.ENOENT, f"calibration file {calibration} not found")
    capture = cv2.VideoCapture(int(device) if device.isdigit() else device)
    try:
        ok, image = capture.read()
    finally:
        capture.release()
    if not ok:
        raise OSError(errno.EIO, "no frame read")
    return f"frame {image.shape[1]} x {image.shape[0]} px"
