"""The dissertation's instrument: two optical mice, one in the x-y plane and one in the x-z plane, as an Instrument.

Each mouse integrates raw counts since the instrument was registered; counts become mm through the calibration in
force (its id travels with every sample). The instrument frame is registered once, at a known pose of the robot
(its home), so a reading is ``registration + displacement``. :func:`hardware_rig` builds the rig for a real pkm5
controller on a serial port with two mice on ``/dev/input``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bench.errors import LinkError
from bench.protocols.rig import Measurement, Rig
from bench.protocols.steps import Capture, Prompt

__all__ = ["ConsoleOperator", "MiceInstrument", "hardware_rig"]


class MiceInstrument:
    """Position (x, y, z) in mm from an x-y mouse and an x-z mouse.

    Parameters
    ----------
    mice : dict
        ``{"xy": EvdevMouse, "xz": EvdevMouse}``: open mice reading raw counts.
    origin_mm : array_like, shape (3,)
        Position of the measuring point when the counts were zero (the registration), mm.
    calibration : bench.sensors.calibration.CountsCalibration
        Counts -> mm, applied by the mice.
    """

    def __init__(self, mice: dict[str, Any], origin_mm, calibration: Any) -> None:
        self.mice = mice
        self.origin = np.asarray(origin_mm, dtype=float)[:3].copy()
        self.calibration = calibration

    def _read(self) -> tuple[Any, Any]:
        return self.mice["xy"].read(timeout_s=0.001), self.mice["xz"].read(timeout_s=0.001)

    def measure(self, capture: Capture) -> Measurement:
        xy, xz = self._read()
        if capture.kind == "mouse":  # calibration runs store the raw counts themselves
            counts = {"mouse_xy_x_counts": xy.raw[0], "mouse_xy_y_counts": xy.raw[1],
                      "mouse_xz_x_counts": xz.raw[0], "mouse_xz_z_counts": xz.raw[1]}
            return Measurement({k: float(v) for k, v in counts.items()},
                               raw={"calibration": self.calibration.calibration_id})
        x_mm, y_mm = self.origin[:2] + np.asarray(xy.value)
        z_mm = self.origin[2] + xz.value[1]
        return Measurement({"x_mm": float(x_mm), "y_mm": float(y_mm), "z_mm": float(z_mm)},
                           raw={"counts_xy": list(xy.raw), "counts_xz": list(xz.raw), "valid": bool(xy.valid
                                                                                                   and xz.valid),
                                "calibration": self.calibration.calibration_id})

    def settings(self) -> dict[str, Any]:
        return {"instrument": "optical mice (x-y, x-z)", "calibration_id": self.calibration.calibration_id,
                "mice": {plane: str(mouse.binding) for plane, mouse in self.mice.items()},
                "registration_mm": [float(v) for v in self.origin]}

    def close(self) -> None:
        for mouse in self.mice.values():
            mouse.close()


class ConsoleOperator:
    """Asks the person at the terminal (prompt on stderr, answer on stdin), re-asking until the value is valid."""

    def __init__(self, read_line: Callable[[str], str] = input) -> None:
        self.read_line = read_line

    def ask(self, prompt: Prompt) -> float | None:
        import sys

        while True:
            unit = f" [{prompt.unit}]" if prompt.unit else ""
            print(f"{prompt.text}{unit}: " if prompt.field else f"{prompt.text} (Enter): ", end="", file=sys.stderr,
                  flush=True)
            text = self.read_line("").strip()
            if prompt.field is None:
                return None
            try:
                value = float(text)
                low, high = prompt.minimum, prompt.maximum
                if (low is not None and value < low) or (high is not None and value > high):
                    raise ValueError
                return value
            except ValueError:
                print(f"  {prompt.field} = {text!r}, expected a number in [{prompt.minimum}, {prompt.maximum}]"
                      f"{unit}; try again", file=sys.stderr)


def hardware_rig(port: str, *, mouse_xy: str, mouse_xz: str, calibration: Any, home_mm) -> Rig:
    """A pkm5 on ``port`` with two mice on event devices; the robot must stand at ``home_mm`` (registration)."""
    import serial

    from bench.protocols.simrig import DriverMover
    from bench.robots.pkm5 import Pkm5Controller
    from bench.sensors.mouse import EvdevMouse

    try:
        port_instance = serial.serial_for_url(port, baudrate=115200, timeout=0.05)
    except serial.SerialException as exc:
        raise LinkError(f"--port {port}: cannot open it ({exc.strerror or exc}); is the controller plugged in "
                        "and is the port name right?") from None
    controller = Pkm5Controller(port_instance)
    mice: dict[str, Any] = {}
    try:
        controller.identify()
        controller.enable()
        for plane, path in (("xy", mouse_xy), ("xz", mouse_xz)):
            mice[plane] = EvdevMouse(path, calibration, label=f"mouse_{plane}", grab=True)
    except BaseException:
        for mouse in mice.values():
            mouse.close()
        controller.shutdown()
        raise
    instrument = MiceInstrument(mice, home_mm, calibration)
    return Rig(DriverMover(controller), instrument, ConsoleOperator(), closers=[instrument.close])
