"""Run names across benches (bench.store.lab_reader.pick_run): BENCH/ID, a UUID or its 8+ digit prefix, a bare ID."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from bench.errors import ConfigError
from bench.store.lab_reader import pick_run

RECORDS = [
    SimpleNamespace(bench="bench-a", id=1, uuid="24600023-9f1c-4d2e-8a7b-0c5d6e7f8091"),
    SimpleNamespace(bench="bench-b", id=1, uuid="a1b2c3d4-0000-4000-8000-000000000001"),
    SimpleNamespace(bench="bench-b", id=2, uuid="a1b2c3d5-0000-4000-8000-000000000002"),
]


def test_a_uuid_prefix_of_decimal_digits_names_its_run():
    # 1 in 43 UUIDs starts with 8 decimal digits: such a prefix was read as a run id and "no such run" (a CI failure)
    assert pick_run(RECORDS, "24600023", "lab").uuid == RECORDS[0].uuid
    assert pick_run(RECORDS, "a1b2c3d5", "lab") is RECORDS[2]
    assert pick_run(RECORDS, "bench-b/1", "lab") is RECORDS[1]
    assert pick_run(RECORDS, "2", "lab") is RECORDS[2]


def test_a_bare_id_two_benches_share_is_refused_naming_both():
    with pytest.raises(ConfigError, match=r"names 2 runs in lab \(bench-a/1 \(24600023\), bench-b/1 \(a1b2c3d4\)\)"):
        pick_run(RECORDS, "1", "lab")
    with pytest.raises(ConfigError, match="no such run in lab"):
        pick_run(RECORDS, "99999999", "lab")
