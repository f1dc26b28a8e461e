"""Resumes: segments labelled on the run's monotonic time (a wall-clock jump relabels nothing), a refused resume
writes nothing and says what to do, and the report's run history shows every abort and resume."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from cli_runs import store_dump

from bench.cli import main
from bench.reports.summary import run_history
from bench.store import Store, tidy_table

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"
START = datetime(2026, 12, 4, 9, 0, tzinfo=UTC)


def _clock(offsets_s: list[float]):
    """A wall clock that reads START + each offset in turn (a jump is a smaller next offset)."""
    readings = iter(offsets_s)
    return lambda: (START + timedelta(seconds=next(readings))).isoformat(timespec="microseconds")


def _registration(at_s: float) -> dict:
    return {
        "utc": (START + timedelta(seconds=at_s)).isoformat(timespec="microseconds"),
        "u_mm": 0.01,
        "instrument": "mice",
    }


@pytest.mark.parametrize(
    "resumed_wall_s",
    [
        [10 + k - 7200 for k in range(5)],  # the clock 2 h behind for the whole resumed segment
        [10, 11, -3589, -3588, -3587],  # a 1 h step back in the middle of it
    ],
)
def test_a_wall_clock_jump_relabels_no_segment(tmp_path, resumed_wall_s):
    with Store(tmp_path / "bench.db") as store:
        run_id = store.start_run(
            protocol_name="p",
            protocol_version="1",
            robot="pkm5",
            config={},
            settings={"registrations": [{**_registration(0), "segment": 1, "from_step": 0}]},
        )
        store.wall_clock = _clock([1, 2, 3, 4, 5, *resumed_wall_s])
        for step in range(5):  # segment 1, then the run is stopped and resumed with a registration of its own
            store.add_sample(run_id, step, values={"x_mm": 1.0}, pose="P1", cycle=step + 1, t_s=float(step))
        assert store.add_registration(run_id, {**_registration(9), "from_step": 5}) == 2
        for step in range(5, 10):  # t_s continues on the runner's monotonic time
            store.add_sample(run_id, step, values={"x_mm": 1.0}, pose="P1", cycle=step + 1, t_s=10.0 + step)
        table = tidy_table(store, run_id, kind="pose")
    assert list(table["registration"]) == [1] * 5 + [2] * 5


@pytest.fixture()
def aborted_run(tmp_path) -> Path:
    store = tmp_path / "bench.db"
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress", "--seed", "2"]) == 0
    with Store(store) as opened:
        opened.set_status(1, "aborted", "interrupted (SIGTERM)")
    return store


def test_a_resume_refused_for_its_calibration_writes_nothing_and_says_what_to_do(aborted_run, capsys):
    with Store(aborted_run) as store:  # the simulated mice's calibration changed since the run began
        calibration = store.calibration_by_id(store.run(1).calibration_ids[0])
        store.add_calibration(calibration.name, {**calibration.params, "mm_per_count": 0.0318})
    before = store_dump(aborted_run)
    capsys.readouterr()
    assert main(["resume", "1", "--store", str(aborted_run), "--no-progress"]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert lines[-1] == (
        f"bench: error: run 1: calibration {calibration.name!r} in force would be a new version "
        "(version 2 is the latest, with other parameters); a run resumes only with the "
        "calibrations it started with: start a new run (bench run)"
    ), captured.err
    assert "Traceback" not in captured.err
    assert store_dump(aborted_run) == before


def test_the_run_history_shows_every_abort_and_resume(aborted_run, capsys):
    assert main(["resume", "1", "--store", str(aborted_run), "--no-progress"]) == 0
    with Store(aborted_run, read_only=True) as store:
        run = store.run(1)
        events = [event.event for event in run_history(store, run)]
    assert run.status == "completed"
    assert events[0] == "started" and events[-1] == "completed"
    assert [e for e in events if e.startswith(("aborted", "resumed"))] == ["aborted: interrupted (SIGTERM)", "resumed"]
