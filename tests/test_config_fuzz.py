"""Fuzzed protocol and station files (hypothesis over their TOML schema): each one either loads or is refused in
one line with exit 2, never a traceback, a hang or a plan too large to build.

Every example file is the seed: a mutation replaces a value (a leaf, a list, a whole table) by a value of any TOML
type, nasty numbers included (0, -1, 1e20, 1e308, inf, nan, 2**63 - 1), or adds a key: an unknown one (any unicode
text too), or a station's ``[lab_store]`` with a malformed address holding a password no message may show."""

from __future__ import annotations

import datetime
import json
import math
import tomllib
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main
from bench.errors import ConfigError
from bench.rigs.station import load_station

ROOT = Path(__file__).resolve().parents[1]
PROTOCOL_FILES = sorted((ROOT / "examples").glob("*.toml"))
STATION_FILES = sorted((ROOT / "examples" / "stations").glob("*.toml"))


def toml_value(value: Any) -> str:
    """``value`` as a TOML inline value (the test's own writer: the standard library only reads TOML)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, (datetime.date, datetime.datetime)):
        return value.isoformat()
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return "{ " + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in value.items()) + " }"


def toml_document(document: dict[str, Any]) -> str:
    """A whole document: plain keys first, then each table as a ``[section]``."""
    lines = [f"{json.dumps(k)} = {toml_value(v)}" for k, v in document.items() if not isinstance(v, dict)]
    for key, table in document.items():
        if isinstance(table, dict):
            lines.append(f"[{json.dumps(key)}]")
            lines.extend(f"{json.dumps(k)} = {toml_value(v)}" for k, v in table.items())
    return "\n".join(lines) + "\n"


def _plausible(number: float) -> bool:  # small, absurd or not finite; never a huge-but-allowed plan size
    return not math.isfinite(number) or abs(number) <= 50 or abs(number) >= 1e6


LEAVES = st.one_of(
    st.booleans(),
    st.integers(-3, 40),
    st.sampled_from([0, -1, 10**6, 2**31, 2**63 - 1, -(2**63)]),
    st.floats().filter(_plausible),
    st.sampled_from([1e20, 1e308, -1e308, 5e-324]),
    st.text(max_size=8),
    st.sampled_from(["50 mm", "2 s", "10 %", "", "pkm5", "delta4", "1e20", "iso9283_pose"]),
    st.dates(),
    st.datetimes(),
)
#: A password no message may show: lab store addresses carry one (docs/lab-store.md).
SECRET = "s3cr3t-Pw"
LAB_URLS = st.builds(
    "{}://bench:{}@{}".format,
    st.sampled_from(["postgresql", "postgres", "mysql", "http"]),
    st.just(SECRET),
    st.sampled_from(["[::1/lab", "localhost/lab?sslmode=bogus", "h:99999/lab", "h/lab?colour=blue", "h/lab", ""]),
)
VALUES = st.recursive(
    LEAVES,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(min_size=1, max_size=6), inner, max_size=3),
    max_leaves=8,
)


@st.composite
def mutated(draw, seeds: list[Path]) -> dict[str, Any]:
    """One seed document with one to three mutations."""
    document = tomllib.loads(draw(st.sampled_from(seeds)).read_text(encoding="utf-8"))
    for _ in range(draw(st.integers(1, 3))):
        table = document
        tables = [k for k, v in document.items() if isinstance(v, dict)]
        if tables and draw(st.booleans()):
            table = document[draw(st.sampled_from(tables))]
        keys = sorted(table)
        if keys and draw(st.integers(0, 4)):
            table[draw(st.sampled_from(keys))] = draw(VALUES)
        else:
            key = draw(
                st.sampled_from(["cycels", "extra", "robot", "protocol", "poses", "station", "lab_store"])
                | st.text(min_size=1, max_size=6)
            )
            table[key] = draw(st.fixed_dictionaries({"url": LAB_URLS}) if key == "lab_store" else VALUES)
    return document


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(document=mutated(PROTOCOL_FILES))
def test_fuzzed_protocol_file_loads_or_is_one_line_exit_2(tmp_path, capsys, document):
    path = tmp_path / "fuzzed.toml"
    path.write_text(toml_document(document), encoding="utf-8")
    capsys.readouterr()
    code = main(["run", str(path), "--dry-run"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code in (0, 2), err
    if code == 2:
        assert len(err) == 1 and err[0].startswith("bench: error: "), err


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(document=mutated(STATION_FILES))
def test_fuzzed_station_file_loads_or_is_one_line_exit_2(tmp_path, document):
    path = tmp_path / "station.toml"
    path.write_text(toml_document(document), encoding="utf-8")
    try:
        load_station(path)
    except ConfigError as exc:
        assert exc.exit_code == 2 and "\n" not in str(exc), str(exc)
        assert not ("lab_store" in str(exc) and SECRET in str(exc)), str(exc)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.sampled_from(STATION_FILES), url=LAB_URLS, auto_sync=st.booleans() | LEAVES)
def test_a_station_lab_store_address_loads_or_is_one_line_without_its_password(tmp_path, seed, url, auto_sync):
    document = tomllib.loads(seed.read_text(encoding="utf-8"))
    document["lab_store"] = {"url": url, "auto_sync": auto_sync}
    path = tmp_path / "station.toml"
    path.write_text(toml_document(document), encoding="utf-8")
    try:
        load_station(path)
    except ConfigError as exc:
        assert exc.exit_code == 2 and "\n" not in str(exc) and SECRET not in str(exc), str(exc)


@pytest.mark.parametrize("seed", PROTOCOL_FILES + STATION_FILES, ids=lambda p: p.name)
def test_the_writer_round_trips_every_seed(seed):
    document = tomllib.loads(seed.read_text(encoding="utf-8"))
    assert tomllib.loads(toml_document(document)) == document
