"""Sample descriptors: which columns each kind of sample carries, with unit, dtype and meaning.

Modelled on PyMeasure's ``DATA_COLUMNS`` and bluesky's event descriptors: a sample of a declared kind must hold its
required columns and no undeclared one, each a finite number, and integers where the dtype is ``int``. The runner
checks every sample of a declared kind before it is stored (:func:`validate_sample`); a mismatch is a bug in the
instrument or the protocol and raises :class:`SampleMismatch`, never stored silently. Export reads units and dtypes
from here (:func:`unit_of`, :func:`dtype_of`); a column of an undeclared kind falls back to the project's naming
rule (the unit is the name's last ``_`` part: ``x_mm``, ``load_kg``).

Units: mm, deg, pct (percent of the robot's top speed), kg, s, counts (raw sensor counts), ``1`` (dimensionless:
flags and counts of things).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from bench.columns import UNITS, Column
from bench.errors import BenchError
from bench.sensor_kinds import sensor_columns

__all__ = [
    "SAMPLE_KINDS",
    "VALUE_COLUMNS",
    "Column",
    "SampleKind",
    "SampleMismatch",
    "dtype_of",
    "unit_of",
    "validate_sample",
]


class SampleMismatch(BenchError):
    """A sample that does not match its kind's descriptor: a bug report (exit 1), never stored."""

    exit_code = 1


@dataclass(frozen=True)
class SampleKind:
    """A declared kind of sample: its name, what it is, and its own value columns; :meth:`declared` adds those the
    registered sensors' captures add to it (:func:`bench.sensor_kinds.sensor_columns`: the laser grid's screens, the
    mice's counts)."""

    name: str
    meaning: str
    columns: tuple[Column, ...]

    def declared(self) -> tuple[Column, ...]:
        return self.columns + sensor_columns(self.name)

    def column(self, name: str) -> Column | None:
        return next((c for c in self.declared() if c.name == name), None)

    def as_dict(self) -> dict[str, object]:
        return {"kind": self.name, "meaning": self.meaning, "columns": [c.as_dict() for c in self.declared()]}


def _xyz(prefix: str, meaning: str, required: bool = True) -> tuple[Column, ...]:
    return tuple(Column(f"{prefix}{axis}_mm", "mm", "float", f"{meaning} {axis}", required) for axis in "xyz")


def _abc(prefix: str, meaning: str) -> tuple[Column, ...]:
    return tuple(Column(f"{prefix}{axis}_deg", "deg", "float", f"{meaning} {axis}", False) for axis in "abc")


_CONDITIONS = (
    Column("velocity_pct", "pct", "float", "commanded velocity, percent of the rated speed", False),
    Column("load_kg", "kg", "float", "payload on the platform", False),
    Column("lead_s", "s", "float", "series recorded from this long before the move-done signal", False),
    Column("hold_s", "s", "float", "series recorded for this long after the move-done signal", False),
)
_COMMANDED = _xyz("cmd_", "commanded position") + _abc("cmd_", "commanded orientation")

#: The declared sample kinds, by name.
SAMPLE_KINDS: dict[str, SampleKind] = {
    kind.name: kind
    for kind in (
        SampleKind(
            "pose",
            "an attained pose measured after settling (ISO 9283 pose tests); an axis the instrument could "
            "not read is absent (e.g. a laser-grid screen that did not decode)",
            _COMMANDED + _xyz("", "measured position", required=False) + _abc("", "measured orientation") + _CONDITIONS,
        ),
        SampleKind(
            "arrival",
            "the last point of a streamed arrival series (the series itself is in raw)",
            _COMMANDED + _xyz("", "measured position at the end of the series") + _CONDITIONS,
        ),
        SampleKind(
            "path",
            "the last point of one streamed segment of a continuous path (ISO 9283 clause 8): cmd_* is "
            "the segment's commanded end, velocity_pct the path velocity in percent of the rated path "
            "velocity; the series (t_s, x_mm, y_mm, z_mm) and its start time t_request_s are in raw",
            _COMMANDED + _xyz("", "measured position at the end of the segment") + _CONDITIONS,
        ),
        SampleKind(
            "positioning",
            "the last point of one streamed step of the minimum positioning time sequence (ISO "
            "9283 clause 9): cmd_* is the step's target, step its number in Table 19; the series "
            "(t_s, x_mm, y_mm, z_mm) from rest before the move to hold_s after it, and its start "
            "time t_request_s, are in raw",
            _COMMANDED
            + _xyz("", "measured position at the end of the series")
            + _CONDITIONS
            + (
                Column("step", "1", "int", "number of the step in ISO 9283 Table 19"),
                Column(
                    "step_distance_mm",
                    "mm",
                    "float",
                    "commanded per-axis distance from the previous pose (Dx = Dy = Dz)",
                ),
            ),
        ),
        SampleKind(
            "mouse",
            "raw counts of the two optical mice at one end of a calibration stroke (the counts' columns are the "
            "mice's, bench.sensor_kinds)",
            _xyz("cmd_", "commanded position")
            + (Column("step_mm", "mm", "float", "length of the calibration stroke"),)
            + _CONDITIONS,
        ),
    )
}


def _value_columns() -> tuple[Column, ...]:
    seen: dict[str, Column] = {}
    for kind in SAMPLE_KINDS.values():
        for column in kind.declared():
            seen.setdefault(column.name, column)
    return tuple(seen.values())


#: Every declared value column once (first declaration wins; a name means one quantity in one unit whichever kind
#: carries it), in declaration order: the typed columns of the lab store (``bench.store.lab_copy``).
VALUE_COLUMNS: tuple[Column, ...] = _value_columns()


def validate_sample(kind: str, values: Mapping[str, float]) -> None:
    """Check ``values`` against the descriptor of ``kind`` (undeclared kinds pass: see the module docstring).

    Raises
    ------
    SampleMismatch
        Naming the kind and the first missing, undeclared or ill-typed column.
    """
    descriptor = SAMPLE_KINDS.get(kind)
    if descriptor is None:
        return
    for name, value in values.items():
        column = descriptor.column(name)
        if column is None:
            declared = ", ".join(c.name for c in descriptor.declared())
            raise SampleMismatch(f"sample kind {kind!r}: column {name!r} is not declared (declared: {declared})")
        if column.dtype == "int" and not (
            isinstance(value, (int, float)) and math.isfinite(value) and float(value).is_integer()
        ):
            raise SampleMismatch(f"sample kind {kind!r}: {name} = {value!r}, expected an integer")
    missing = [c.name for c in descriptor.declared() if c.required and c.name not in values]
    if missing:
        raise SampleMismatch(f"sample kind {kind!r}: missing column(s) {', '.join(missing)}")


def unit_of(kind: str, name: str) -> str | None:
    """The unit of column ``name`` of samples of ``kind``: the descriptor's, else the name's suffix when it is a
    known unit, else None."""
    descriptor = SAMPLE_KINDS.get(kind)
    column = descriptor.column(name) if descriptor else None
    if column is not None:
        return column.unit
    suffix = name.rsplit("_", 1)[-1] if "_" in name else ""
    return suffix if suffix in UNITS else None


def dtype_of(kind: str, name: str) -> str | None:
    """The declared dtype of column ``name`` of ``kind``, or None when the kind or column is not declared."""
    descriptor = SAMPLE_KINDS.get(kind)
    column = descriptor.column(name) if descriptor else None
    return column.dtype if column else None
