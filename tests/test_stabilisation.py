"""Stabilisation time and overshoot (ISO 9283 7.4, 7.5) from a streamed arrival: the simulated structural mode,
its wire commands, the mice's streamed capture, the protocol, the series export and ``bench analyze``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from reports_runs import simulated_run
from scipy import signal

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology import pose_stabilisation, position_stabilisation
from bench.protocols.iso9283 import StabilisationOvershoot
from bench.robots.pkm5 import ControllerError
from bench.simulators.client import SimulatorClient
from bench.simulators.dynamics import StructuralMode, trace_times
from bench.simulators.rig import simulated_rig
from bench.steps import Capture
from bench.store import Store, series_table
from motion import pkm5

#: One count of the simulated 800 cpi mice, mm.
COUNT_MM = 25.4 / 800


def _lti(mode: StructuralMode) -> signal.lti:
    omega = 2 * np.pi * mode.frequency_hz
    return signal.lti([omega**2], [1, 2 * mode.damping_ratio * omega, omega**2])


@pytest.mark.parametrize("duration_s", [0.4, 3.0])
def test_closed_form_arrival_equals_scipy_lsim_of_the_ramp(duration_s):
    mode = StructuralMode(2.5, 0.05)
    t = np.arange(0.0, duration_s + 4.0, 1e-3)
    command = np.clip(t / duration_s, 0.0, 1.0)
    _, simulated, _ = signal.lsim(_lti(mode), command, t)
    start, end = np.array([1.0, -2.0]), np.array([3.0, 5.0])
    closed = mode.arrival(t - duration_s, start, end, duration_s)
    np.testing.assert_allclose(closed, start + np.outer(simulated, end - start), atol=1e-9)


def test_a_jump_rings_like_the_step_response_and_the_ramp_overshoot_is_near_v_over_omega():
    mode = StructuralMode(2.0, 0.1)
    t = np.linspace(0.0, 3.0, 3001)
    _, step = signal.step(_lti(mode), T=t)
    np.testing.assert_allclose(mode.arrival(t, [0.0], [1.0], 0.0)[:, 0], step, atol=1e-9)
    light = StructuralMode(2.0, 0.02)  # lightly damped: a stop at 2 mm/s rings with about v / omega
    ramp = light.arrival(t, [0.0], [100.0], 50.0)[:, 0]  # long enough for the start's ringing to die out
    assert ramp.max() - 100.0 == pytest.approx(2.0 / (2 * np.pi * 2.0), rel=0.06)


def test_mode_parameters_are_checked():
    with pytest.raises(ValueError, match="damping_ratio = 1.0, expected a number in"):
        StructuralMode(2.0, 1.0)
    with pytest.raises(ValueError, match="frequency_hz = 0"):
        StructuralMode(0, 0.1)


def test_trace_over_the_wire_is_the_mode_driven_from_the_last_true_pose_to_the_new_one():
    rig = simulated_rig("pkm5", seed=5, speed_factor=1000, options=("--mode-hz", "1.5", "--damping", "0.04"))
    controller = rig.robot.controller
    try:
        before, steps_before = SimulatorClient(controller).true_pose(), np.array(controller.position().steps)
        controller.move_to_pose((110.0, 0.0, 320.0, 0.0, 0.0), speed_steps_s=200)
        after, steps_after = SimulatorClient(controller).true_pose(), np.array(controller.position().steps)
        times, poses = SimulatorClient(controller).trace(200, 0.5, 1.0)
        duration_s = np.abs(steps_after - steps_before).max() / 200
        expected = StructuralMode(1.5, 0.04).arrival(trace_times(200, 0.5, 1.0), before, after, duration_s)
        assert times[0] == -0.5 and times[-1] == 1.0 and len(times) == 301
        np.testing.assert_allclose(poses, expected, atol=1.5e-4)  # 4 decimals on the wire, for both ends too
        with pytest.raises(ControllerError, match="ARGUMENT"):
            controller._exchange("SIMTRACE", (200, 500, 1000, 301))
    finally:
        rig.close()


def test_true_leg_lengths_are_the_commanded_ones_on_an_ideal_robot_and_perturbed_otherwise():
    lengths = {}
    for ideal in (True, False):
        rig = simulated_rig("pkm5", seed=3, speed_factor=1000, ideal=ideal)
        try:
            rig.robot.controller.move_to_pose((110.0, 0.0, 320.0, 0.0, 0.0))
            commanded = pkm5.steps_to_lengths(np.array(rig.robot.controller.position().steps)[None, :])[0]
            lengths[ideal] = SimulatorClient(rig.robot.controller).true_lengths() - commanded
        finally:
            rig.close()
    np.testing.assert_allclose(lengths[True], 0.0, atol=6e-5)
    assert 0.05 < np.abs(lengths[False]).max() < 1.5


def test_the_streamed_arrival_matches_the_simulators_truth():
    """A ringing arrival (1 Hz mode) read by the mice gives the truth's stabilisation time and overshoot."""
    rig = simulated_rig("pkm5", seed=7, speed_factor=1000, options=("--mode-hz", "1.0", "--damping", "0.05"))
    try:
        rig.robot.move_to((100.0, -10.0, 310.0), velocity_pct=100)
        rig.robot.move_to((120.0, 10.0, 330.0), velocity_pct=100)
        measured = rig.instrument.measure(Capture("P", 1, kind="arrival", conditions={"lead_s": 1.0, "hold_s": 6.0}))
        t_true, true_poses = SimulatorClient(rig.robot.controller).trace(250, 1.0, 6.0)
    finally:
        rig.close()
    series = measured.raw["series"]
    t = np.array(series["t_s"])
    positions = np.column_stack([series[k] for k in ("x_mm", "y_mm", "z_mm")])
    assert t[0] == -1.0 and t[-1] == 6.0 and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(positions[-1], true_poses[-1, :3], atol=2 * COUNT_MM)
    assert measured.values["x_mm"] == positions[-1, 0]
    truth = position_stabilisation(t_true, true_poses[:, :3], band_mm=0.1, hysteresis_mm=COUNT_MM)
    seen = position_stabilisation(t, positions, band_mm=0.1, hysteresis_mm=COUNT_MM)
    assert truth.overshoot_mm > 0.15 and truth.stabilisation_time_s > 0.5  # it does ring past the band
    assert seen.overshoot_mm == pytest.approx(truth.overshoot_mm, abs=2 * COUNT_MM)
    # a 1 Hz ring leaves the band only near its peaks: t_2 can move by half a period for a count of error
    assert seen.stabilisation_time_s == pytest.approx(truth.stabilisation_time_s, abs=0.5)
    # the raw reports and the counts at the window start give the stored series back
    for plane, axis in (("xy", "y_mm"), ("xz", "z_mm")):
        reports = measured.raw["reports"][plane]
        counts = measured.raw["counts_at_start"][plane][1] + np.sum(reports["dy_counts"])
        origin = {"y_mm": 1, "z_mm": 2}[axis]
        registration = rig.instrument.origin[origin]
        assert registration + counts * COUNT_MM == pytest.approx(series[axis][-1], abs=1e-4)


