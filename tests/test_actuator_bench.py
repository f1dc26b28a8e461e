"""The actuator bench (000 §8.4): single-axis moves only on the bench and inside the stroke, the simulated depth
gauge, and the ``actuator_accuracy`` protocol analysed with the dissertation's formulas against the simulator's
injected joint errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import serial

from bench.errors import ConfigError, UnreachableTarget
from bench.protocols import PROTOCOLS, Runner, load_protocol, summarize
from bench.protocols.actuator import ActuatorAccuracy, actuator_results
from bench.robots.pkm5 import Pkm5Controller
from bench.robots.pkm5_kinematics import steps_for_stroke
from bench.simulators.pkm5_plant import build_actuator_bench
from bench.simulators.rig import simulated_rig, start_simulator
from bench.steps import ActuatorMove
from bench.store import Store, tidy_table

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "actuator_accuracy.toml"


def _controller(fixture: str, *options: str):
    process, path = start_simulator("pkm5", seed=1, speed_factor=1000, options=options)
    controller = Pkm5Controller(serial.serial_for_url(path, baudrate=115200, timeout=0.05), fixture=fixture)
    controller.identify()
    controller.enable()
    return process, controller


def _close(process, controller) -> None:
    controller.shutdown()
    process.terminate()
    process.wait(5)


def test_stroke_to_steps_uses_each_actuators_resolution():
    # 0.00625 mm/step on legs 1-4 and 0.003125 mm/step on legs 5-6 (000 Eq. 8.1, firmware MAX_STEPS 10560 / 21120)
    assert steps_for_stroke(1, 66.0) == 10560 and steps_for_stroke(6, 66.0) == 21120
    assert steps_for_stroke(3, 10.0) == 1600 and steps_for_stroke(5, 0.0) == 0
    for axis, stroke in ((1, 66.01), (2, -0.01), (7, 10.0), (0, 10.0), (1, float("nan")), (1.0, 10.0)):
        with pytest.raises(UnreachableTarget, match="expected"):
            steps_for_stroke(axis, stroke)


def test_single_axis_move_is_refused_on_the_assembled_robot_and_outside_the_stroke():
    process, robot = _controller("assembled")
    try:
        before = robot.position().steps
        with pytest.raises(UnreachableTarget, match="refused on the assembled robot, one leg cannot move alone"):
            robot.move_actuator(1, 10.0)
        assert robot.position().steps == before == (800, 800, 800, 800, 1600, 1600)
    finally:
        _close(process, robot)
    process, bench = _controller("actuator-bench", "--fixture", "actuator-bench")
    try:
        for axis, stroke in ((1, 66.5), (6, -1.0), (7, 10.0)):
            with pytest.raises(UnreachableTarget, match="expected"):
                bench.move_actuator(axis, stroke)
        assert bench.position().steps == (800, 800, 800, 800, 1600, 1600)  # nothing was sent
        assert bench.move_actuator(5, 30.0) == (800, 800, 800, 800, 9600, 1600)  # the other axes hold
        assert bench.settings()["fixture"] == "actuator-bench"
    finally:
        _close(process, bench)
    with pytest.raises(ConfigError, match="fixture = 'bench', expected one of"):
        Pkm5Controller(serial.serial_for_url("loop://"), fixture="bench")


def test_protocol_parameters_and_plan():
    protocol = load_protocol(EXAMPLE)
    assert protocol.config()["fixture"] == "actuator-bench"
    summary = summarize(protocol)
    assert summary.ok and summary.counts["prompts"] == 6 * 5 * 11  # a zeroing and 10 readings per travel
    assert summary.counts["actuatormoves"] == 6 * 5 * 21 + 6
    with pytest.raises(ConfigError, match=r"start_mm \+ max\(distances_mm\) = 70 mm, expected <= 66 mm"):
        ActuatorAccuracy(start_mm=20.0)
    with pytest.raises(ConfigError, match="actuators = \\[1.5\\], expected distinct whole numbers"):
        ActuatorAccuracy(actuators=[1.5])
    with pytest.raises(ConfigError, match="fixture = 'assembled', expected one of 'actuator-bench'"):
        ActuatorAccuracy(fixture="assembled")

    class Overreach(ActuatorAccuracy):  # a plan that would leave the stroke is refused by the dry run
        def steps(self):
            yield ActuatorMove(2, 70.0, 100.0, "far")

    refused = summarize(Overreach())
    assert not refused.ok and refused.problems()[0].startswith("target far: actuator 2: stroke_mm = 70.0")


def test_actuator_protocol_fails_on_an_assembled_rig_before_any_reading(tmp_path):
    protocol = PROTOCOLS["actuator_accuracy"](repeats=2, distances_mm=[10], actuators=[1], settle_s=0)
    with Store(tmp_path / "b.db") as store:
        rig = simulated_rig("pkm5", seed=1, speed_factor=20000)
        try:
            result = Runner(rig, store).run(protocol)
        finally:
            rig.close()
        assert result.exit_status == "failed" and result.samples == 0
        assert "one leg cannot move alone" in store.run(result.run_id).reason


def _run(tmp_path, *, ideal: bool, seed: int, **parameters):
    protocol = PROTOCOLS["actuator_accuracy"](settle_s=0.0, **parameters)
    with Store(tmp_path / f"b{seed}{ideal}.db") as store:
        rig = simulated_rig("pkm5", seed=seed, speed_factor=50000, ideal=ideal, fixture="actuator-bench")
        try:
            result = Runner(rig, store).run(protocol)
        finally:
            rig.close()
        assert result.exit_status == "completed"
        return actuator_results(store, result.run_id), tidy_table(store, result.run_id, kind="actuator_travel")


def test_ideal_actuators_read_the_commanded_travel(tmp_path):
    results, table = _run(tmp_path, ideal=True, seed=1, actuators=[2, 5], distances_mm=[10, 50], repeats=3)
    assert len(table) == 12 and sorted(set(table["actuator"])) == [2, 5]
    assert (table["travel_mm"] - table["cmd_travel_mm"]).abs().max() <= 0.05  # gauge noise 0.01 mm, 0.01 steps
    for axis in (2, 5):
        assert max(abs(b) for b in results[axis].mean_deviation_mm) < 0.02
        assert results[axis].control_resolution_mm == {2: 0.00625, 5: 0.003125}[axis]


def test_simulated_actuators_show_the_injected_scale_and_noise(tmp_path):
    seed = 3
    results, _ = _run(tmp_path, ideal=False, seed=seed, actuators=[1, 2], distances_mm=[10, 20, 30, 40, 50], repeats=10)
    model = build_actuator_bench(seed).model
    distances = np.array([10, 20, 30, 40, 50.0])
    for axis in (1, 2):
        result = results[axis]
        # within a block the gauge zero is fixed: scatter = joint noise (0.05) and gauge noise (0.01), sigma ~0.051
        assert 0.10 < result.repeatability_mm < 0.21
        # travel error grows with the commanded travel at the drawn scale error (a gauge zero per block adds
        # 0.05 mm of bias noise, so the slope is known to about +-0.0025)
        slope = np.polyfit(distances[1:], np.array(result.mean_deviation_mm)[1:], 1)[0]
        assert slope == pytest.approx(model.scale[axis - 1], abs=0.0075)
    assert model.scale[0] > 0.005 and model.scale[1] < -0.007  # the seed's two actuators err in opposite directions
