"""A column of stored sample values: its name (unit in the name, checked), unit, dtype and meaning.

The store's sample descriptors (:mod:`bench.store.descriptors`) and the sensor registry (:mod:`bench.sensor_kinds`,
the columns a sensor adds to the samples it takes) both declare columns with it; it imports nothing of bench, so
either may use it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["UNITS", "Column"]

#: The units a column's name ends in: mm, deg, pct (percent of the robot's top speed), kg, s, counts (raw sensor
#: counts). A column in ``1`` (flags, numbers of things) has no unit suffix.
UNITS = ("mm", "deg", "pct", "kg", "s", "counts")


@dataclass(frozen=True)
class Column:
    """One column of a sample kind: its name (unit in the name), unit, dtype (``float`` or ``int``) and meaning."""

    name: str
    unit: str
    dtype: str
    meaning: str
    required: bool = True

    def __post_init__(self) -> None:
        suffix = self.name.rsplit("_", 1)[-1] if "_" in self.name else ""
        if (suffix in UNITS or self.unit in UNITS) and suffix != self.unit:
            raise ValueError(f"column {self.name!r} in {self.unit!r}: a column's name ends in its unit (x_mm)")

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "unit": self.unit,
            "dtype": self.dtype,
            "meaning": self.meaning,
            "required": self.required,
        }
