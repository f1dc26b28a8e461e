"""Digital calliper readings: tolerant parsing, prompted manual entry with validation, serial callipers, and tilt
from two depths with the play-bias correction (``sensors.md`` §6; keyboard wedges in ``calliper_wedge``).
"""

from __future__ import annotations

import math
import re
import statistics
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from bench.errors import ConfigError, InsufficientData
from bench.sensors.reading import MalformedSample, Reading, now
from bench.sensors.serial_lines import LineReader, Port

__all__ = [
    "ReadingRequest",
    "SerialCalliper",
    "TiltBias",
    "parse_length",
    "prompt_reading",
    "tilt_deg",
    "tilt_reading",
    "tilt_uncertainty_deg",
]

#: ASCII digits only: ``\d`` would take any script's (``45\u0661\u0662`` read as 45 12, i.e. 4512), which a gauge never
#: sends and a typist mixes only by mistake.
_NUMBER = re.compile(r"\s*([+-]?)\s*([0-9]+(?:[.,][0-9]*)?|[.,][0-9]+)\s*(mm|in|\")?\s*", re.IGNORECASE)
_MM_PER_UNIT = {"mm": 1.0, "in": 25.4, '"': 25.4}
#: Digits (with the decimal separator) a typed or sent reading may have.
_MAX_DIGITS = 15


def parse_length(text: str, *, source: str = "calliper") -> float:
    """Parse a calliper reading into mm.

    Accepts an optional sign, digits with a ``.`` or ``,`` decimal separator, and an optional unit ``mm``, ``in``
    or ``"`` (default mm) (``sensors.md`` §6.4). Anything else raises ``MalformedSample`` naming the text.

    >>> parse_length("-12,34 mm"), parse_length('0.5"')
    (-12.34, 12.7)
    """
    match = _NUMBER.fullmatch(text)
    if match is None:
        raise MalformedSample(
            f"{source}: reading {text!r} is not a length; expected e.g. '12.34', '-0,50 mm' or '0.4865 in'"
        )
    sign, digits, unit = match.groups()
    if len(digits) > _MAX_DIGITS:  # no calliper shows that many digits; a float would round or overflow to inf
        raise MalformedSample(f"{source}: reading {text!r} has {len(digits)} digits, expected at most {_MAX_DIGITS}")
    value = float(digits.replace(",", ".")) * _MM_PER_UNIT[(unit or "mm").lower()]
    return -value if sign == "-" else value


@dataclass(frozen=True)
class ReadingRequest:
    """What the protocol is waiting for: a label and the plausible range of the answer.

    Parameters
    ----------
    label : str
        Pre-filled context, e.g. ``"actuator 3, 20 mm, repeat 4, final depth"``.
    min_mm, max_mm : float
        Hard limits (the instrument's range); outside them an entry is refused.
    expected_mm, tolerance_mm : float or None
        Plausible value; an entry further than ``tolerance_mm`` from it needs confirmation.
    """

    label: str
    min_mm: float = 0.0
    max_mm: float = 150.0
    expected_mm: float | None = None
    tolerance_mm: float = 2.0

    def check(self, value_mm: float) -> str:
        """Return ``""`` when plausible, a question when it needs confirmation; raise when out of range."""
        if not self.min_mm <= value_mm <= self.max_mm:
            raise ConfigError(f"{self.label}: {value_mm:g} mm, expected {self.min_mm:g} to {self.max_mm:g} mm")
        if self.expected_mm is not None and abs(value_mm - self.expected_mm) > self.tolerance_mm:
            return (
                f"{value_mm:g} mm is {value_mm - self.expected_mm:+.3f} mm from the expected "
                f"{self.expected_mm:g} mm; keep it? [y/N] "
            )
        return ""


def prompt_reading(
    request: ReadingRequest,
    store: Callable[[Reading], None],
    *,
    ask: Callable[[str], str] = input,
    out: TextIO | None = None,
    double_entry: bool = False,
    operator: str = "",
) -> Reading:
    """Ask for one manual reading until a valid one is given, store it at once, and return it.

    ``ask`` shows a prompt and returns the typed line (``input`` on the CLI, a form field in a GUI). Invalid text
    and out-of-range values are explained and asked again; implausible values need a ``y``; with
    ``double_entry`` the value must be typed twice identically. ``store`` is called before returning, so the
    entry is on disk even if the program stops right after. Explanations go to ``out`` (default stderr).
    """
    out = out or sys.stderr
    while True:
        text = ask(f"{request.label} [mm]: ")
        try:
            value = parse_length(text, source=request.label)
            question = request.check(value)
        except (MalformedSample, ConfigError) as exc:
            print(f"  {exc}", file=out)
            continue
        if question and ask(f"  {question}").strip().lower() not in ("y", "yes"):
            continue
        if double_entry:
            again = ask(f"{request.label} again [mm]: ")
            try:
                same = parse_length(again, source=request.label) == value
            except MalformedSample:
                same = False
            if not same:
                print(f"  the two entries differ ({text!r} and {again!r}); enter the reading again", file=out)
                continue
        t_mono, t_wall = now()
        reading = Reading(
            value,
            "mm",
            t_mono,
            t_wall,
            raw=text,
            source=f"manual:{operator or 'operator'}",
            note=request.label + ("; confirmed outside the expected range" if question else ""),
        )
        store(reading)
        return reading


