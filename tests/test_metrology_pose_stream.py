"""A pose table read a chunk at a time (bench.metrology.pose_stream) gives the figures of the whole table read at once,
bit for bit, for any chunk size and row order, and refuses a bad table with the message the whole-table path gives
(the fault placed in a later chunk, its row numbered in the file)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology.pose_stream import analyze_pose_file
from bench.metrology.tables import POSE_NUMERIC_COLUMNS, analyze_poses, pose_result_json, pose_table, read_table_csv

HEADER = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm,cmd_a_deg,a_deg,velocity_pct,load_kg,frame"


def _rows(seed: int = 0) -> list[str]:
    """Three poses at two velocities (load constant), 12 cycles each (the measurement model's U), one at 120 cycles
    (the delta method's), with an angle and a frame tag."""
    rng = np.random.default_rng(seed)
    rows = []
    for pose, cycles in (("P1", 12), ("P2", 12), ("P3", 120)):
        command = rng.uniform(-50, 50, 3).round(3)
        for velocity in (50, 100):
            for cycle in range(1, cycles + 1):
                x, y, z = command + rng.normal(0, [0.3, 0.2, 0.1])
                a = 1.5 + rng.normal(0, 0.05)
                rows.append(
                    f"{pose},{cycle},{command[0]},{command[1]},{command[2]},{x:.5f},{y:.5f},{z:.5f},1.5,{a:.5f},"
                    f"{velocity},2,base"
                )
    return rows


def _write(tmp_path, rows: list[str], header: str = HEADER):
    path = tmp_path / "poses.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def _whole(path) -> list[dict]:
    table = pose_table(read_table_csv(path, numeric=POSE_NUMERIC_COLUMNS), partial_axes=True)
    return [pose_result_json(r) for r in analyze_poses(table, instrument_u_mm=0.01)]


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(chunk_rows=st.integers(1, 400), seed=st.integers(0, 2**32 - 1))
def test_chunks_give_the_whole_tables_figures_bit_for_bit(tmp_path, chunk_rows, seed):
    rows = _rows()
    np.random.default_rng(seed).shuffle(rows)  # row order carries no meaning, in a chunk or across chunks
    path = _write(tmp_path, rows)
    streamed = [pose_result_json(r) for r in analyze_pose_file(path, instrument_u_mm=0.01, chunk_rows=chunk_rows)]
    assert streamed == _whole(path)


def test_a_fault_in_a_later_chunk_is_the_whole_tables_message(tmp_path):
    for fault in ("command", "frame", "cycle"):
        rows = _rows()
        if fault == "command":
            rows[200] = rows[200].replace(rows[200].split(",")[2], "999", 1)
        elif fault == "frame":
            rows[150] = rows[150].removesuffix("base") + "tool"
        else:
            rows[230] = rows[230].split(",", 2)[0] + ",5," + rows[230].split(",", 2)[2]
        path = _write(tmp_path, rows)
        with pytest.raises(ConfigError) as whole:
            _whole(path)
        with pytest.raises(ConfigError) as streamed:
            analyze_pose_file(path, chunk_rows=64)
        assert str(streamed.value) == str(whole.value), fault
        assert "row " in str(whole.value)


def test_a_table_that_is_not_plain_is_left_to_the_whole_reader(tmp_path, capsys):
    rows = _rows()
    rows[100] = rows[100].replace(",2,base", ",two,base")
    path = _write(tmp_path, rows)
    assert analyze_pose_file(path, chunk_rows=64) is None
    assert main(["analyze", "iso9283", str(path), "--chunk-rows", "64"]) == 2
    assert (
        capsys.readouterr().err.strip()
        == f"bench: error: {path}: row 101, column load_kg: 'two' is not a finite number"
    )


def test_the_cli_prints_the_same_json_in_chunks(tmp_path, capsys):
    path = _write(tmp_path, _rows())
    outputs = []
    for extra in ([], ["--chunk-rows", "50"]):
        assert main(["analyze", "iso9283", str(path), "--json", *extra]) == 0
        outputs.append(json.loads(capsys.readouterr().out))
    assert outputs[0] == outputs[1]
    assert sorted(outputs[0]["poses"]) == sorted(
        f"{p} (velocity_pct={v})" for p in ("P1", "P2", "P3") for v in (50, 100)
    )