def test_a_stabilisation_run_exports_series_that_bench_analyze_reads(tmp_path, capsys):
    protocol = StabilisationOvershoot(
        cycles=2, lead_s=0.5, hold_s=2.0, poses={"A": [100.0, -10.0, 310.0], "B": [120.0, 10.0, 330.0]}
    )
    with Store(tmp_path / "b.db") as store:
        run_id = simulated_run(store, protocol, "pkm5", seed=2, speed_factor=1000)
        table = series_table(store, run_id)
        samples = store.samples(run_id, kind="arrival")
    assert len(samples) == 4
    assert list(table.columns[:2]) == ["pose", "cycle"] and "t_s" in table.columns
    assert len(table) == sum(len(s.raw["series"]["t_s"]) for s in samples)
    direct = pose_stabilisation(
        [
            (np.array(s.raw["series"]["t_s"]), np.column_stack([s.raw["series"][k] for k in ("x_mm", "y_mm", "z_mm")]))
            for s in samples
            if s.pose == "B"
        ],
        band_mm=0.1,
        hysteresis_mm=COUNT_MM,
    )
    db = str(tmp_path / "b.db")
    out = tmp_path / "series.csv"
    assert main(["export", str(run_id), "--series", "--store", db, "--out", str(out)]) == 0
    capsys.readouterr()
    assert (
        main(["analyze", "stabilisation", str(out), "--band-mm", "0.1", "--hysteresis-mm", str(COUNT_MM), "--json"])
        == 0
    )
    analysed = json.loads(capsys.readouterr().out)["bands"]["0.1"]["B"]
    assert analysed["n"] == 2
    assert analysed["mean_time_s"] == pytest.approx(direct.mean_time_s, abs=1e-6)
    assert analysed["max_overshoot_mm"] == pytest.approx(direct.max_overshoot_mm, abs=1e-4)


