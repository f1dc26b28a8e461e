"""bench.store: provenance, sample durability (kill -9 of a writer), calibrations, tidy export."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, InsufficientData
from bench.store import DuplicateSample, Store, export_run, tidy_table


@pytest.fixture()
def store(tmp_path):
    with Store(tmp_path / "bench.db") as s:
        yield s


def _start(store, **overrides):
    args = {
        "protocol_name": "iso9283_pose",
        "protocol_version": "1",
        "robot": "pkm5",
        "config": {"cycles": 30},
        "settings": {"port": "/dev/pts/9"},
        "calibration_ids": [3, 1],
        "campaign": "lab-a",
    }
    args.update(overrides)
    return store.start_run(**args)


def test_run_is_running_with_full_provenance(store):
    run_id = _start(store)
    run = store.run(run_id)
    assert (run.status, run.reason, run.campaign) == ("running", None, "lab-a")
    assert run.config == {"cycles": 30} and run.settings == {"port": "/dev/pts/9"}
    assert run.calibration_ids == (1, 3)
    assert run.git_sha and run.software_version
    assert store._db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_status_is_settled_with_reason(store):
    run_id = _start(store)
    store.set_status(run_id, "aborted", "operator abort at cycle 3")
    run = store.run(run_id)
    assert (run.status, run.reason) == ("aborted", "operator abort at cycle 3")
    assert run.ended_utc is not None
    with pytest.raises(ConfigError, match="status = 'done', expected one of running, completed"):
        store.set_status(run_id, "done")


def test_unknown_run_is_named(store):
    with pytest.raises(ConfigError, match="run 42: no such run"):
        store.run(42)


def test_samples_round_trip_and_duplicates_refused(store):
    run_id = _start(store)
    store.add_sample(
        run_id, 4, values={"x_mm": 1.5, "cmd_x_mm": 1.0}, pose="P1", cycle=1, t_s=0.25, raw={"counts": [3, -2]}
    )
    with pytest.raises(DuplicateSample, match="run 1: step 4 already has a stored sample"):
        store.add_sample(run_id, 4, values={"x_mm": 9.0}, t_s=1.0)
    (sample,) = store.samples(run_id)
    assert (sample.step_index, sample.pose, sample.cycle, sample.t_s) == (4, "P1", 1, 0.25)
    assert sample.values == {"x_mm": 1.5, "cmd_x_mm": 1.0} and sample.raw == {"counts": [3, -2]}
    assert store.stored_steps(run_id) == {4}
    assert store.run(run_id).n_samples == 1


def test_non_finite_value_is_refused_naming_field(store):
    run_id = _start(store)
    with pytest.raises(ConfigError, match="step 0: y_mm = nan, expected a finite number"):
        store.add_sample(run_id, 0, values={"y_mm": float("nan")}, t_s=0.0)


def test_calibrations_are_versioned(store):
    first = store.add_calibration("mouse_xy", {"mm_per_count": [0.2055, 0.2049]})
    second = store.add_calibration("mouse_xy", {"mm_per_count": [0.2060, 0.2050]}, notes="after cleaning")
    assert (first.version, second.version) == (1, 2)
    assert store.calibration("mouse_xy").params == {"mm_per_count": [0.2060, 0.2050]}
    assert store.calibration("mouse_xy", 1).id == first.id
    with pytest.raises(ConfigError, match="calibration 'camera': any version not found"):
        store.calibration("camera")


def test_tidy_export_orders_columns_and_keeps_values(store, tmp_path):
    run_id = _start(store)
    for step, (pose, cycle, x) in enumerate([("P1", 1, 10.1), ("P2", 1, 20.2), ("P1", 2, 10.3)]):
        store.add_sample(
            run_id,
            step,
            pose=pose,
            cycle=cycle,
            t_s=step * 0.5,
            values={
                "x_mm": x,
                "y_mm": 0.0,
                "z_mm": 300.0,
                "cmd_x_mm": round(x),
                "cmd_y_mm": 0.0,
                "cmd_z_mm": 300.0,
                "velocity_pct": 100.0,
                "load_kg": 0.0,
            },
        )
    table = tidy_table(store, run_id)
    assert list(table.columns[:8]) == ["pose", "cycle", "cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "x_mm", "y_mm", "z_mm"]
    assert list(table.columns[8:]) == ["velocity_pct", "load_kg", "t_s", "step_index"]
    path = export_run(store, run_id, tmp_path / "run.csv")
    back = pd.read_csv(path)
    assert back["x_mm"].tolist() == [10.1, 20.2, 10.3] and back["cycle"].tolist() == [1, 1, 2]
    with pytest.raises(ConfigError, match="--format xls: expected one of csv, parquet"):
        export_run(store, run_id, tmp_path / "run.xls", fmt="xls")


def test_parquet_export_holds_the_same_table_as_csv(store, tmp_path):
    """The parquet extra (pyarrow, installed with the test extras): the same values and dtypes as the CSV."""
    run_id = _start(store)
    for step, (pose, x) in enumerate([("P1", 10.125), ("P2", -3.5)]):
        store.add_sample(
            run_id,
            step,
            pose=pose,
            cycle=1,
            t_s=step * 0.5,
            values={
                "x_mm": x,
                "y_mm": 0.0,
                "z_mm": 300.0,
                "cmd_x_mm": 10.0,
                "cmd_y_mm": 0.0,
                "cmd_z_mm": 300.0,
                "velocity_pct": 100.0,
                "load_kg": 0.0,
            },
        )
    csv = pd.read_csv(export_run(store, run_id, tmp_path / "run.csv"))
    parquet = pd.read_parquet(export_run(store, run_id, tmp_path / "run.parquet", fmt="parquet"))
    assert parquet["x_mm"].tolist() == [10.125, -3.5] and parquet["pose"].tolist() == ["P1", "P2"]
    pd.testing.assert_frame_equal(parquet[csv.columns], csv, check_dtype=False)


def test_export_of_empty_run_says_so(store):
    run_id = _start(store)
    with pytest.raises(InsufficientData, match="run 1: no 'pose' samples"):
        tidy_table(store, run_id)


@settings(max_examples=30, deadline=None)
@given(
    st.dictionaries(
        st.from_regex(r"[a-z]{1,6}_mm", fullmatch=True),
        st.floats(allow_nan=False, allow_infinity=False, width=64),
        min_size=1,
        max_size=5,
    )
)
def test_values_survive_the_round_trip_exactly(values):
    with Store(":memory:") as mem:
        run_id = _start(mem)
        mem.add_sample(run_id, 0, values=values, t_s=0.0)
        assert mem.samples(run_id)[0].values == values


_WRITER = textwrap.dedent("""
    import sys
    from bench.store import Store
    store = Store(sys.argv[1])
    run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
    for step in range(100000):
        store.add_sample(run_id, step, values={"x_mm": step * 0.1}, t_s=step * 0.001)
        print(step, flush=True)
