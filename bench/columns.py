"""A column of stored sample values: its name (unit in the name), unit, dtype and meaning.

The store's sample descriptors (:mod:`bench.store.descriptors`) and the sensor registry (:mod:`bench.sensor_kinds`,
the columns a sensor adds to the samples it takes) both declare columns with it; it imports nothing of bench, so
either may use it.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Column"]


@dataclass(frozen=True)
class Column:
    """One column of a sample kind: its name (unit in the name), unit, dtype (``float`` or ``int``) and meaning."""

    name: str
    unit: str
    dtype: str
    meaning: str
    required: bool = True

    def as_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "unit": self.unit,
            "dtype": self.dtype,
            "meaning": self.meaning,
            "required": self.required,
        }
