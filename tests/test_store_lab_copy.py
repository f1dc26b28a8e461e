"""The lab sync's COPY text (:func:`bench.store.lab_copy.copy_text`) read back by an independent decoder of
PostgreSQL's text format (manual, COPY, "Text Format": tab between fields, ``\\N`` for NULL, backslash escapes)
gives every stored column back exactly, whatever the text holds (hypothesis), and the typed columns hold the JSON's
numbers (NULL where it holds none)."""

from __future__ import annotations

import json

from hypothesis import given, settings
from hypothesis import strategies as st

from bench.store.lab_copy import COPY_COLUMNS, TYPED_COLUMNS, copy_text
from bench.store.sample_checksum import sample_checksum

_UNESCAPE = {"\\": "\\", "t": "\t", "n": "\n", "r": "\r", "b": "\b", "f": "\f", "v": "\v"}


def decode_field(field: str) -> str | None:
    """One field of PostgreSQL's COPY text format."""
    if field == "\\N":
        return None
    out, chars = [], iter(field)
    for char in chars:
        if char == "\\":
            follower = next(chars)
            out.append(_UNESCAPE.get(follower, follower))
        else:
            out.append(char)
    return "".join(out)


def decode(text: bytes) -> list[list[str | None]]:
    lines = text.decode().split("\n")
    assert lines[-1] == ""
    return [[decode_field(f) for f in line.split("\t")] for line in lines[:-1]]


def _row(step, kind, pose, cycle, t_s, wall, values, raw):
    values_json = json.dumps(values, sort_keys=True)
    raw_json = None if raw is None else json.dumps(raw, ensure_ascii=False)
    stored = (step, kind, pose, cycle, t_s, wall, values_json, raw_json)
    return (*stored, sample_checksum(*stored))  # as Store.stored_rows(checksum=True) reads it


awkward = st.lists(st.sampled_from(["a", "N", "\\", "\t", "\n", "\r", "None", "\\N", "µ", " ", ","]), max_size=6).map(
    "".join
)
numbers = st.floats(allow_nan=False, allow_infinity=False) | st.integers(-(2**53), 2**53)
values = st.dictionaries(
    st.sampled_from([*TYPED_COLUMNS[:8], "note"]),
    numbers | st.booleans() | awkward | st.none() | st.lists(numbers, max_size=2),
    max_size=6,
)
rows = st.lists(
    st.builds(
        _row,
        st.integers(0, 10**6),
        awkward.filter(bool),
        st.none() | awkward,
        st.none() | st.integers(1, 100),
        st.floats(allow_nan=False, allow_infinity=False),
        awkward,
        values,
        st.none() | st.dictionaries(st.just("text"), awkward),
    ),
    min_size=1,
    max_size=5,
)


@settings(max_examples=300, deadline=None)
@given(rows)
def test_copy_text_gives_every_column_back(rows):
    run_uuid = "4e9af590-0000-4000-8000-000000000001"
    decoded = decode(copy_text(run_uuid, rows))
    assert len(decoded) == len(rows)
    for fields, row in zip(decoded, rows):
        assert len(fields) == len(COPY_COLUMNS)
        step, kind, pose, cycle, t_s, wall, values_json, raw_json, checksum = row
        assert fields[0] == run_uuid and fields[1] == str(step)
        assert fields[2:4] == [kind, pose] and fields[4] == (None if cycle is None else str(cycle))
        assert float(fields[5]) == t_s  # the same double (shortest round-trip text)
        assert fields[6:10] == [wall, values_json, raw_json, checksum]
        values = json.loads(values_json)
        for name, field in zip(TYPED_COLUMNS, fields[10:]):
            value = values.get(name)
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            assert (field is None) == (not number), (name, value, field)
            if number:
                assert float(field) == float(value)


def test_json_only_the_standard_library_reads_keeps_its_numbers():
    """A key with an escaped lone surrogate (``to_json`` writes one; msgspec refuses it, ``json.loads`` reads it):
    the row is not refused as damaged, its typed numbers are sent."""
    from bench.store.records import to_json

    values_json = to_json({"x\ud800": 1.0, "cmd_x_mm": 2.5, "x_mm": -0.0}, "values")
    stored = (3, "pose", "P1", 1, 0.5, "w", values_json, None)
    (fields,) = decode(copy_text("4e9af590-0000-4000-8000-000000000001", [(*stored, sample_checksum(*stored))]))
    typed = dict(zip(TYPED_COLUMNS, fields[10:]))
    assert typed["cmd_x_mm"] == "2.5" and typed["x_mm"] == "-0.0"
    assert all(v is None for k, v in typed.items() if k not in ("cmd_x_mm", "x_mm"))
