"""Every signal is a safe stop: SIGTERM and SIGHUP stop the robot and end the run aborted and resumable, like a
double Ctrl-C; end of input while paused aborts once instead of asking forever."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest
from cli_runs import QUICK, STATION, start_station_run, wait_for_samples

from bench.cli import main
from bench.store import Store


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_aborts_the_run_resumably_and_resume_completes_it(tmp_path, stop, capsys):
    store = tmp_path / "b.db"
    process = start_station_run(store, "300")
    wait_for_samples(store, process, 2)
    process.send_signal(stop)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 1, err
    assert f"bench: {stop.name}: stopping the robot and aborting the run (resumable)" in err
    with Store(store) as opened:
        (run,) = opened.runs()
        before = {s.step_index: s.values for s in opened.samples(run.id)}
    assert run.status == "aborted" and run.reason == f"interrupted ({stop.name})" and 2 <= len(before) < 15
    assert (
        main(["resume", str(run.id), "--station", str(STATION), "--sim", "--store", str(store), "--no-progress"]) == 0
    )
    capsys.readouterr()
    with Store(store) as opened:
        (run,) = opened.runs()
        after = {s.step_index: s.values for s in opened.samples(run.id)}
    assert run.status == "completed" and len(after) == 15
    assert all(after[step] == values for step, values in before.items())  # stored rows unchanged


def test_ctrl_c_with_stdin_at_its_end_aborts_once(tmp_path):
    store = tmp_path / "b.db"
    process = start_station_run(store, "60")
    wait_for_samples(store, process, 1)
    process.send_signal(signal.SIGINT)  # pause at the next checkpoint, then the pause menu reads end of input
    out, err = process.communicate(timeout=120)
    assert process.returncode == 1
    assert "end of input while paused: aborting (resumable)" in err
    assert err.count("paused: [r]esume") == 1 and len(err) < 20_000
    with Store(store) as opened:
        (run,) = opened.runs()
    assert run.status == "aborted"


def test_a_resume_that_changes_the_seed_is_refused(tmp_path, capsys):
    store = tmp_path / "b.db"
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress", "--seed", "3"]) == 0
    run_id = int(capsys.readouterr().out.split()[-1])
    assert main(["resume", str(run_id), "--store", str(store), "--seed", "4"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        "bench: error: seed = 4: the run was made with seed 3, expected the same (a resume keeps the "
        "run's own; leave the seed out)"
    )
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--speed-factor", "inf"]) == 2
    assert "speed factor = inf, expected a finite number > 0" in capsys.readouterr().err
