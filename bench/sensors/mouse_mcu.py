"""Mouse sensor on a microcontroller (e.g. PMW3360 over SPI) streaming ``t_us,dx,dy[,squal]`` lines.

This route owns the CPI register and sees the sensor's surface quality (``sensors.md`` §4.13). ``t_us`` is the
MCU clock in microseconds; a clock that goes backwards, or a SQUAL below the threshold, invalidates the segment.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from bench.sensors.calibration import CountsCalibration
from bench.sensors.reading import MalformedSample, Reading, now
from bench.sensors.serial_lines import LineReader, Port

__all__ = ["McuMouse", "McuSample", "parse_mcu_line"]

_LINE = re.compile(rb"\s*(\d+)\s*,\s*([+-]?\d+)\s*,\s*([+-]?\d+)\s*(?:,\s*(\d+)\s*)?")


@dataclass(frozen=True)
class McuSample:
    """One MCU report: MCU time (us), counts since the previous report, and SQUAL when sent."""

    t_us: int
    dx: int
    dy: int
    squal: int | None = None


def parse_mcu_line(line: bytes, *, source: str = "mouse MCU") -> McuSample:
    """Parse ``t_us,dx,dy[,squal]`` (integers; optional spaces); anything else raises ``MalformedSample``."""
    match = _LINE.fullmatch(line)
    if match is None:
        raise MalformedSample(
            f"{source}: malformed line {line!r}, expected 't_us,dx,dy[,squal]' with integers; sample not stored"
        )
    t_us, dx, dy, squal = match.groups()
    return McuSample(int(t_us), int(dx), int(dy), None if squal is None else int(squal))


class McuMouse:
    """A mouse sensor read through a microcontroller's serial stream, integrated and calibrated.

    Parameters
    ----------
    port : Port
        Open serial port (``serial.serial_for_url``).
    calibration : CountsCalibration
        Counts -> mm; its id travels with every reading.
    label : str
        The bench's name for this sensor.
    min_squal : int
        Reports with a lower surface quality invalidate the segment (lift-off, poor surface).
    """

    def __init__(
        self, port: Port, calibration: CountsCalibration, *, label: str = "mouse-mcu", min_squal: int = 30
    ) -> None:
        self.name = label
        self.calibration = calibration
        self.min_squal = min_squal
        self._lines = LineReader(port, f"mouse {label!r} ({getattr(port, 'port', 'serial')})")
        self.counts = np.zeros(2, np.int64)
        self.segment_valid = True
        self.notes: list[str] = []
        self._last: McuSample | None = None

    def read_sample(self, timeout_s: float = 1.0) -> McuSample:
        """Read, parse and integrate the next report; problems mark the segment invalid with a note."""
        sample = parse_mcu_line(self._lines.read_line(timeout_s), source=self._lines.name)
        if self._last is not None and sample.t_us <= self._last.t_us:
            self._invalidate(f"MCU clock went from {self._last.t_us} to {sample.t_us} us (reset or lost data)")
        if sample.squal is not None and sample.squal < self.min_squal:
            self._invalidate(f"SQUAL {sample.squal} < {self.min_squal} at t = {sample.t_us} us")
        self.counts += (sample.dx, sample.dy)
        self._last = sample
        return sample

    def _invalidate(self, note: str) -> None:
        self.segment_valid = False
        self.notes.append(note)

    def rezero(self) -> None:
        """Start a new segment at the current position."""
        self.counts[:] = 0
        self.segment_valid = True
        self.notes.clear()

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about this sensor: port, SQUAL threshold and calibration."""
        return {
            "sensor": "MCU mouse stream",
            "label": self.name,
            "port": self._lines.name,
            "min_squal": self.min_squal,
            "calibration": self.calibration.to_dict(),
            "calibration_hash": self.calibration.content_hash(),
        }

    def read(self, n_samples: int = 1, timeout_s: float = 1.0) -> Reading:
        """Read ``n_samples`` reports, then return the integrated displacement (mm) since :meth:`rezero`."""
        for _ in range(n_samples):
            self.read_sample(timeout_s)
        t_mono, t_wall = now()
        x_mm, y_mm = self.calibration.counts_to_mm(self.counts)
        squal = "" if self._last is None or self._last.squal is None else f"squal={self._last.squal}"
        return Reading(
            (float(x_mm), float(y_mm)),
            "mm",
            t_mono,
            t_wall,
            raw=tuple(int(c) for c in self.counts),
            calibration_id=self.calibration.calibration_id,
            source=self._lines.name,
            valid=self.segment_valid,
            note="; ".join([squal, *self.notes]).strip("; "),
        )