def test_analyze_stabilisation_names_a_missing_column(tmp_path, capsys):
    table = tmp_path / "poses.csv"
    table.write_text("pose,cycle,x_mm,y_mm,z_mm\nP1,1,0,0,0\n")
    assert main(["analyze", "stabilisation", str(table)]) == 2
    assert "missing column(s) t_s; export the run with --series" in capsys.readouterr().err


def test_analyze_stabilisation_names_a_cell_that_is_not_a_number(tmp_path, capsys):
    table = tmp_path / "series.csv"
    table.write_text("pose,cycle,t_s,x_mm,y_mm,z_mm\nP1,1,0.0,0.1,0,0\nP1,1,0.01,abc,0,0\n")
    assert main(["analyze", "stabilisation", str(table)]) == 2
    err = capsys.readouterr().err
    assert err.strip() == f"bench: error: {table}: row 2, column x_mm: 'abc' is not a finite number"  # one line


def test_band_edge_flicker_is_an_overshoot_of_about_b_unless_hysteresis_covers_it():
    t = np.arange(8) * 0.01
    d = np.array([0.3, 0.2, 0.1, 0.11, 0.09, 0.05, 0.01, 0.0])  # one count of flicker at the band edge
    position = np.column_stack([d, np.zeros_like(d)])
    plain = position_stabilisation(t, position, band_mm=0.1)
    assert (plain.first_entry_s, plain.overshoot_mm) == (0.02, 0.11)
    assert plain.stabilisation_time_s == pytest.approx(0.02)
    tolerant = position_stabilisation(t, position, band_mm=0.1, hysteresis_mm=0.02)
    assert (tolerant.stabilisation_time_s, tolerant.overshoot_mm) == (0.0, 0.0)
    with pytest.raises(ConfigError, match="hysteresis_mm = -1"):
        position_stabilisation(t, position, band_mm=0.1, hysteresis_mm=-1)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 2.0), min_size=3, max_size=40), st.floats(0.05, 1.0), st.floats(0.0, 0.5))
def test_more_hysteresis_never_lengthens_stabilisation_or_raises_overshoot(distances, band, hysteresis):
    d = np.array(distances + [0.0])
    t = np.arange(len(d)) * 0.01
    position = d[:, None]
    plain = position_stabilisation(t, position, band_mm=band)
    tolerant = position_stabilisation(t, position, band_mm=band, hysteresis_mm=hysteresis)
    assert 0.0 <= tolerant.stabilisation_time_s <= plain.stabilisation_time_s
    assert tolerant.overshoot_mm <= plain.overshoot_mm
    assert tolerant.first_entry_s == plain.first_entry_s
    assert plain.overshoot_mm == 0.0 or plain.overshoot_mm > band


