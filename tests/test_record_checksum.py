"""Every stored run and calibration record carries a checksum, as every sample does: a changed digit in a run's
settings or a calibration's parameters is found by ``bench store check`` and refused in one line, never read as
another number; bench's own changes to a run (its status, its registrations) keep it sealed."""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_error_line
from hypothesis import given
from hypothesis import strategies as st

from bench.cli import main
from bench.store import Store
from bench.store.connection import check_store
from bench.store.record_checksum import DamagedRecord, record_checksum
from bench.store.schema import SCHEMA_VERSION

PARAMS = {"scale_mm_per_count": 0.0254, "offset_mm": 1.25}


@pytest.fixture(scope="module")
def sound_store(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("records") / "bench.db"
    with Store(path) as store:
        calibration = store.add_calibration("mouse_xy", PARAMS)
        run_id = store.start_run(
            protocol_name="p",
            protocol_version="1",
            robot="pkm5",
            config={"cycles": 30},
            settings={"speed_pct": 50},
            calibration_ids=[calibration.id],
        )
        store.add_sample(run_id, 0, values={"x_mm": 1.0}, pose="P1", cycle=1, t_s=0.0)
        store.add_registration(run_id, {"u_mm": 0.25})
        store.set_status(run_id, "aborted", "stopped by the operator")
        store.set_status(run_id, "running")
        store.set_status(run_id, "completed")
    return path


def _changed(sound_store: Path, tmp_path: Path, sql: str) -> Path:
    damaged = tmp_path / "bench.db"
    shutil.copy(sound_store, damaged)
    with sqlite3.connect(damaged) as db:
        assert db.execute(sql).rowcount == 1
    db.close()
    return damaged


def test_a_sound_store_checks_ok_after_bench_changed_its_run(sound_store):
    assert check_store(str(sound_store)) == []
    with Store(sound_store, read_only=True) as store:
        [run] = store.runs()
        assert run.status == "completed" and run.settings["registrations"][0]["u_mm"] == 0.25
        assert [e["event"] for e in run.settings["history"]] == ["aborted", "resumed", "completed"]
        assert store.calibration("mouse_xy").params == PARAMS


def test_the_checksums_are_the_stored_columns_hashed(sound_store):
    with sqlite3.connect(sound_store) as db:
        *fields, checksum = db.execute(
            "SELECT uuid, name, version, created_utc, params_json, source_run_id, notes, checksum FROM calibrations"
        ).fetchone()
    db.close()
    text = "\x1f".join("\x00" if f is None else str(f) for f in fields)  # recomputed by hand
    assert fields[5] is None and checksum == hashlib.sha256(text.encode()).hexdigest()


def test_a_changed_digit_in_a_runs_settings_is_refused_in_one_line(sound_store, tmp_path, capsys):
    damaged = _changed(
        sound_store,
        tmp_path,
        "UPDATE runs SET settings_json = replace(settings_json, '\"speed_pct\": 50', '\"speed_pct\": 80')",
    )
    expected = (
        f"bench: error: store {damaged}: run 1 is damaged: its stored bytes no longer match their checksum "
        f"(changed since it was stored); it is refused, nothing computed from it: list the damage with "
        f"`bench store check {damaged}` and read a backup copy"
    )
    out = tmp_path / "run1.csv"
    assert main(["export", "1", "--store", str(damaged), "--out", str(out)]) == 1
    assert _one_error_line(capsys) == expected and not out.exists()
    assert main(["runs", "--store", str(damaged)]) == 1
    assert _one_error_line(capsys) == expected
    assert main(["store", "check", str(damaged)]) == 1
    assert capsys.readouterr().out.splitlines() == [
        f"{damaged}: run 1 (runs row 1): its stored bytes no longer match their checksum (changed since it was stored)"
    ]


def test_a_changed_digit_in_a_calibrations_parameters_is_refused(sound_store, tmp_path, capsys):
    damaged = _changed(
        sound_store, tmp_path, "UPDATE calibrations SET params_json = replace(params_json, '0.0254', '0.0264')"
    )
    with Store(damaged, read_only=True) as store, pytest.raises(DamagedRecord, match=r"calibration 1 is damaged"):
        store.calibration("mouse_xy")
    assert main(["store", "check", str(damaged)]) == 1
    assert capsys.readouterr().out.splitlines() == [
        f"{damaged}: calibration 1 (calibrations row 1): its stored bytes no longer match their checksum "
        "(changed since it was stored)"
    ]


def test_a_record_written_outside_bench_is_named(sound_store, tmp_path):
    damaged = _changed(sound_store, tmp_path, "UPDATE runs SET checksum = NULL")
    assert check_store(str(damaged)) == [f"{damaged}: run 1 (runs row 1): it has no checksum (written outside bench)"]


def test_a_version_3_store_is_migrated_with_its_records_sealed(sound_store, tmp_path):
    old = _changed(sound_store, tmp_path, "UPDATE runs SET checksum = NULL")  # then as schema 3 wrote it:
    with sqlite3.connect(old) as db:
        db.execute("ALTER TABLE runs DROP COLUMN checksum")
        db.execute("ALTER TABLE calibrations DROP COLUMN checksum")
        db.execute("PRAGMA user_version = 3")
    db.close()
    assert check_store(str(old)) == []  # nothing to check yet
    with Store(old) as store:
        assert store.runs()[0].settings["speed_pct"] == 50
    assert Path(f"{old}.schema-v3.bak").exists()
    with sqlite3.connect(old) as db:
        assert db.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 4
        assert db.execute("SELECT count(*) FROM runs WHERE checksum IS NOT NULL").fetchone()[0] == 1
        assert db.execute("SELECT count(*) FROM calibrations WHERE checksum IS NOT NULL").fetchone()[0] == 1
    db.close()
    assert check_store(str(old)) == []


#: bench's text never holds U+0000 (NULL's mark) or U+001F (the separator): JSON escapes both; nor a lone surrogate
#: (the stored JSON escapes them, and text read from non-UTF-8 bytes holds only the ones that stand for those bytes)
_TEXT = st.text(alphabet=st.characters(blacklist_characters="\x00\x1f", blacklist_categories=("Cs",)), max_size=8)
_FIELD = st.one_of(st.none(), st.integers(-(10**6), 10**6), _TEXT)


@given(fields=st.lists(_FIELD, min_size=1, max_size=6), index=st.data())
def test_changing_any_one_field_changes_the_checksum(fields, index):
    i = index.draw(st.integers(0, len(fields) - 1))
    other = index.draw(_FIELD.filter(lambda v: str(v) != str(fields[i]) or (v is None) != (fields[i] is None)))
    changed = [*fields[:i], other, *fields[i + 1 :]]
    assert record_checksum(*changed) != record_checksum(*fields)
