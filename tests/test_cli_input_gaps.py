"""Issue 15, finding 9: bad command-line input is one line and exit 2, before anything is created or started
(a protocol path that is a folder or binary: tests/test_station.py; ``export --out`` into a missing folder and a
header-only table for ``bench analyze iso9283``: tests/test_store_file.py)."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_line

from bench.cli import main

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"


@pytest.mark.parametrize("factor", ["inf", "nan", "-1", "0"])
def test_a_speed_factor_that_is_not_finite_and_positive_is_refused_naming_the_option(tmp_path, capsys, factor):
    store = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress", "--speed-factor", factor]) == 2
    shown = f"{float(factor):g}"
    assert _one_line(capsys) == (
        f"bench: error: speed factor = {shown}, expected a finite number > 0 "
        "(--speed-factor, how much faster than real time the simulators run)"
    )
    assert not store.exists()  # refused before the store opens: no empty file left behind


@pytest.mark.parametrize("factor", ["inf", "nan", "-1"])
def test_a_simulator_refuses_a_speed_factor_that_is_not_finite_and_positive(capsys, factor):
    assert main(["sim", "pkm5", "--speed-factor", factor]) == 2
    assert _one_line(capsys) == f"bench: error: --speed-factor = {float(factor)}, expected a finite number > 0"


def test_calliper_entry_into_a_missing_folder_or_onto_a_folder_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", open("/dev/null"))  # noqa: SIM115 - nothing is read before the refusal
    missing = tmp_path / "nope" / "readings.csv"
    assert main(["sensors", "calliper-entry", "--out", str(missing)]) == 2
    assert _one_line(capsys) == (
        f"bench: error: calliper-entry: --out {missing}: folder {missing.parent} does not "
        "exist, expected an existing folder"
    )
    assert main(["sensors", "calliper-entry", "--out", str(tmp_path)]) == 2
    assert _one_line(capsys) == f"bench: error: calliper-entry: --out {tmp_path}: a folder, expected a CSV file name"
    assert list(tmp_path.iterdir()) == []