""")


def test_kill_9_of_writer_loses_no_committed_sample(tmp_path):
    path = tmp_path / "bench.db"
    writer = subprocess.Popen([sys.executable, "-c", _WRITER, str(path)], stdout=subprocess.PIPE, text=True)
    reported = []
    for line in writer.stdout:
        reported.append(int(line))
        if len(reported) == 200:
            os.kill(writer.pid, signal.SIGKILL)
            break
    writer.wait(timeout=10)
    assert writer.returncode == -signal.SIGKILL
    with Store(path) as reopened:
        stored = reopened.stored_steps(1)
        assert set(reported) <= stored
        assert stored == set(range(len(stored)))  # no gap: each commit landed in order
        assert reopened.run(1).status == "interrupted"  # its owner was killed
        assert reopened.samples(1)[150].values == {"x_mm": pytest.approx(15.0)}


def test_export_without_kind_takes_pose_or_the_runs_most_frequent_kind(tmp_path, capsys):
    from bench.cli import main

    db = tmp_path / "kinds.db"
    with Store(db) as store:
        run_id = _start(store)
        for index, kind in enumerate(["leg_length", "leg_length", "manual"]):
            store.add_sample(
                run_id, index, values={"length_mm": 200.0 + index}, kind=kind, pose="L", cycle=index, t_s=float(index)
            )
        assert store.sample_kinds(run_id) == {"leg_length": 2, "manual": 1}
    out = tmp_path / "legs.csv"
    assert main(["export", str(run_id), "--store", str(db), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "exporting kind leg_length; the run also holds leg_length (2), manual (1)" in err
    assert list(pd.read_csv(out)["length_mm"]) == [200.0, 201.0]
