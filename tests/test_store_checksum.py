"""Every stored sample carries a checksum: a flipped bit on disk is found by ``bench store check``, and a damaged
sample makes export, report and analysis refuse its run in one line naming the run and the step."""

from __future__ import annotations

import hashlib
import json
import shutil
import sqlite3
from pathlib import Path

import pytest
from cli_lines import one_error_line as _one_error_line
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main
from bench.store import DamagedSample, Store
from bench.store.connection import check_store
from bench.store.sample_checksum import sample_checksum

N_SAMPLES = 10


def _ap_mm(step: int) -> float:
    """A distinct value per sample, so each one's JSON text can be found in the file."""
    return 2.1 + step + 0.0625


@pytest.fixture(scope="module")
def sound_store(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("checksum") / "bench.db"
    with Store(path) as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        for step in range(N_SAMPLES):
            store.add_sample(run_id, step, values={"ap_mm": _ap_mm(step)}, pose="P2", cycle=step + 1, t_s=float(step))
        store.set_status(run_id, "completed")
    assert not Path(f"{path}-wal").exists()  # the last close copied the log into the file
    return path


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(step=st.integers(0, N_SAMPLES - 1), digit=st.integers(0, 5), bit=st.integers(0, 7))
def test_one_flipped_bit_in_a_stored_value_is_found_by_store_check(sound_store, tmp_path, step, digit, bit, capsys):
    text = json.dumps({"ap_mm": _ap_mm(step)}).encode()  # as the store wrote it (sorted keys, one value)
    data = bytearray(sound_store.read_bytes())
    assert data.count(text) == 1
    offset = data.index(text) + text.index(b": ") + 2 + digit  # a character of the number
    data[offset] ^= 1 << bit
    damaged = tmp_path / f"flip-{step}-{digit}-{bit}.db"
    damaged.write_bytes(bytes(data))

    assert check_store(str(sound_store)) == []
    assert main(["store", "check", str(damaged)]) == 1
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1 and out[0].startswith(f"{damaged}: run 1 sample at step {step} (samples row "), out


def test_a_changed_digit_refuses_export_and_report_in_one_line_naming_run_and_step(sound_store, tmp_path, capsys):
    damaged = tmp_path / "bench.db"
    shutil.copy(sound_store, damaged)
    with sqlite3.connect(damaged) as db:  # 2.1625 -> 2.4625: the digit changed, the JSON still parses
        db.execute("UPDATE samples SET values_json = replace(values_json, '3.1625', '3.4625') WHERE step_index = 1")
    db.close()
    expected = (
        f"bench: error: store {damaged}: run 1 sample at step 1 is damaged: its stored bytes no longer "
        "match their checksum (changed since it was stored); its run is refused, nothing computed from it: "
        f"list the damage with `bench store check {damaged}` and read a backup copy"
    )
    out = tmp_path / "run1.csv"
    assert main(["export", "1", "--store", str(damaged), "--out", str(out)]) == 1
    assert _one_error_line(capsys) == expected
    assert not out.exists()
    with Store(damaged, read_only=True) as store, pytest.raises(DamagedSample, match="run 1 sample at step 1"):
        store.samples(1)


def test_damaged_json_is_named_in_one_line_never_a_traceback(sound_store, tmp_path, capsys):
    damaged = tmp_path / "bench.db"
    shutil.copy(sound_store, damaged)
    broken = '{"ap_mm": 4.1'
    with sqlite3.connect(damaged) as db:  # damaged JSON under a checksum that matches it (a bad migrated row)
        step, kind, pose, cycle, t_s, wall_utc, raw_json = db.execute(
            "SELECT step_index, kind, pose, cycle, t_s, wall_utc, raw_json FROM samples WHERE step_index = 2"
        ).fetchone()
        checksum = sample_checksum(step, kind, pose, cycle, t_s, wall_utc, broken, raw_json)
        db.execute("UPDATE samples SET values_json = ?, checksum = ? WHERE step_index = 2", (broken, checksum))
    db.close()
    assert main(["export", "1", "--store", str(damaged), "--out", str(tmp_path / "run1.csv")]) == 1
    line = _one_error_line(capsys)
    assert line.startswith(
        f"bench: error: store {damaged}: run 1 sample at step 2 is damaged: its values_json does not parse ("
    ), line
    assert main(["store", "check", str(damaged)]) == 1
    [problem] = capsys.readouterr().out.splitlines()
    assert problem.startswith(f"{damaged}: run 1 sample at step 2 (samples row 3): its values_json does not parse")


def test_a_sound_store_checks_ok_and_its_checksums_are_the_stored_columns(sound_store, capsys):
    assert main(["store", "check", str(sound_store)]) == 0
    assert capsys.readouterr().out == f"{sound_store}: ok\n"
    with sqlite3.connect(sound_store) as db:
        rows = db.execute(
            "SELECT step_index, kind, pose, cycle, t_s, wall_utc, values_json, raw_json, checksum"
            " FROM samples ORDER BY step_index"
        ).fetchall()
    db.close()
    assert len(rows) == N_SAMPLES
    for step, kind, pose, cycle, t_s, wall_utc, values_json, raw_json, checksum in rows:  # recomputed by hand
        assert raw_json is None and kind == "pose"
        text = f"{step}\x1fpose\x1f{pose}\x1f{cycle}\x1f{t_s!r}\x1f{wall_utc}\x1f{values_json}\x1f\x00"
        assert checksum == hashlib.sha256(text.encode()).hexdigest()
