"""ISO 230-2 bidirectional approaches in the actuator protocol: the linear cycle's plan, a run on the simulated actuator
bench with typed readings through the real protocol, and B, R, A from the stored run (bench analyze, the report)
against an independent computation and the simulator's seeded backlash."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_station import STATIONS, _GaugeReader, _rehearsed_run

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology.bidirectional_tables import analyze_bidirectional
from bench.protocols.actuator import ActuatorAccuracy
from bench.simulators.error_model import ErrorModel
from bench.simulators.pkm5_plant import PKM5_ERRORS
from bench.steps import ActuatorMove, Prompt
from bench.store import Store, tidy_table

TRAVELS = (10.0, 20.0, 35.0)


def _readings(protocol):
    """(stroke before the approach, target stroke, direction, cycle) of every reading prompt of the plan."""
    out, where, last = [], None, None
    for step in protocol.steps():
        if isinstance(step, ActuatorMove):
            where, last = last, step.stroke_mm
        elif isinstance(step, Prompt) and step.field == "travel_mm":
            out.append((where, last, step.conditions["direction"], step.cycle))
    return out


def test_each_target_is_approached_from_below_and_from_above_past_an_overrun():
    p = ActuatorAccuracy(actuators=[2], distances_mm=[20.0, 10.0, 35.0], approach="bidirectional", overrun_mm=2.0)
    readings = _readings(p)
    assert p.cycles == 5 and len(readings) == 5 * 2 * 3  # ISO 230-2: 5 approaches per target and direction
    strokes = [5.0 + t for t in TRAVELS]
    for cycle in range(1, 6):
        mine = [r for r in readings if r[3] == cycle]
        assert [r[1] for r in mine] == strokes + strokes[::-1]  # increasing, then decreasing
        assert [r[2] for r in mine] == [1, 1, 1, -1, -1, -1]
        for before, target, direction, _ in mine:
            assert (target - before) * direction > 0  # approached in its direction
        assert mine[3][0] == 40.0 + 2.0  # the reversal: 2 mm past the highest target
        assert mine[0][0] == 5.0  # the start stroke, below the lowest target
    with pytest.raises(
        ConfigError,
        match=r"overrun_mm = 7: the reversals at 5 and 67 mm stroke, expected both "
        r"within 0-66 mm",
    ):
        ActuatorAccuracy(distances_mm=[10.0, 55.0], approach="bidirectional", overrun_mm=7.0, actuators=[1])
    unidirectional = ActuatorAccuracy(actuators=[2], distances_mm=[10.0], repeats=3)
    assert all("direction" not in s.conditions for s in unidirectional.steps() if isinstance(s, Prompt))


def test_hand_computed_signed_directions_and_a_repeatability_set_by_one_direction():
    """+1/-1 directions (an exported run). At 10 mm: ↑ 10.0, 10.2 (x̄↑ = 0.1, s↑ = 0.1√2), ↓ 10.1, 10.1 (x̄↓ = 0.1,
    s↓ = 0): B = 0 and 2s↑ + 2s↓ + |B| = 0.2√2 < R↑ = 0.4√2, so R = R↑; at 20 mm every reading is 20.0."""
    import pandas as pd

    frame = pd.DataFrame(
        {
            "cmd_travel_mm": [10, 10, 10, 10, 20, 20, 20, 20],
            "direction": [1.0, 1.0, -1.0, -1.0, 1.0, -1.0, 1.0, -1.0],
            "travel_mm": [10.0, 10.2, 10.1, 10.1, 20.0, 20.0, 20.0, 20.0],
            "actuator": [3.0] * 8,
        }
    )
    (r,) = analyze_bidirectional(frame)
    s_up = 0.1 * np.sqrt(2)
    assert r.axis == "3" and r.result.reversal_mm == pytest.approx((0.0, 0.0), abs=1e-12)
    assert r.result.repeatability_mm == pytest.approx(4 * s_up)
    assert r.result.repeatability_forward_mm == pytest.approx(4 * s_up)
    assert r.result.accuracy_mm == pytest.approx((0.1 + 2 * s_up) - min(0.1 - 2 * s_up, 0.0))


@pytest.fixture(scope="module")
def bench_run(tmp_path_factory):
    """actuator 2 on the simulated actuator bench, 3 targets, 5 bidirectional cycles, the gauge typed by a person."""
    folder = tmp_path_factory.mktemp("bidirectional")
    protocol = folder / "actuators.toml"
    protocol.write_text(
        'protocol = "actuator_accuracy"\nactuators = [2]\ndistances_mm = [10, 20, 35]\n'
        'approach = "bidirectional"\nsettle_s = 0.1\n'
    )
    station = folder / "bench.toml"
    station.write_text((STATIONS / "pkm5_actuator_bench.toml").read_text().replace('kind = "serial"', 'kind = "typed"'))
    with Store(folder / "b.db") as store:
        result, _ = _rehearsed_run(store, station, protocol, operator=_GaugeReader())
        assert result.exit_status == "completed", result.reason
    return folder, result.run_id


def _independent(table):
    """B_i, R and A from the stored readings, written out (ISO 230-2, iso9283.md §7.1)."""
    up, down = (table[table["direction"] == d] for d in (1.0, -1.0))
    x_up = np.array([up.loc[up["cmd_travel_mm"] == t, "travel_mm"].to_numpy() - t for t in TRAVELS])
    x_down = np.array([down.loc[down["cmd_travel_mm"] == t, "travel_mm"].to_numpy() - t for t in TRAVELS])
    m_up, m_down = x_up.mean(axis=1), x_down.mean(axis=1)
    s_up, s_down = x_up.std(axis=1, ddof=1), x_down.std(axis=1, ddof=1)
    b = m_up - m_down
    r = np.max(np.maximum(2 * s_up + 2 * s_down + np.abs(b), np.maximum(4 * s_up, 4 * s_down)))
    a = max(np.max(m_up + 2 * s_up), np.max(m_down + 2 * s_down)) - min(
        np.min(m_up - 2 * s_up), np.min(m_down - 2 * s_down)
    )
    return b, r, a


def test_the_stored_bidirectional_run_gives_b_r_a_and_the_simulators_backlash(bench_run, tmp_path, capsys):
    folder, run_id = bench_run
    db = str(folder / "b.db")
    with Store(db, read_only=True) as store:
        table = tidy_table(store, run_id, kind="actuator_travel")
    assert len(table) == 5 * 2 * 3 and set(table["direction"]) == {1.0, -1.0}
    b, r, a = _independent(table)
    out = tmp_path / "travels.csv"
    assert main(["export", str(run_id), "--kind", "actuator_travel", "--store", db, "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["analyze", "iso230-2", str(out), "--json"]) == 0
    axis = json.loads(capsys.readouterr().out)["axes"]["2"]
    assert axis["reversal_mm"] == pytest.approx(b.tolist(), abs=1e-9)
    assert axis["B_mm"] == pytest.approx(np.abs(b).max(), abs=1e-9)
    assert axis["R_mm"] == pytest.approx(r, abs=1e-9) and axis["A_mm"] == pytest.approx(a, abs=1e-9)
    assert (axis["n_up"], axis["n_down"]) == (5, 5)
    assert main(["analyze", "iso230-2-run", str(run_id), "--store", db, "--json"]) == 0
    from_store = json.loads(capsys.readouterr().out)["axes"]["2"]  # the stored run gives the CSV's figures
    assert {k: from_store[k] for k in ("B_mm", "R_mm", "A_mm")} == pytest.approx(
        {k: axis[k] for k in ("B_mm", "R_mm", "A_mm")}, abs=1e-12
    )
    assert main(["analyze", "iso230-2-run", str(run_id), "--store", str(tmp_path / "none.db")]) == 2
    assert "none.db: no run store there" in capsys.readouterr().err
    # the truth: the leg lengthens on an up approach, so x↑ - x↓ = -backlash of actuator 2 (seed 3), plus the
    # reading noise (0.05 mm) of 5 approaches each way: sigma of the mean of 3 B_i = 0.05 sqrt(2/5) / sqrt(3)
    backlash = ErrorModel.draw(PKM5_ERRORS, 6, 3).backlash[1]
    assert float(np.mean(b)) == pytest.approx(-backlash, abs=4 * 0.05 * np.sqrt(2 / 5) / np.sqrt(3))
    # the dissertation's figures use the approaches from below only
    assert main(["analyze", "actuator", str(out), "--robot", "pkm5", "--json"]) == 0
    (groover,) = json.loads(capsys.readouterr().out)["actuators"].values()
    up = table[table["direction"] == 1.0]
    assert groover["n"] == 5
    assert groover["mean_deviation_mm"] == pytest.approx(
        [float((up.loc[up["cmd_travel_mm"] == t, "travel_mm"] - t).mean()) for t in TRAVELS], abs=1e-9
    )
    assert groover["mean_deviation_mm"] == pytest.approx(axis["mean_deviation_up_mm"], abs=1e-9)


def test_the_report_of_a_bidirectional_run_shows_b_r_a(bench_run, tmp_path):
    folder, run_id = bench_run
    db = str(folder / "b.db")
    from bench.reports.actuator import collect_actuator

    with Store(db, read_only=True) as store:
        report = collect_actuator(store, run_id)
        b, r, a = _independent(tidy_table(store, run_id, kind="actuator_travel"))
    (bidirectional,) = report.bidirectional
    assert bidirectional.result.repeatability_mm == pytest.approx(r, abs=1e-9)
    assert report.actuators[0].groover.n == 5
    rows = {d.topic: d for d in report.deviations}
    assert rows["direction"].status == "conforms" and rows["cycles"].status == "conforms"
    assert main(["report", str(run_id), "--store", db, "--out", str(tmp_path), "--format", "html"]) == 0
    html = (tmp_path / f"report_run{run_id}.html").read_text()
    assert "ISO 230-2 bidirectional figures per actuator" in html
    # figures without a U of their own to 1 um, never finer than the gauge's readings (0.01 mm typed: 2 decimals)
    for value in (np.abs(b).max(), r, a):
        assert f"{value:.3f}" in html or f"{value:.2f}" in html, value


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-0.2, 0.2), min_size=12, max_size=12))
def test_swapping_the_directions_negates_b_and_keeps_r_and_a(deviations):
    """Invariant of B_i = x̄_i↑ − x̄_i↓, R and A (ISO 230-2): read the ↑ approaches as ↓ and back, and every B_i changes
    sign while R, E, M and A stay (they are symmetric in the two directions); row order carries no meaning."""
    import pandas as pd

    targets = [10.0, 20.0, 30.0] * 4
    directions = [1.0] * 6 + [-1.0] * 6
    frame = pd.DataFrame({"target_mm": targets, "direction": directions, "reading_mm": np.add(targets, deviations)})
    (forward,) = analyze_bidirectional(frame)
    (swapped,) = analyze_bidirectional(frame.assign(direction=-frame["direction"]).iloc[::-1])
    np.testing.assert_allclose(swapped.result.reversal_mm, -np.asarray(forward.result.reversal_mm), atol=1e-12)
    for name in ("repeatability_mm", "systematic_mm", "mean_bidirectional_mm", "accuracy_mm", "reversal_max_mm"):
        assert getattr(swapped.result, name) == pytest.approx(getattr(forward.result, name), abs=1e-12), name
