"""The path report states U(AT_p), U(RT_p), U(AV), U(RV) exactly as ``bench analyze path`` and ``bench analyze
path-velocity`` print them for the same simulated run (its crossings' path and stations, its constant-velocity
readings, its instrument), names the same budget, and judges ``--criterion`` with those U under the guarded rule."""

from __future__ import annotations

import html
import re

import pytest
from reports_runs import html_tables, simulated_path_run

from bench.cli import main
from bench.reports import collect, write_report
from bench.reports.decision import FAIL, PASS
from bench.reports.path_run import PathDesign, attained_cycles, path_stations, speed_readings
from bench.store import Store


@pytest.fixture(scope="module")
def line_run(tmp_path_factory):
    """A simulated straight-line run of 3 cycles (the fewest the path model takes) and its report."""
    folder = tmp_path_factory.mktemp("path_u")
    run_id = simulated_path_run(folder, shape="line", cycles=3, seed=4)
    with Store(folder / "p.db", read_only=True) as store:
        report = collect(store, run_id)
        samples = store.samples(run_id, kind="path")
        design = PathDesign.from_config(store.run(run_id).config, "test")
    ((figure,),) = [report.analysis.figures]
    cycles = attained_cycles(samples)[("line", 100.0)]
    return folder, run_id, report, figure, design, cycles


def _csv(path, cycles) -> str:
    """``cycle, t_s, x_mm, y_mm, z_mm`` at full precision (repr), one row per reading."""
    lines = ["cycle,t_s,x_mm,y_mm,z_mm"]
    for cycle, (t, p) in enumerate(cycles, start=1):
        lines += [",".join(map(repr, (cycle, float(ti), *map(float, pi)))) for ti, pi in zip(t, p)]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def _cli(capsys, *argv) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


def test_the_report_states_the_numbers_the_cli_prints_for_the_same_run(line_run, capsys, tmp_path):
    folder, run_id, report, figure, design, cycles = line_run
    assert figure.n_cycles == 3 and figure.at_u is not None and figure.rv_u is not None
    row = dict(zip(*html_tables(write_report(folder / "p.db", run_id, folder / "out").html)["path"]))
    stations = path_stations(design.path("line"), 1.0, 2.0)
    commanded = tmp_path / "stations.csv"
    commanded.write_text(
        "station,x_mm,y_mm,z_mm\n"
        + "\n".join(f"{i}," + ",".join(repr(float(v)) for v in point) for i, point in enumerate(stations))
        + "\n"
    )
    u_mm = report.instrument.sigma_mm
    assert u_mm is not None  # the simulated mice state their resolution: U includes the instrument
    path_text = _cli(
        capsys,
        "analyze",
        "path",
        _csv(tmp_path / "line.csv", [(t, p) for _, t, p, _ in cycles]),
        "--commanded",
        str(commanded),
        "--instrument-u-mm",
        repr(u_mm),
    )
    at, rt = re.search(r"AT_p = (.+?) mm \(k = 2\), RT_p = (.+?) mm \(k = 2\)", path_text).groups()
    assert " ± " in at and (row["AT ± U (mm)"], row["RT ± U (mm)"]) == (at, rt)
    readings = speed_readings(cycles, 2.0, figure.commanded_mm_s, design.final_hold_s)
    velocity_text = _cli(
        capsys,
        "analyze",
        "path-velocity",
        _csv(tmp_path / "speeds.csv", readings),
        "--commanded-mm-s",
        repr(figure.commanded_mm_s),
    )
    av, rv = re.search(r"AV = (.+?) % \(k = [\d.]+\), RV = (.+?) % \(k = 2\)", velocity_text).groups()
    assert (row["AV ± U (%)"], row["RV ± U (%)"]) == (av, rv)
    # the budget named in the words of the CLI, its source the run's settings instead of the CLI's option
    statement = report.analysis.budget
    assert statement == f"U includes the instrument: u = {u_mm:g} mm per axis (the run's instrument settings)"
    assert statement.split(" (")[0] in path_text
    assert report.analysis.speed_budget.split(" (")[0] in velocity_text  # "U(AV) excludes the instrument: ..."
    assert any(statement in html.unescape(p.read_text(encoding="utf-8")) for p in (folder / "out").glob("*.html"))
    # the report's recompute command, bench analyze path-run, prints the same cells and budgets
    run_text = _cli(capsys, "analyze", "path-run", str(run_id), "--store", str(folder / "p.db"))
    assert all(row[h] in run_text for h in ("AT ± U (mm)", "RT ± U (mm)", "AV ± U (%)", "RV ± U (%)"))
    assert statement in run_text and report.analysis.speed_budget in run_text


def test_the_guarded_rule_judges_with_the_u(line_run):
    """Today's figures with a U are proven either way when the limit lies beyond U; a limit inside ± U is not
    proven (before: every path figure read 'not proven' under the guarded rule, having no U)."""
    folder, run_id, _, f, _, _ = line_run
    criteria = {
        "AT_mm": f.at_mm + 1.5 * f.at_u.expanded_uncertainty,  # value + U below the limit: pass proven
        "RT_mm": f.rt_mm - 1.5 * f.rt_u.expanded_uncertainty,  # value - U above the limit: fail proven
        "RV_pct": f.rv_pct,  # the limit within ± U: not proven
    }
    with Store(folder / "p.db", read_only=True) as store:
        judged = collect(store, run_id, criteria=criteria, decision_rule="guarded")
    verdicts = {name: (u, result) for name, _, _, u, _, result in judged.decision.verdicts}
    assert verdicts == {
        "AT_mm": (f.at_u.expanded_uncertainty, PASS),
        "RT_mm": (f.rt_u.expanded_uncertainty, FAIL),
        "RV_pct": (f.rv_u.expanded_uncertainty, "not proven"),
    }