class SerialCalliper:
    """A calliper (or interface cable) that sends one ASCII line per reading on a serial port.

    Parameters
    ----------
    port : Port
        Open port (``serial.serial_for_url``); baud rate and framing are set on it.
    name : str
        Name in messages and readings.
    request : bytes
        Sent before each read when the interface answers requests; empty for push-button devices.
    terminator : bytes
        Line end (``b"\\r"`` for many interfaces).
    """

    def __init__(self, port: Port, *, name: str = "calliper", request: bytes = b"", terminator: bytes = b"\n") -> None:
        self.name = name
        self.port = port
        self.request = request
        self._lines = LineReader(port, f"{name} ({getattr(port, 'port', 'serial')})", terminator=terminator)

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about this calliper: port, request string and line end."""
        return {
            "sensor": "serial calliper",
            "name": self.name,
            "port": self._lines.name,
            "request": self.request.decode(errors="replace"),
            "terminator": self._lines.terminator.decode(),
        }

    def read(self, timeout_s: float = 30.0) -> Reading:
        """Wait for the next line (the operator presses the data button) and return it as a reading in mm."""
        if self.request:
            self.port.write(self.request)  # type: ignore[attr-defined]
        line = self._lines.read_line(timeout_s)
        text = line.decode("ascii", errors="replace")
        value = parse_length(text, source=self._lines.name)
        t_mono, t_wall = now()
        return Reading(value, "mm", t_mono, t_wall, raw=text, source=self._lines.name)


def tilt_deg(h1_mm: np.ndarray | float, h2_mm: np.ndarray | float, spacing_mm: float) -> np.ndarray:
    """Tilt from two depths through holes ``spacing_mm`` apart (``sensors.md`` §6.3, reconstructed formula).

    .. math:: \\theta = \\operatorname{atan2}(h_2 - h_1, s)

    Positive when hole 2 reads deeper than hole 1; the protocol states which rotation (alpha or beta) that is.
    Returns degrees, broadcast over the inputs.
    """
    if not spacing_mm > 0:
        raise ConfigError(f"tilt: spacing_mm = {spacing_mm!r}, expected the positive hole spacing in mm")
    return np.degrees(np.arctan2(np.subtract(h2_mm, h1_mm), spacing_mm))


def tilt_uncertainty_deg(h1_mm: float, h2_mm: float, spacing_mm: float, u_h_mm: float, u_spacing_mm: float) -> float:
    """Standard uncertainty of :func:`tilt_deg` (``iso9283.md`` §8.2(d)): the one formula,
    :func:`bench.metrology.orientation.tilt_gradient_uncertainty_deg`, at Δh = h2 − h1."""
    from bench.metrology.orientation import tilt_gradient_uncertainty_deg

    return tilt_gradient_uncertainty_deg(h2_mm - h1_mm, spacing_mm, u_h_mm, u_spacing_mm)


@dataclass(frozen=True)
class TiltBias:
    """Measured tilt of the end effector at home with the actuators locked (the play bias, ``sensors.md`` §6.3).

    The dissertation found -4 deg about y and subtracted it from beta; here it is a signed calibration value,
    measured at least 5 times per test day: ``beta_corrected = beta_measured - mean_deg``.
    """

    mean_deg: float
    std_deg: float
    n: int
    calibration_id: str

    MIN_REPEATS = 5

    @classmethod
    def from_repeats(cls, angles_deg: list[float], *, calibration_id: str) -> TiltBias:
        """Mean and sample standard deviation of repeated bias measurements (at least 5)."""
        if len(angles_deg) < cls.MIN_REPEATS:
            raise InsufficientData(
                f"tilt bias {calibration_id}: {len(angles_deg)} repeats, expected at least {cls.MIN_REPEATS}"
            )
        return cls(statistics.fmean(angles_deg), statistics.stdev(angles_deg), len(angles_deg), calibration_id)

    @property
    def u_mean_deg(self) -> float:
        """Standard uncertainty of the mean bias (deg)."""
        return self.std_deg / math.sqrt(self.n)

    def changed_since(self, previous: TiltBias, *, coverage: float = 2.0) -> bool:
        """True when the bias moved by more than ``coverage`` combined standard uncertainties: the play changed."""
        return abs(self.mean_deg - previous.mean_deg) > coverage * math.hypot(self.u_mean_deg, previous.u_mean_deg)


def tilt_reading(h1: Reading, h2: Reading, spacing_mm: float, bias: TiltBias | None = None) -> Reading:
    """Derived reading: the corrected tilt (deg) from two depth readings, with the bias id as calibration."""
    measured = float(tilt_deg(float(h1.value), float(h2.value), spacing_mm))  # type: ignore[arg-type]
    corrected = measured - (bias.mean_deg if bias else 0.0)
    note = f"measured {measured:.4f} deg" + (f", bias {bias.mean_deg:+.4f} deg removed" if bias else ", no bias")
    return Reading(
        corrected,
        "deg",
        max(h1.t_monotonic_s, h2.t_monotonic_s),
        max(h1.t_wall_s, h2.t_wall_s),
        raw=(f"{h1.value}|{h2.value}|{spacing_mm}"),
        calibration_id=bias.calibration_id if bias else None,
        source="tilt:" + h1.source,
        valid=h1.valid and h2.valid,
        note=note,
    )
