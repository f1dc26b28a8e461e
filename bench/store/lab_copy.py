"""Sample rows in PostgreSQL's COPY text format, with the typed value columns of the lab store.

``bench.samples`` on the server keeps every stored column byte for byte (``values_json`` as text, so checksums are
equal on both sides) and, beside it, one ``double precision`` column per declared value column
(:data:`bench.store.descriptors.VALUE_COLUMNS`: ``x_mm``, ``cmd_x_mm``, ``velocity_pct``, ...), NULL where the
sample lacks it, so lab-wide queries read numbers instead of parsing JSON. Integers (dtype ``int``) are exact in a
double up to 2**53.

The typed fields come from msgspec: the sample's ``values_json`` decoded into a struct of the typed columns (each
a float or null; every other key skipped unparsed) and encoded again as one JSON array, both in C; its commas become
tabs and its ``null`` becomes COPY's ``\\N``. A float is written as its shortest round-trip text, so the server stores
the same double as the stored text's (an integer becomes that integer's double, correctly rounded as the server's
own conversion of its text would be: exact up to 2**53; ``-0`` becomes 0.0). A value that is not a number (a
string, a boolean, a nested object, in an undeclared kind), JSON that is not an object, or JSON that only the
standard library reads (an escaped lone surrogate in a key, which :func:`bench.store.records.to_json` can write)
sends the row through :func:`_typed_fields_slow`, which keeps the numbers and sends NULL for the rest. (SQLite's
``json_extract`` of the 28 paths did the same in 2.0 us a sample and its number text needed 0.84 us more of Python;
this takes 1.3 + 0.9: ``benchmarks/bench_sync_costs.py``.)

Format: PostgreSQL manual, COPY, "Text Format": tab-separated, ``\\N`` for NULL, backslash escapes for backslash,
tab, newline and carriage return.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import msgspec

from bench.store.descriptors import VALUE_COLUMNS
from bench.store.records import from_json
from bench.store.sample_checksum import DamagedSample

__all__ = ["COPY_COLUMNS", "SAMPLE_COLUMNS", "TYPED_COLUMNS", "copy_text", "typed_columns_ddl"]

#: The sample columns as the local store holds them (``Store.stored_rows`` order).
SAMPLE_COLUMNS = ("step_index", "kind", "pose", "cycle", "t_s", "wall_utc", "values_json", "raw_json")
#: The typed value columns, from the descriptors.
TYPED_COLUMNS: tuple[str, ...] = tuple(c.name for c in VALUE_COLUMNS)
#: The columns a COPY of :func:`copy_text` fills, in order: the stored columns, the local store's checksum of
#: them (:mod:`bench.store.sample_checksum`, carried as stored, so the server's copy is checked the same way), the
#: typed values.
COPY_COLUMNS = ("run_uuid", *SAMPLE_COLUMNS, "checksum", *TYPED_COLUMNS)

_NULL = "\\N"
_COPY_ESCAPES = str.maketrans({"\\": "\\\\", "\t": "\\t", "\n": "\\n", "\r": "\\r"})
_EMPTY_TYPED = "\t".join([_NULL] * len(TYPED_COLUMNS))
#: A sample's typed values: each a float or null, absent keys null, every other key skipped (msgspec, in C).
_Typed = msgspec.defstruct("_Typed", [(name, float | None, None) for name in TYPED_COLUMNS])
_DECODE_TYPED = msgspec.json.Decoder(_Typed).decode
_ENCODE = msgspec.json.Encoder().encode
_AS_TUPLE = msgspec.structs.astuple


def typed_columns_ddl(table: str) -> str:
    """``ALTER TABLE`` statements adding the typed columns to ``table`` where missing (idempotent)."""
    return "".join(
        f'ALTER TABLE {table} ADD COLUMN IF NOT EXISTS "{name}" double precision;\n' for name in TYPED_COLUMNS
    )


def _text(value: str | None) -> str:
    if value is None:
        return _NULL
    if "\\" in value or "\t" in value or "\n" in value or "\r" in value:  # rare: JSON escapes its own controls
        return value.translate(_COPY_ESCAPES)
    return value


def _number(value: object) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return _NULL
    return repr(value) if isinstance(value, float) else str(value)


def _typed_fields_slow(values_json: str) -> str:
    """The typed fields of a sample whose values are not all numbers: numbers kept, anything else NULL."""
    values = from_json(values_json)
    if not isinstance(values, dict):
        return _EMPTY_TYPED
    return "\t".join(_number(values.get(name)) for name in TYPED_COLUMNS)


def _typed_fields(values_json: str) -> str:
    """The typed fields (tab-separated) of a sample's ``values_json``: its numbers, NULL where it holds none."""
    try:
        array = _ENCODE(_AS_TUPLE(_DECODE_TYPED(values_json)))
    except msgspec.MsgspecError:  # a value that is not a number, JSON that is not an object, or JSON that msgspec
        # refuses and the standard library reads (an escaped lone surrogate, NaN): the slow path's from_json decides
        return _typed_fields_slow(values_json)
    return array[1:-1].replace(b",", b"\t").replace(b"null", b"\\N").decode()


def _line(run_uuid: str, row: tuple[Any, ...], typed: str) -> str:
    """One COPY line, escaping every text field (the general path of :func:`copy_text`)."""
    step, kind, pose, cycle, t_s, wall, values, raw, checksum = row
    return (
        f"{run_uuid}\t{step}\t{_text(kind)}\t{_text(pose)}\t{_NULL if cycle is None else cycle}\t"
        f"{float(t_s)!r}\t{_text(wall)}\t{_text(values)}\t{_text(raw)}\t{_text(checksum)}\t{typed}\n"
    )


def copy_text(run_uuid: str, rows: Iterable[tuple[Any, ...]]) -> bytes:
    """Rows of ``Store.stored_rows(run_id, checksum=True)`` as COPY text for :data:`COPY_COLUMNS`; ``t_s`` as its
    shortest round-trip repr.

    The common row (no text needing an escape, a pose, a checksum and a raw record or none) is formatted inline; any
    other goes through :func:`_line`. (Formatting a whole chunk blind and checking it by counting tabs, newlines and
    backslashes was tried: 1.5 times slower than this row-by-row check.)"""
    lines = []
    for row in rows:
        step, kind, pose, cycle, t_s, wall, values, raw, checksum = row
        try:
            typed = _typed_fields(values)
        except ValueError as exc:  # from_json's: not JSON at all (damaged bytes: bench writes only JSON)
            raise DamagedSample(
                f"sample at step {step}: its values_json is malformed JSON ({exc}); nothing after it is sent: list "
                "the damage with `bench store check FILE`"
            ) from None
        if pose is None or cycle is None or checksum is None:
            lines.append(_line(run_uuid, row, typed))
            continue
        texts = f"{kind}{pose}{wall}{values}{raw}{checksum}"
        if "\\" in texts or "\t" in texts or "\n" in texts or "\r" in texts:
            lines.append(_line(run_uuid, row, typed))
            continue
        lines.append(
            f"{run_uuid}\t{step}\t{kind}\t{pose}\t{cycle}\t{float(t_s)!r}\t{wall}\t{values}\t"
            f"{_NULL if raw is None else raw}\t{checksum}\t{typed}\n"
        )
    return "".join(lines).encode()
