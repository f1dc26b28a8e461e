"""The distance report states AD_p and RD with their U exactly as ``bench analyze distance`` prints them for the
same run (its raw-data CSV, its instrument), and names the same budget."""

from __future__ import annotations

import html
import math
import re

import pytest
from reports_runs import html_tables, pose_config, write_pose_run
from scipy import stats

from bench.cli import main
from bench.errors import ConfigError
from bench.reports import collect, write_report
from bench.store import Store


def test_the_distance_report_states_the_numbers_the_cli_prints(tmp_path, capsys):
    with Store(tmp_path / "bench.db") as store:
        run_id = write_pose_run(store, config=pose_config(protocol="iso9283_distance", cycles=6), noise_mm=0.03)
        report = collect(store, run_id, resamples=50)
        paths = write_report(store, run_id, tmp_path / "out")
    (row,) = report.distances
    u_mm = report.instrument.sigma_mm
    assert u_mm is not None  # the stored 800 cpi mice: U includes the instrument
    argv = ["analyze", "distance", str(paths.csv[0]), "--from", row.first, "--to", row.second]
    assert main([*argv, "--instrument-u-mm", repr(u_mm)]) == 0
    text = capsys.readouterr().out
    ad, rd = re.search(r"AD_p = (.+?) mm \(k = [\d.]+\), RD = (.+?) mm \(k = 2\)", text).groups()
    header, cells = html_tables(paths.html)["distance"]
    printed = dict(zip(header, cells))
    assert " ± " in rd and (printed["AD_p ± U (mm)"], printed["RD ± U (mm)"]) == (ad, rd)
    # U(RD) is the chi pivot's: for 6 cycles w >= 1, so P(S/σ >= 1/(1 + w)) = p gives w in closed form (1.136)
    p = math.erf(2 / math.sqrt(2))
    w = math.sqrt(5 / stats.chi2.ppf(1 - p, 5)) - 1
    assert row.u_rd.expanded_uncertainty / row.result.rd_mm == pytest.approx(w, rel=1e-6) and w > 1
    budget = f"U includes the instrument: u = {u_mm:g} mm per axis"
    assert budget in text and f"{budget} (the run's instrument settings)" in html.unescape(paths.html.read_text())


def test_the_guarded_rule_judges_ad_and_rd_with_their_u(tmp_path):
    """AD_mm (|AD_p|, the error short or long alike) and RD_mm judge a distance run's figures with their U (a limit
    beyond U proves pass or fail, one within ± U is not proven); on a run without distance figures they are
    refused, never silently empty."""
    with Store(tmp_path / "bench.db") as store:
        run_id = write_pose_run(store, config=pose_config(protocol="iso9283_distance", cycles=6), noise_mm=0.03)
        (row,) = collect(store, run_id, resamples=50).distances
        u_ad, u_rd = row.u_ad.expanded_uncertainty, row.u_rd.expanded_uncertainty
        size = abs(row.result.ad_mm)  # AD_p is signed; the limit bounds its size
        criteria = {"AD_mm": size + 1.5 * u_ad, "RD_mm": row.result.rd_mm}
        judged = collect(store, run_id, criteria=criteria, decision_rule="guarded", resamples=50)
        assert {(name, where, value, u, result) for name, where, value, u, _, result in judged.decision.verdicts} == {
            ("AD_mm", row.label, size, u_ad, "pass"),
            ("RD_mm", row.label, row.result.rd_mm, u_rd, "not proven"),
        }
        failing = collect(store, run_id, criteria={"AD_mm": size - 1.5 * u_ad}, decision_rule="guarded")
        assert [v[-1] for v in failing.decision.verdicts] == ["fail"]
        pose = write_pose_run(store, config=pose_config(cycles=3))
        with pytest.raises(ConfigError, match="RD_mm judges distance figures, expected an iso9283_distance run"):
            collect(store, pose, criteria={"RD_mm": 1.0}, resamples=50)
