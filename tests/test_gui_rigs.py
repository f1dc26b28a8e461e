"""The desktop app builds its rigs with the same function as ``bench run`` (:func:`bench.launch.open_rig`): the
protocol's fixture and capabilities reach the builder, so the actuator bench runs from the window too."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest

pytest.importorskip("PySide6")

from gui_support import RUN_TIMEOUT_S, application, wait_for

from bench.protocols import load_protocol
from bench.store import Store


def _run(tmp_path, protocol_file, spec):
    from bench.gui.worker import CampaignWorker

    application()
    worker = CampaignWorker(str(tmp_path / "bench.db"), [load_protocol(protocol_file)], spec)
    results, failures = [], []
    worker.run_finished.connect(results.append)
    worker.failed.connect(failures.append)
    worker.start()
    wait_for(lambda: worker.isFinished() and (results or failures), RUN_TIMEOUT_S, "the worker to finish")
    return results, failures


def test_the_window_runs_the_actuator_bench_on_the_simulator(tmp_path):
    from bench.gui.worker import RigSpec

    protocol = tmp_path / "actuators.toml"
    protocol.write_text(
        'protocol = "actuator_accuracy"\nactuators = [3]\ndistances_mm = [10]\nrepeats = 2\nsettle_s = 0\n'
    )
    results, failures = _run(tmp_path, protocol, RigSpec(speed_factor=20000))
    assert failures == [] and results[0].exit_status == "completed", (failures, results)
    with Store(tmp_path / "bench.db") as store:
        (run,) = store.runs()
        travels = [s.values["travel_mm"] for s in store.samples(run.id) if s.kind == "actuator_travel"]
    assert run.settings["robot"]["fixture"] == "actuator-bench" and len(travels) == 2
    assert all(abs(t - 10) < 0.5 for t in travels)


def test_the_window_refuses_a_station_that_lacks_what_the_protocol_needs(tmp_path):
    from pathlib import Path

    from bench.gui.worker import RigSpec

    root = Path(__file__).resolve().parents[1]
    spec = RigSpec(station=str(root / "examples" / "stations" / "pkm5_camera.toml"), simulate=True)
    results, failures = _run(tmp_path, root / "examples" / "mouse_calibration.toml", spec)
    assert results == [] and len(failures) == 1
    assert failures[0].endswith("protocol 'mouse_calibration' needs mouse_counts (add [mice])")
    assert "--" not in failures[0]  # no command-line flag names in the window


@pytest.mark.parametrize(
    "where, simulated",
    [
        ({"port": "/dev/ttyUSB0"}, False),
        ({"station": "examples/stations/pkm5_camera.toml"}, False),
        ({"station": "examples/stations/pkm5_camera.toml", "simulate": True}, True),
        ({}, True),
    ],
)
def test_the_window_sends_a_seed_and_a_speed_factor_for_simulators_only(where, simulated):
    """The robot panel always holds a seed and a speed factor; real hardware has neither, and open_rig refuses them
    there (a run would otherwise believe something untrue about itself)."""
    from bench.gui.worker import RigSpec

    request = RigSpec(seed=3, speed_factor=500.0, **where).request()
    assert (request.seed, request.speed_factor) == ((3, 500.0) if simulated else (None, None))