def test_analyze_stabilisation_keeps_velocities_apart(tmp_path, capsys):
    rows = ["pose,cycle,velocity_pct,t_s,x_mm,y_mm,z_mm"]
    for velocity, peak in ((100, 0.3), (10, 0.05)):  # the fast arrival overshoots the 0.1 mm band, the slow one not
        for t, d in ((-0.1, 1.0), (0.0, 0.0), (0.1, peak), (0.2, 0.0), (0.3, 0.0)):
            rows.append(f"P1,1,{velocity},{t},{d},0,0")
    table = tmp_path / "two_speeds.csv"
    table.write_text("\n".join(rows) + "\n")
    assert main(["analyze", "stabilisation", str(table), "--band-mm", "0.1", "--json"]) == 0
    per_pose = json.loads(capsys.readouterr().out)["bands"]["0.1"]
    assert per_pose["P1 (velocity_pct=100)"]["overshoot_mm"] == pytest.approx(0.3)
    assert per_pose["P1 (velocity_pct=100)"]["mean_time_s"] == pytest.approx(0.2)
    assert per_pose["P1 (velocity_pct=10)"]["overshoot_mm"] == 0.0


def test_each_load_is_mounted_on_request_and_stabilisation_runs_under_it():
    from bench.protocols.plan import iterate
    from bench.steps import Prompt

    protocol = StabilisationOvershoot(cycles=1, loads_kg=[0.0, 5.0], poses={"A": [100.0, -10.0, 310.0]})
    steps = list(iterate(protocol, final=False))
    prompts = [s for s in steps if isinstance(s, Prompt)]
    captures = [s for s in steps if isinstance(s, Capture)]
    assert [p.conditions["load_kg"] for p in prompts] == [5.0]
    assert [(c.kind, c.conditions["load_kg"]) for c in captures] == [("arrival", 0.0), ("arrival", 5.0)]
    assert steps.index(prompts[0]) < steps.index(captures[1])


def _fifo_mice(tmp_path):
    import os

    from bench.sensors.calibration import CountsCalibration
    from bench.sensors.mouse import EvdevMouse

    calibration = CountsCalibration.from_cpi(800, calibration_id="t-800", date="2026-01-01")
    writers, mice = {}, {}
    for plane in ("xy", "xz"):
        path = tmp_path / f"{plane}.fifo"
        os.mkfifo(path)
        writers[plane] = os.open(path, os.O_RDWR)
        mice[plane] = EvdevMouse(str(path), calibration, label=f"mouse_{plane}")
    return mice, writers, calibration


def test_a_following_instrument_drains_the_mice_during_a_long_move(tmp_path):
    """Reports far beyond a kernel buffer (and a pipe's 64 KiB) are read as they come, none lost."""
    import os
    import threading
    import time

    from bench.rigs.mice import MiceInstrument
    from bench.sensors.input_event import encode_frames

    mice, writers, calibration = _fifo_mice(tmp_path)
    instrument = MiceInstrument(mice, (10.0, 20.0, 30.0), calibration, follow=True)
    try:
        n = 6000  # 432 kB of input_event records: the writer blocks unless someone reads meanwhile
        start = time.monotonic() - 1.0
        data = encode_frames(start + np.arange(n) * 1e-4, np.ones(n, np.int64), np.zeros(n, np.int64))
        writer = threading.Thread(target=os.write, args=(writers["xy"], data), daemon=True)
        writer.start()
        writer.join(10)
        assert not writer.is_alive()  # drained while nobody asked for a capture
        static = instrument.measure(Capture("P", 1))
        assert static.values["x_mm"] == pytest.approx(10.0 + n * COUNT_MM)
        # an arrival keeps only the window: counts before it are the series' start
        recent = time.monotonic()
        os.write(
            writers["xy"],
            encode_frames(recent - 0.8 + np.arange(100) * 1e-3 * 7, np.ones(100, np.int64), np.zeros(100, np.int64)),
        )
        arrival = instrument.measure(Capture("P", 2, kind="arrival", conditions={"lead_s": 0.5, "hold_s": 0.1}))
    finally:
        instrument.close()
        for fd in writers.values():
            os.close(fd)
    series = arrival.raw["series"]
    assert arrival.values["x_mm"] == pytest.approx(10.0 + (n + 100) * COUNT_MM)
    assert len(arrival.raw["reports"]["xy"]["t_s"]) < 100  # reports before the window are not kept
    assert series["x_mm"][0] == pytest.approx(
        10.0 + (n + 100 - len(arrival.raw["reports"]["xy"]["t_s"])) * COUNT_MM, abs=1e-4
    )
