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

from bench.errors import BenchError

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

_KNOWN_UNITS = ("mm", "deg", "pct", "kg", "s", "counts")


class SampleMismatch(BenchError):
    """A sample that does not match its kind's descriptor: a bug report (exit 1), never stored."""

    exit_code = 1


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


@dataclass(frozen=True)
class SampleKind:
    """A declared kind of sample: its name, what it is, and its value columns."""

    name: str
    meaning: str
    columns: tuple[Column, ...]

    def column(self, name: str) -> Column | None:
        return next((c for c in self.columns if c.name == name), None)

    def as_dict(self) -> dict[str, object]:
        return {"kind": self.name, "meaning": self.meaning, "columns": [c.as_dict() for c in self.columns]}


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
_LASER_GRID = (
    Column("horizontal_valid", "1", "int", "laser grid: 1 when the horizontal screen decoded", False),
    Column("vertical_valid", "1", "int", "laser grid: 1 when the vertical screen decoded", False),
    Column("horizontal_hits", "1", "int", "laser grid: lasers lit on the horizontal screen", False),
    Column("vertical_hits", "1", "int", "laser grid: lasers lit on the vertical screen", False),
    Column("y_disagreement_mm", "mm", "float", "laser grid: difference of the two screens' y readings", False),
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
            _COMMANDED
            + _xyz("", "measured position", required=False)
            + _abc("", "measured orientation")
            + _CONDITIONS
            + _LASER_GRID,
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
            "raw counts of the two optical mice at one end of a calibration stroke",
            _xyz("cmd_", "commanded position")
            + (Column("step_mm", "mm", "float", "length of the calibration stroke"),)
            + tuple(
                Column(
                    f"mouse_{plane}_{axis}_counts",
                    "counts",
                    "float",
                    f"accumulated counts of the {plane} mouse along {axis}",
                )
                for plane, axis in (("xy", "x"), ("xy", "y"), ("xz", "x"), ("xz", "z"))
            )
            + _CONDITIONS,
        ),
    )
}


def _value_columns() -> tuple[Column, ...]:
    seen: dict[str, Column] = {}
    for kind in SAMPLE_KINDS.values():
        for column in kind.columns:
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
            declared = ", ".join(c.name for c in descriptor.columns)
            raise SampleMismatch(f"sample kind {kind!r}: column {name!r} is not declared (declared: {declared})")
        if column.dtype == "int" and not (
            isinstance(value, (int, float)) and math.isfinite(value) and float(value).is_integer()
        ):
            raise SampleMismatch(f"sample kind {kind!r}: {name} = {value!r}, expected an integer")
    missing = [c.name for c in descriptor.columns if c.required and c.name not in values]
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
    return suffix if suffix in _KNOWN_UNITS else None


def dtype_of(kind: str, name: str) -> str | None:
    """The declared dtype of column ``name`` of ``kind``, or None when the kind or column is not declared."""
    descriptor = SAMPLE_KINDS.get(kind)
    column = descriptor.column(name) if descriptor else None
    return column.dtype if column else None
