"""``from_json`` (msgspec, the standard library where msgspec refuses) reads stored JSON exactly as ``json.loads``."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.store.records import from_json

# every JSON value, with what only the standard library reads (NaN, infinities, lone surrogates) and integers
# beyond 64 bits (orjson turns those into floats: why msgspec was chosen)
_SCALARS = (
    st.none()
    | st.booleans()
    | st.integers()
    | st.integers(min_value=2**63 - 3, max_value=2**64 + 3)
    | st.integers(min_value=-(2**64), max_value=-(2**63) + 3)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.floats(min_value=-1e-300, max_value=1e-300)
    | st.text()
)
_VALUES = st.recursive(
    _SCALARS,
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=5), inner, max_size=5),
    max_leaves=20,
)


def _same(a: object, b: object) -> bool:
    """Equal values of equal types (NaN equal to NaN, -0.0 told from 0.0)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return (math.isnan(a) and math.isnan(b)) or (a == b and math.copysign(1, a) == math.copysign(1, b))  # type: ignore[arg-type]
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))  # type: ignore[arg-type]
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)  # type: ignore[attr-defined,index]
    return a == b


def _outcome(parse, text: str) -> tuple[str, object]:
    try:
        return "value", parse(text)
    except ValueError:
        return "error", None


@settings(max_examples=400, deadline=None)
@given(_VALUES, st.booleans())
def test_values_read_as_the_standard_library_reads_them(value: object, sorted_keys: bool) -> None:
    text = json.dumps(value, sort_keys=sorted_keys)
    assert _same(from_json(text), json.loads(text))
    assert _same(from_json(text.encode()), json.loads(text))  # bytes as the store may hand them


@settings(max_examples=400, deadline=None)
@given(_VALUES, st.data())
def test_damaged_text_fails_or_reads_as_the_standard_library(value: object, data: st.DataObject) -> None:
    """One character changed, dropped or added: the same value, or a ValueError, from both."""
    text = json.dumps(value)
    at = data.draw(st.integers(min_value=0, max_value=len(text)))
    change = data.draw(st.sampled_from(["replace", "drop", "insert"]))
    char = data.draw(st.sampled_from(list('0123456789.eE+-,:[]{}" \\nNaIfy\x00\ud800')))
    if change == "replace":
        text = text[:at] + char + text[at + 1 :]
    elif change == "drop":
        text = text[:at] + text[at + 1 :]
    else:
        text = text[:at] + char + text[at:]
    ours, theirs = _outcome(from_json, text), _outcome(json.loads, text)
    assert ours[0] == theirs[0], (text, ours, theirs)
    assert _same(ours[1], theirs[1])


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("123456789012345678901234567890", 123456789012345678901234567890),  # exact, not 1.2345678901234568e+29
        ("2.4703282292062328e-324", 5e-324),  # rounds half to even at the subnormal edge
        ("0.30000000000000004", 0.30000000000000004),
        ('{"a": 1, "a": 2}', {"a": 2}),
    ],
)
def test_edges(text: str, expected: object) -> None:
    assert _same(from_json(text), expected)
    assert _same(from_json(text), json.loads(text))
