"""End to end against the simulated pkm5 over a pty: runs, the CLI, kill -9 and resume, AP/RP against the truth."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cli_runs import wait_for_samples

from bench.cli import main
from bench.commands.demo import analyze_run
from bench.launch import simulated_rig_in
from bench.protocols import PROTOCOLS, Runner
from bench.protocols.iso9283 import PoseAccuracy
from bench.protocols.plan import iterate, step_stores_sample
from bench.simulators.error_model import ErrorModel
from bench.simulators.pkm5_plant import PKM5_ERRORS
from bench.simulators.rig import simulated_rig
from bench.store import Store, tidy_table
from motion import pkm5

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_pose_quick.toml"


def _run_id(capsys) -> int:
    return int(capsys.readouterr().out.strip().splitlines()[-1])


def test_dry_run_prints_the_plan_and_moves_nothing(capsys, tmp_path):
    assert main(["run", str(QUICK), "--dry-run", "--store", str(tmp_path / "b.db")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("protocol iso9283_pose on pkm5: 16 moves, 15 settles, 15 captures, 3 checkpoints")
    assert "estimated duration" in out and out.count(" ok\n") == 6
    assert not (tmp_path / "b.db").exists()


def test_unreachable_target_is_refused_before_any_motion(capsys, tmp_path):
    bad = tmp_path / "far.toml"
    bad.write_text('protocol = "iso9283_pose"\ncycles = 2\n[poses]\nP1 = [110, 0, 320]\nFAR = [110, 0, 400]\n')
    assert main(["run", str(bad), "--sim", "--store", str(tmp_path / "b.db")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("bench: error: far.toml: target FAR (x 110.00 mm, y 0.00 mm, z 400.00 mm")
    assert "is not reachable: leg 1 length" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "b.db").exists()  # refused before the store, the simulator or the port was opened


def test_run_list_export_analyze(capsys, tmp_path):
    db = str(tmp_path / "b.db")
    assert main(["run", str(QUICK), "--sim", "--store", db, "--no-progress", "--seed", "4"]) == 0
    run_id = _run_id(capsys)
    assert main(["runs", "--store", db, "--json"]) == 0
    (record,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert (record["id"], record["status"], record["n_samples"]) == (run_id, "completed", 15)
    assert record["settings"]["simulator"] == {"seed": 4} and len(record["calibration_ids"]) == 1
    out = tmp_path / "run.csv"
    assert main(["export", str(run_id), "--store", db, "--out", str(out)]) == 0
    table = pd.read_csv(out)
    assert len(table) == 15 and set(table["pose"]) == {"P1", "P2", "P3", "P4", "P5"}
    capsys.readouterr()
    assert main(["analyze", "iso9283", str(out), "--json"]) == 0
    poses = json.loads(capsys.readouterr().out)["poses"]
    assert sorted(poses) == ["P1", "P2", "P3", "P4", "P5"] and all(p["n"] == 3 for p in poses.values())


#: The path protocols here are segmented with a 0.05 mm chord error instead of 0.01: half the segments (the
#: rectangle 43 instead of 83, the line 15 instead of 29) stream through the same steps, corners and captures; how
#: closely the segments follow the path is tested in tests/test_path_protocols.py.
QUICK_PARAMETERS = {
    "iso9283_pose": {"cycles": 2, "velocities_pct": [100], "loads_kg": [0, 2.5]},
    "iso9283_distance": {"cycles": 2, "velocities_pct": [100]},
    "iso9283_drift": {"cycles": 4, "velocities_pct": [100], "pause_s": 0.5},
    "iso9283_multidirectional": {"cycles": 2, "velocities_pct": [100]},
    "dissertation_pose": {"variant": "beta", "cycles": 2},
    "lasergrid_hits": {"attempts": 2, "heights_mm": [-170], "spread": 2},
    "delta_positioning": {"cycles": 2},
    "payload_ladder": {"loads_kg": [0.45, 7.08, 25.23]},
    "mouse_calibration": {
        "repeats": 2,
        "distances_mm": [5, 20, 40],
        "reference": "calibrated-axis",
        "reference_u_pct": 0.05,
    },
    "actuator_accuracy": {"repeats": 2, "distances_mm": [10, 50], "actuators": [1, 6]},
    "iso9283_stabilisation": {"cycles": 1, "lead_s": 0.2, "hold_s": 0.4},
    "iterative_correction": {"iterations": 1},
    "iso9283_path": {
        "shape": "line",
        "cycles": 2,
        "velocities_pct": [100],
        "final_hold_s": 0.1,
        "chord_error_mm": 0.05,
    },
    "iso9283_positioning_time": {"steps_mm": [-2, 4], "cycles": 1, "rest_s": 0.1, "hold_s": 0.4},
    "iso9283_cornering": {
        "cycles": 2,
        "velocities_pct": [100],
        "final_hold_s": 0.1,
        "chord_error_mm": 0.05,
    },  # more adapt to the readings (tests/test_kinematic_compensation.py)
}


def test_every_protocol_has_a_quick_end_to_end_case():
    assert set(QUICK_PARAMETERS) == set(PROTOCOLS)


@pytest.mark.parametrize("name", sorted(QUICK_PARAMETERS))
def test_each_protocol_completes_on_the_simulator(tmp_path, name, capsys):
    protocol = PROTOCOLS[name](settle_s=0.1, **QUICK_PARAMETERS[name])
    expected = sum(1 for step in iterate(protocol, final=False) if step_stores_sample(step))
    with Store(tmp_path / "b.db") as store:
        rig = simulated_rig_in(
            store, protocol.robot, seed=2, speed_factor=20000, fixture=getattr(protocol, "fixture", "assembled")
        )
        try:
            result = Runner(rig, store).run(protocol)
        finally:
            rig.close()
        assert (result.exit_status, result.samples) == ("completed", expected)
        if name == "mouse_calibration":  # fitted and stored as a new calibration version
            fitted = store.calibration("mouse")
            assert fitted.source_run_id == result.run_id
            assert fitted.params["mm_per_count"] == pytest.approx(25.4 / 800, rel=0.05)
        if name == "payload_ladder":  # the true leg lengths (SIMLEGS): the seed's drawn actuator errors show
            legs = tidy_table(store, result.run_id, kind="leg_length")
            assert sorted(set(legs["leg"])) == [1, 2, 3, 4, 5, 6]
            model = ErrorModel.draw(PKM5_ERRORS, 6, 2, np.asarray(pkm5.DEFAULT_GEOMETRY.leg_length_offset_mm))
            leg = legs["leg"].to_numpy() - 1
            systematic = (
                model.offset[leg]
                + model.scale[leg] * (legs["cmd_length_mm"] - model.joint_zero[leg])
                - model.sag_per_kg[leg] * legs["load_kg"]
            )
            # what is left: half the backlash (<= 0.075), joint noise 0.05 and calliper 0.02 (1 sigma)
            assert (legs["error_mm"] - systematic).abs().max() < 0.35
            assert legs["error_mm"].abs().max() > 0.2  # not calliper scatter alone (that is 0.02)
        if name == "lasergrid_hits":  # the simulator's laser grid is attached: sensors light up
            hits = tidy_table(store, result.run_id, kind="grid_hit")
            assert hits["hit_any"].sum() > 0 and (hits["hit_expected"] <= hits["hit_any"]).all()
        if name == "dissertation_pose":  # beta read by calliper, error of the order of the documents' 0.2-1.8 deg
            tilts = tidy_table(store, result.run_id, kind="tilt")
            assert len(tilts) == 30 and (tilts["b_deg"] - tilts["cmd_b_deg"]).abs().max() < 5
            # reportable: the deviations table knows the explicit poses and the (absent) load, no unknown row
            from bench.reports import collect

            deviations = {(d.clause, d.topic): d.status for d in collect(store, result.run_id).deviations}
            assert "unknown" not in deviations.values(), deviations
            assert deviations[("6.8", "poses")] == deviations[("6.6", "load")] == "deviates"
            # orientation AP_b/RP_b against the simulator's truth: the true beta at each stop (stored with the
            # position sample of the same visit); the simulated calliper adds 0.1 deg of scatter and 0.01 rounding
            report = collect(store, result.run_id)
            assert deviations[("7.2.1, 7.2.2", "orientation")] == "deviates"
            truth = {(s.pose, s.cycle): s.raw["true_pose"][4] for s in store.samples(result.run_id, kind="pose")}
            assert len(report.orientation) == 15 and len(report.tilt_table) == 30
            for pose in report.orientation:
                (beta,) = pose.figures
                true = np.array([truth[(pose.pose, c)] for c in (1, 2)])
                assert beta.ap_deg == pytest.approx(true.mean() - beta.commanded_deg, abs=0.35)
                assert beta.rp_deg == pytest.approx(3 * true.std(ddof=1), abs=3 * 0.35)
            true_ap = [
                np.mean([truth[(p.pose, c)] for c in (1, 2)]) - p.figures[0].commanded_deg for p in report.orientation
            ]
            assert max(map(abs, true_ap)) > 0.5  # a real robot error the readings show, not calliper noise alone
            # the report's tables and its recomputing command give the same numbers as the CLI on the tilts CSV
            from bench.reports.orientation import orientation_blocks, orientation_headline

            table, _, budget = orientation_blocks(report)
            assert len(table.rows) == 15 and table.rows[0][0] == "1-1" and len(budget.rows) == 6
            (headline,) = orientation_headline(report)
            assert headline.rows[0][0] == "beta (about y)"
            report.tilt_table.to_csv(tmp_path / "tilts.csv", index=False)
            assert main(["analyze", "orientation", str(tmp_path / "tilts.csv"), "--json"]) == 0
            printed = json.loads(capsys.readouterr().out)["poses"]
            for pose in report.orientation:
                assert printed[pose.label]["AP_b_deg"] == pytest.approx(pose.figures[0].ap_deg)
                assert printed[pose.label]["U_AP_b_deg"] == pytest.approx(pose.figures[0].u_ap_deg)


def test_a_stored_design_key_is_left_out_on_resume_but_refused_in_a_protocol_file():
    from bench.errors import ConfigError
    from bench.protocols import protocol_from_config

    config = PROTOCOLS["dissertation_pose"](variant="alpha", cycles=3).config()
    assert config["loads_kg"] == [0.0] and len(config["poses"]) == 15
    rebuilt = protocol_from_config(config, source="run 1", stored=True)
    assert rebuilt.config() == config
    path = PROTOCOLS["iso9283_cornering"](cube_side_mm=40.0).config()  # the path protocols store their paths
    assert [p["shape"] for p in path["paths"]] == ["rectangle"] and path["rated_path_speed_mm_s"] > 0
    assert protocol_from_config(path, source="run 2", stored=True).config() == path
    with pytest.raises(ConfigError, match="p.toml: unknown key 'loads_kg'"):
        protocol_from_config({"protocol": "dissertation_pose", "loads_kg": [1.0]}, source="p.toml")


def _campaign(tmp_path, *, ideal: bool, seed: int, cycles: int) -> pd.DataFrame:
    with Store(tmp_path / f"{ideal}.db") as store:
        rig = simulated_rig("pkm5", seed=seed, speed_factor=20000, ideal=ideal)
        try:
            result = Runner(rig, store).run(PoseAccuracy(cycles=cycles, velocities_pct=[100], settle_s=0.1))
        finally:
            rig.close()
        return analyze_run(store, result.run_id)


def test_ideal_robot_shows_only_the_instrument_floor(tmp_path):
    results = _campaign(tmp_path, ideal=True, seed=0, cycles=5)
    # ideal robot: every error left is the mice' quantisation (0.032 mm/count) and 0.3-count noise
    assert results["AP_mm"].max() < 0.05 and results["RP_mm"].max() < 0.1
    # the ideal robot still attains the step-quantised pose: 0.00625 / 0.003125 mm per step (000 Eq. 8.1)
    assert results["true_AP_mm"].max() < 0.02 and results["true_RP_mm"].max() < 1e-9


def test_ap_rp_match_the_injected_errors(tmp_path):
    results = _campaign(tmp_path, ideal=False, seed=3, cycles=30)
    assert np.abs(results["AP_mm"] - results["true_AP_mm"]).max() < 0.05
    assert np.abs(results["RP_mm"] - results["true_RP_mm"]).max() < 0.1
    # RP of isotropic Gaussian play sigma per axis, n = 30, by an independent Monte Carlo of RP = l_mean + 3 S_l
    sigma = PKM5_ERRORS.pose_play_sigma[0]
    clouds = np.random.default_rng(0).normal(0.0, sigma, (4000, 30, 3))
    distances = np.linalg.norm(clouds - clouds.mean(axis=1, keepdims=True), axis=2)
    rp = distances.mean(axis=1) + 3 * distances.std(axis=1, ddof=1)
    tolerance = 4 * rp.std() / np.sqrt(len(results)) + 0.1  # + the joint-space noise and backlash, not modelled
    assert abs(results["RP_mm"].mean() - rp.mean()) < tolerance


def test_kill_9_mid_run_then_resume_gives_exactly_the_expected_samples(capsys, tmp_path):
    protocol_file = tmp_path / "pose.toml"
    protocol_file.write_text('protocol = "iso9283_pose"\ncycles = 6\nvelocities_pct = [100, 50]\nsettle_s = 0.2\n')
    db = tmp_path / "b.db"
    writer = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "bench.cli",
            "run",
            str(protocol_file),
            "--sim",
            "--store",
            str(db),
            "--no-progress",
            "--speed-factor",
            "3000",
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for_samples(db, writer, 17)
    os.kill(writer.pid, signal.SIGKILL)
    writer.wait(timeout=10)
    with Store(db) as store:
        before = {s.step_index: s.values for s in store.samples(1)}
        assert store.run(1).status == "interrupted" and 17 <= len(before) < 60
    assert main(["resume", "1", "--store", str(db), "--no-progress"]) == 0
    assert _run_id(capsys) == 1
    with Store(db) as store:
        from bench.protocols import protocol_from_config

        protocol = protocol_from_config(store.run(1).config)
        expected = {i for i, step in enumerate(iterate(protocol, final=False)) if step_stores_sample(step)}
        after = {s.step_index: s.values for s in store.samples(1)}
        assert set(after) == expected and len(store.samples(1)) == 60
        assert all(after[i] == values for i, values in before.items())  # stored samples untouched
        assert store.run(1).status == "completed"


@pytest.mark.slow
def test_demo_writes_table_results_and_report(capsys, tmp_path):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--cycles", "3", "--no-progress"]) == 0
    printed = capsys.readouterr().out.split()
    # one report (HTML and PDF from one document): no report.md that could disagree with it
    assert [Path(p).name for p in printed[1:]] == [
        "bench.db",
        "run-1.csv",
        "results.csv",
        "report_run1.html",
        "report_run1.pdf",
    ]
    results = pd.read_csv(out / "results.csv")
    assert len(results) == 15 and set(results["velocity_pct"]) == {100, 50, 10}
    assert not (out / "report.md").exists()


def test_ctrl_c_pauses_at_a_checkpoint_then_stop_ends_the_run(tmp_path):
    protocol_file = tmp_path / "pose.toml"
    protocol_file.write_text('protocol = "iso9283_pose"\ncycles = 20\nvelocities_pct = [100]\nsettle_s = 0.2\n')
    db = tmp_path / "b.db"
    run = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "bench.cli",
            "run",
            str(protocol_file),
            "--sim",
            "--store",
            str(db),
            "--no-progress",
            "--speed-factor",
            "3000",
        ],
        cwd=ROOT,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for_samples(db, run, 7)
    run.send_signal(signal.SIGINT)
    out, err = run.communicate("s\n", timeout=30)
    assert run.returncode == 1 and out.strip() == "1"
    assert (
        "pausing at the next checkpoint" in err and "paused: [r]esume, [s]top, [a]bort, [h]alt (Ctrl-C aborts)?" in err
    )
    with Store(db) as store:
        record = store.run(1)
        assert record.status == "aborted" and record.reason.startswith("stopped by the operator at checkpoint")
        assert record.n_samples % 5 == 0 and 10 <= record.n_samples < 100  # whole cycles only


def test_a_slow_operator_does_not_lose_the_run(tmp_path):
    """Prompts wait for the person; no link deadline runs meanwhile (the controller's reply timeout is 1 s)."""
    from bench.protocols.dissertation import PayloadLadder
    from bench.simulators.rig import SimulatedCalliper

    with Store(tmp_path / "b.db") as store:
        rig = simulated_rig("pkm5", seed=1, speed_factor=20000)
        calliper = SimulatedCalliper(rig.robot.controller, seed=1)

        def slow(prompt):
            time.sleep(1.5 if prompt.conditions.get("leg") == 1 else 0.0)
            return calliper(prompt)

        rig.operator.answer = slow
        try:
            result = Runner(rig, store).run(PayloadLadder(loads_kg=[2.0], settle_s=0.1))
        finally:
            rig.close()
        assert (result.exit_status, result.samples) == ("completed", 6)


def test_hardware_path_on_a_pty_with_mice_that_see_nothing_is_refused_at_the_check_pose(capsys, tmp_path):
    """``--port`` with the real driver on the simulator's pty and two mice on FIFOs that nothing moves (lifted mice,
    a dead feed): the registration's check pose (bench.rigs.registration) reads home where home + (10, 6, 14) mm
    was commanded, so the run is refused in one line before anything is stored."""
    from bench.simulators.rig import start_simulator

    process, pty = start_simulator("pkm5", seed=0, speed_factor=20000)
    fifos, writers = [], []
    try:
        for plane in ("xy", "xz"):
            fifos.append(str(tmp_path / f"{plane}.fifo"))
            os.mkfifo(fifos[-1])
            writers.append(os.open(fifos[-1], os.O_RDWR))
        db = str(tmp_path / "b.db")
        quick = tmp_path / "quick.toml"
        quick.write_text(QUICK.read_text().replace("settle_s = 0.5", "settle_s = 0"))
        assert (
            main(
                [
                    "run",
                    str(quick),
                    "--store",
                    db,
                    "--port",
                    pty,
                    "--mouse-xy",
                    fifos[0],
                    "--mouse-xz",
                    fifos[1],
                    "--no-progress",
                ]
            )
            == 1
        )
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.startswith(
            "bench: error: registration check: at the check pose home + (10.0, 6.0, 14.0) mm the "
            "instruments read (-10.00, -6.00, -14.00) mm = 18.22 mm from the commanded pose, "
            "tolerance 6.74 mm"
        ), err
        with Store(db) as store:
            assert store.runs() == []
    finally:
        for writer in writers:
            os.close(writer)
        process.terminate()
        process.wait(5)


def test_missing_port_is_one_line(capsys, tmp_path):
    assert (
        main(
            [
                "run",
                str(QUICK),
                "--store",
                str(tmp_path / "b.db"),
                "--port",
                "/dev/ttyNONE",
                "--mouse-xy",
                "a",
                "--mouse-xz",
                "b",
            ]
        )
        == 1
    )
    err = capsys.readouterr().err.strip()
    assert (
        err.startswith("bench: error: --port: controller.port = '/dev/ttyNONE': cannot open it")
        and len(err.splitlines()) == 1
    )
