"""The one structural interface of bench sensors: a ``Reading`` record and the ``Sensor`` protocol.

Modelled on bluesky's ``Readable`` / ``Reading`` (``src/bluesky/protocols.py``): any object with a ``name`` and a
``read() -> Reading`` method is a sensor; no base class is needed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from bench.errors import LinkError

__all__ = ["MalformedSample", "Reading", "Sensor", "SensorStalled", "now"]


class MalformedSample(LinkError):
    """A device sent bytes, a line or an image that cannot be turned into a sample; nothing was stored."""


class SensorStalled(LinkError):
    """A streaming sensor stopped reporting, closed (end of stream) or froze: its sample would repeat stale data, so
    it is refused and the run ends with this reason; nothing was stored."""


def now() -> tuple[float, float]:
    """Return ``(t_monotonic_s, t_wall_s)`` taken together.

    The monotonic time orders samples and survives clock jumps; the wall time dates them for people.
    """
    return time.monotonic(), time.time()


@dataclass(frozen=True)
class Reading:
    """One sample of one sensor, stored the moment it is taken.

    Attributes
    ----------
    value : float or tuple of float
        The calibrated value(s), in ``unit``. A 2-D or 3-D position is a tuple ``(x, y[, z])``.
    unit : str
        Unit of ``value``: ``"mm"``, ``"deg"`` or ``"px"``.
    t_monotonic_s : float
        Time of the sample on ``CLOCK_MONOTONIC`` (s), the clock ``time.monotonic()`` reads on Linux.
    t_wall_s : float
        The same instant as a POSIX wall-clock time (s).
    raw : bytes, str, tuple of int or float, or None
        What the device gave before calibration: raw bytes, the raw text line, integer counts or pixels.
    calibration_id : str or None
        Identifier of the calibration that turned ``raw`` into ``value``; ``None`` when none was applied.
    source : str
        The sensor's name and binding, e.g. ``"mouse-xy:/dev/input/by-path/...-event-mouse"``.
    valid : bool
        False when the sample is known to be bad (lost counts, no laser hit); ``note`` then says why.
    note : str
        Free text: status, reason for invalidity, sensor quality figures.
    """

    value: float | tuple[float, ...]
    unit: str
    t_monotonic_s: float
    t_wall_s: float
    raw: bytes | str | tuple[int | float, ...] | None = None
    calibration_id: str | None = None
    source: str = ""
    valid: bool = True
    note: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        values = self.value if isinstance(self.value, tuple) else (self.value,)
        if not values or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in values):
            raise ValueError(
                f"Reading from {self.source or 'sensor'}: value = {self.value!r}, "
                "expected a finite number or a non-empty tuple of finite numbers"
            )
        if not self.unit:
            raise ValueError(f"Reading from {self.source or 'sensor'}: unit is empty, expected e.g. 'mm'")

    def as_row(self) -> dict[str, object]:
        """Flatten to one storage row; column names carry the unit (``value_mm``, ``value1_mm``...)."""
        values = self.value if isinstance(self.value, tuple) else (self.value,)
        row: dict[str, object] = {"t_monotonic_s": self.t_monotonic_s, "t_wall_s": self.t_wall_s, "source": self.source}
        if len(values) == 1:
            row[f"value_{self.unit}"] = values[0]
        else:
            row.update({f"value{i}_{self.unit}": v for i, v in enumerate(values)})
        raw = self.raw.hex() if isinstance(self.raw, bytes) else self.raw
        row.update({"raw": raw, "calibration_id": self.calibration_id, "valid": self.valid, "note": self.note})
        return row


@runtime_checkable
class Sensor(Protocol):
    """Anything that can be read: a ``name`` and ``read()`` returning one :class:`Reading`."""

    name: str

    def read(self) -> Reading:
        """Take one sample now (blocking up to the sensor's own timeout) and return it."""
        ...
