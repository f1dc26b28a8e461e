"""The actuator bench through the command line, on the simulator: ``bench run --dry-run`` lists the strokes, a short
run, ``bench export --kind actuator_travel`` feeds ``bench analyze actuator`` unchanged, and ``bench report`` prints
the same numbers. Checked against numpy on the exported CSV and the dissertation's CR per actuator (000 Eq. 8.1);
``bench.protocols.actuator.actuator_results`` (the protocol's reduction of the stored samples, full precision) must
agree with the CLI on the 6-decimal export."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from reports_runs import rounded_by_u

from bench.cli import main
from bench.protocols import summarize
from bench.protocols.actuator import ActuatorAccuracy, actuator_results
from bench.steps import ActuatorMove
from bench.store import Store

PROTOCOL = """protocol = "actuator_accuracy"
fixture = "actuator-bench"
actuators = [2, 5]
distances_mm = [10, 30, 50]
repeats = 3
start_mm = "5 mm"
settle_s = "0 s"
"""


def _out(capsys, *argv, code: int = 0) -> str:
    capsys.readouterr()
    assert main(list(argv)) == code
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """One short actuator_accuracy run on the simulated actuator bench (seed 3), through ``bench run``."""
    folder = tmp_path_factory.mktemp("actuator_cli")
    toml = folder / "actuators.toml"
    toml.write_text(PROTOCOL)
    db = folder / "bench.db"
    assert (
        main(["run", str(toml), "--sim", "--store", str(db), "--no-progress", "--seed", "3", "--speed-factor", "50000"])
        == 0
    )
    with Store(db) as store:
        (record,) = store.runs()
        expected = actuator_results(store, record.id)
    return folder, toml, db, record.id, expected


def test_dry_run_lists_the_strokes_of_every_actuator_with_their_time(simulated, capsys):
    _, toml, _, _, _ = simulated
    out = _out(capsys, "run", str(toml), "--dry-run")
    assert "0 distinct targets" not in out
    # per actuator and travel d: one move to the 5 mm start, then 3 x (start, start + d), and the way back to the
    # start afterwards (the next block's first move or the clean-up's home stroke): 7 moves and 6 d of travel;
    # 3 travels + the clean-up = 22 moves and 6 x 90 = 540 mm, at 200 steps/s x 0.00625 mm = 1.25 mm/s: 432 s
    assert "actuator bench: 2 actuator(s), 44 single-axis moves (0:21:36)" in out
    assert re.search(r"actuator 2  strokes 5, 15, 35, 55 mm  window 0-66 mm  22 moves  0:07:12  ok", out)
    # actuator 5 has half the step (0.003125 mm) at the same step rate: twice the time
    assert re.search(r"actuator 5  strokes 5, 15, 35, 55 mm  window 0-66 mm  22 moves  0:14:24  ok", out)
    assert out.startswith("protocol actuator_accuracy on pkm5: 44 actuatormoves, 24 prompts")


def test_dry_run_names_a_stroke_outside_the_window():
    class Overreach(ActuatorAccuracy):
        def steps(self):
            yield ActuatorMove(3, 10.0, 100.0, "A3/near")
            yield ActuatorMove(3, 70.0, 100.0, "A3/far")

    summary = summarize(Overreach(actuators=[3]))
    (axis,) = summary.strokes
    assert (axis.axis, axis.strokes_mm, axis.moves, axis.window_mm) == (3, (5.0, 10.0, 70.0), 3, (0.0, 66.0))
    assert not summary.ok and summary.problems() == [
        "target A3/far: actuator 3: stroke_mm = 70.0, expected a number in [0, 66] mm"
    ]
    line = next(line for line in summary.lines() if line.startswith("  actuator 3"))
    assert line.endswith("REFUSED: target A3/far: actuator 3: stroke_mm = 70.0, expected a number in [0, 66] mm")
    # the refused move is not timed: 5 -> 10 mm (800 steps at 200/s) and back to the 5 mm home stroke
    assert axis.move_s == pytest.approx(2 * 800 / 200)


def test_export_then_analyze_actuator_reproduces_the_protocols_own_figures(simulated, capsys, tmp_path):
    _, _, db, run_id, expected = simulated
    csv = tmp_path / "a.csv"
    assert _out(
        capsys, "export", str(run_id), "--store", str(db), "--kind", "actuator_travel", "--out", str(csv)
    ).strip() == str(csv)
    table = pd.read_csv(csv)
    assert {"actuator", "cmd_travel_mm", "travel_mm", "cycle"} <= set(table.columns) and len(table) == 18
    result = json.loads(_out(capsys, "analyze", "actuator", str(csv), "--robot", "pkm5", "--json"))["actuators"]
    assert sorted(result) == ["2", "5"]
    for axis, groover in expected.items():
        ours = result[str(axis)]
        assert ours["repeatability_mm"] == pytest.approx(groover.repeatability_mm, abs=1e-9)
        assert ours["accuracy_mm"] == pytest.approx(groover.accuracy_mm, abs=1e-9)
        assert ours["mean_deviation_mm"] == pytest.approx(groover.mean_deviation_mm, abs=1e-9)
        assert ours["control_resolution_mm"] == groover.control_resolution_mm
        # numpy on the CSV: sigma per travel, and ISO 230-2 A↑ = max(x̄ + 2s) - min(x̄ - 2s) of the deviations
        rows = table[table["actuator"] == axis]
        deviation = rows["travel_mm"] - rows["cmd_travel_mm"]
        mean, sd = deviation.groupby(rows["cmd_travel_mm"]).mean(), deviation.groupby(rows["cmd_travel_mm"]).std()
        assert ours["sigma_mm"] == pytest.approx(list(sd), abs=1e-6)  # the export keeps 6 decimals
        # 000 Eqs. 8.1-8.3 by hand: CR = 1.25 mm / (200 or 400 steps), repeatability 3 σ̄, accuracy CR/2 + 3 σ̄
        cr = {2: 1.25 / 200, 5: 1.25 / 400}[axis]
        assert ours["control_resolution_mm"] == pytest.approx(cr, rel=1e-15)
        assert ours["repeatability_mm"] == pytest.approx(3 * sd.mean(), abs=1e-6)
        assert ours["accuracy_mm"] == pytest.approx(cr / 2 + 3 * sd.mean(), abs=1e-6)
        assert ours["mean_deviation_mm"] == pytest.approx(list(mean), abs=1e-6)
        assert ours["iso230_2_forward"]["A_mm"] == pytest.approx(
            float((mean + 2 * sd).max() - (mean - 2 * sd).min()), abs=1e-6
        )
        assert ours["U_repeatability_mm"] > 0 and ours["dropped_readings"] == 0
    # the simulator's actuators read their travel within the gauge noise and the seeded joint errors
    assert all(abs(b) < 0.6 for a in result.values() for b in a["mean_deviation_mm"])


def test_analyze_actuator_without_a_control_resolution_names_the_fix(simulated, capsys, tmp_path):
    _, _, db, run_id, _ = simulated
    csv = tmp_path / "a.csv"
    _out(capsys, "export", str(run_id), "--store", str(db), "--kind", "actuator_travel", "--out", str(csv))
    assert main(["analyze", "actuator", str(csv)]) == 2
    err = capsys.readouterr().err
    assert "no cr_mm column and no --cr-mm given" in err and "--robot pkm5" in err and err.count("\n") == 1
    # an explicit CR overrides the model's for every actuator
    result = json.loads(_out(capsys, "analyze", "actuator", str(csv), "--cr-mm", "0.01", "--json"))["actuators"]
    assert {a["control_resolution_mm"] for a in result.values()} == {0.01}


def test_report_prints_the_numbers_bench_analyze_gives_on_its_raw_data(simulated, capsys, tmp_path):
    _, _, db, run_id, expected = simulated
    printed = _out(capsys, "report", str(run_id), "--store", str(db), "--out", str(tmp_path), "--format", "html")
    html_path, csv_path = (Path(p) for p in printed.split())
    html = html_path.read_text(encoding="utf-8")
    command = re.search(r"bench analyze actuator FILE\.csv (--robot pkm5 --instrument-u-mm \S+ --k 2)", html)
    assert command is not None
    result = json.loads(_out(capsys, "analyze", "actuator", str(csv_path), *command.group(1).split(), "--json"))[
        "actuators"
    ]
    summary = re.search(r'<table id="actuators">(.*?)</table>', html, re.DOTALL).group(1)
    for axis, groover in expected.items():
        figures = result[str(axis)]
        assert rounded_by_u(figures["repeatability_mm"], figures["U_repeatability_mm"]) in summary
        assert rounded_by_u(groover.accuracy_mm, figures["U_accuracy_mm"]) in summary
        for bias, u in zip(figures["mean_deviation_mm"], figures["U_mean_deviation_mm"]):
            assert rounded_by_u(bias, u) in html
    assert np.isclose(float(command.group(1).split()[3]), 0.01 / np.sqrt(6), rtol=1e-5)  # the gauge reads 0.01 mm
