"""Page 1 of a report: identity, headline per velocity and load, verdict per characteristic, SIMULATED banner on
every page, run history; and one rounding in results.csv and the HTML."""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from reports_runs import SETTINGS, html_tables, pose_config, rounded_by_u, write_pose_run

from bench.cli import main
from bench.commands.demo import analyze_run, rounded_results
from bench.errors import ConfigError
from bench.reports import SIMULATED_BANNER, collect, write_report
from bench.reports.summary import Identity, interruptions
from bench.store import Store

LIVE = {
    **SETTINGS,
    "instrument": {**SETTINGS["instrument"], "instrument": "two optical mice (x-y, x-z)"},
    "robot": {**SETTINGS["robot"], "firmware": {"firmware_version": "1.0.0"}},
}


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    folder = tmp_path_factory.mktemp("summary")
    store = Store(folder / "bench.db")
    simulated = write_pose_run(
        store,
        seed=2,
        bias_mm=(0.3, -0.2, 0.1),
        noise_mm=0.04,
        config=pose_config(velocities_pct=[100.0, 10.0]),
        settings={
            **SETTINGS,
            "simulator": {"seed": 2},
            "dut": {"dut_serial": "PKM5-0042", "customer": "stored customer"},
        },
    )
    live = write_pose_run(store, seed=3, settings=LIVE)
    yield folder, store, simulated, live
    store.close()


@pytest.fixture(scope="module")
def simulated_report(stored):
    """The simulated run's report as written by default (HTML and PDF), read by the tests that need no options
    (the headline does not depend on project criteria: :func:`bench.reports.summary.headline_rows`)."""
    folder, store, simulated, _ = stored
    return write_report(store, simulated, folder / "c")


def _pdf_pages(path):
    from pypdf import PdfReader

    return [page.extract_text() for page in PdfReader(path).pages]


def test_headline_is_the_worst_and_mean_per_velocity(stored, simulated_report):
    _, store, run_id, _ = stored
    report = collect(store, run_id)
    rows = {row[0]: row for row in html_tables(simulated_report.html)["headline"][1:]}
    assert list(rows) == ["100 % velocity", "10 % velocity"]
    for velocity, key in ((100.0, "100 % velocity"), (10.0, "10 % velocity")):
        poses = [p for p in report.poses if dict(p.conditions)["velocity_pct"] == velocity]
        worst = max(poses, key=lambda p: p.accuracy.ap_mm)
        mean_ap = np.mean([p.accuracy.ap_mm for p in poses])
        mean_u = np.mean([p.ap_u.expanded_uncertainty for p in poses])
        assert rows[key][1] == "5"
        assert rows[key][2] == f"{rounded_by_u(worst.accuracy.ap_mm, worst.ap_u.expanded_uncertainty)} ({worst.pose})"
        assert rows[key][3] == rounded_by_u(mean_ap, mean_u)


def test_verdict_per_characteristic_and_overall(stored):
    folder, store, run_id, _ = stored
    report = collect(store, run_id)
    aps = sorted(p.accuracy.ap_mm for p in report.poses)
    limit = (aps[3] + aps[4]) / 2  # between the 4th and 5th smallest AP: 4 of 10 poses pass
    paths = write_report(store, run_id, folder / "b", formats=("html",), criteria={"AP_mm": limit, "RP_mm": 10.0})
    verdict = {row[0]: row for row in html_tables(paths.html)["verdict"][1:]}
    assert verdict["AP (mm)"][3:] == ["4 of 10", "FAIL"]
    assert verdict["RP (mm)"][3:] == ["10 of 10", "PASS"]
    assert verdict["Overall"][-1] == "FAIL"
    text = paths.html.read_text(encoding="utf-8")
    assert "Decision rule: simple acceptance (ILAC-G8:09/2019 4.2.1)" in text


def test_simulated_banner_on_every_page_and_only_for_simulated_runs(stored, simulated_report):
    folder, store, _, live = stored
    sim = simulated_report
    pages = _pdf_pages(sim.pdf)
    assert len(pages) > 3 and all(SIMULATED_BANNER in page for page in pages)
    assert f'<div class="banner" id="banner">{SIMULATED_BANNER}</div>' in sim.html.read_text(encoding="utf-8")
    real = write_report(store, live, folder / "d")
    assert not any(SIMULATED_BANNER in page for page in _pdf_pages(real.pdf))
    assert "banner" not in html_tables(real.html) and SIMULATED_BANNER not in real.html.read_text(encoding="utf-8")


def test_identity_from_the_stored_settings_overridden_by_the_cli(stored, capsys):
    folder, store, run_id, _ = stored
    assert (
        main(
            [
                "report",
                str(run_id),
                "--store",
                str(store.path),
                "--out",
                str(folder / "e"),
                "--format",
                "html",
                "--customer",
                "ACME Robotics",
                "--order",
                "PO-17",
                "--lab",
                "Bench lab 2",
            ]
        )
        == 0
    )
    capsys.readouterr()
    rows = dict(html_tables(folder / "e" / f"report_run{run_id}.html")["summary-identity"][1:])
    assert rows["Device under test (serial / asset)"] == "PKM5-0042"  # stored with the run
    assert rows["Customer"] == "ACME Robotics"  # the option wins over the stored value
    # nobody named the operator: an empty line to fill in by hand, never a placeholder's text
    assert rows["Order"] == "PO-17" and rows["Laboratory"] == "Bench lab 2" and rows["Operator"] == ""
    assert rows["Measuring point (TCP / reference point)"].startswith("platform centre of the kinematic model")
    with pytest.raises(ConfigError, match="settings.dut: unknown key 'colour'"):
        Identity.from_mapping({"colour": "red"})


def test_history_names_the_interruptions():
    t0 = datetime(2026, 12, 1, 10, 0, tzinfo=UTC)
    times = [t0 + timedelta(seconds=2 * i) for i in range(20)]
    times += [times[-1] + timedelta(seconds=600 + 2 * i) for i in range(20)]  # paused 10 min, then resumed
    (event,) = interruptions(times)
    assert event.time_utc == "2026-12-01T10:00:38+00:00"
    assert "no sample for 600 s" in event.event and "resumed 2026-12-01T10:10:38+00:00" in event.event
    assert interruptions(times[:20]) == []


def test_history_table_shows_the_end_status(tmp_path):
    with Store(tmp_path / "bench.db") as store:
        run_id = write_pose_run(store)
        store.set_status(run_id, "aborted", "stopped by the operator")
        paths = write_report(store, run_id, tmp_path / "out", formats=("html",))
    history = html_tables(paths.html)["history"][1:]
    # the fixture's run was settled completed first: the history keeps that settle too, then the end
    assert [event for _, event in history] == ["started", "completed", "aborted: stopped by the operator"]


def test_results_csv_and_html_give_the_same_numbers(stored, simulated_report):
    folder, store, run_id, _ = stored
    paths = simulated_report
    results = analyze_run(store, run_id)
    csv = rounded_results(results)
    csv_path = folder / "results.csv"
    csv.to_csv(csv_path, index=False)
    read = pd.read_csv(csv_path, dtype=str)
    table = html_tables(paths.html)["results"]
    html = {row[0]: row for row in table[1:]}
    assert list(html) == [f"P{i}, {v} % velocity" for v in (100, 10) for i in range(1, 6)]
    assert [f"{p}, {v} % velocity" for p, v in zip(read["pose"], read["velocity_pct"])] == list(html)
    for _, row in read.iterrows():
        label = f"{row['pose']}, {row['velocity_pct']} % velocity"
        assert html[label][3] == f"{row['AP_mm']} ± {row['U_AP_mm']}"
        assert html[label][7] == f"{row['RP_mm']} ± {row['U_RP_mm']}"


def test_customer_language_on_a_simulated_pose_run(tmp_path):
    from bench.reports.language import INTERNAL_PATTERNS, customer_text

    settings = {
        **SETTINGS,
        "simulator": {"seed": 1},
        "robot": {**SETTINGS["robot"], "port": "/dev/pts/3", "move_margin_s": 2.0, "reply_timeout_s": 1.0},
        "instrument": {**SETTINGS["instrument"], "mice": {"xy": "mouse 'mouse_xy' (/tmp/bench-sim-abc/mouse_xy.fifo)"}},
    }
    with Store(tmp_path / "bench.db") as store:
        run_id = write_pose_run(store, settings=settings)
        paths = write_report(store, run_id, tmp_path / "out", formats=("html",))
    tables = html_tables(paths.html)
    device = dict(tables["device"][1:])
    assert "move_margin_s" not in str(device) and "reply_timeout_s" not in str(device)  # appendix only
    appendix = dict(tables["settings"][1:])
    assert appendix["robot.move_margin_s"] == "2.0" and appendix["robot.port"] == "3"
    assert appendix["instrument.mice.xy"] == "mouse 'mouse_xy' (mouse_xy.fifo)"
    conditions = dict(tables["conditions"][1:])
    assert conditions["Test cube edge (mm)"] == "40" and "Poses (mm)" not in conditions  # no "poses —"
    text = re.sub(
        r"<svg.*?</svg>|<style>.*?</style>|<p>Every number above can be recomputed.*?</p>",
        "",
        paths.html.read_text(encoding="utf-8"),
        flags=re.DOTALL,
    )
    assert not [p.pattern for p in INTERNAL_PATTERNS if p.search(text)]
    assert customer_text("as in iso9283.md §7.1 (see docs/campaigns.md)") == "as in ISO 230-2"
    assert customer_text("calliper (000 §8.4, sensors.md §6.2)") == "calliper (pkm5 dissertation §8.4)"
    assert customer_text("calibration (delta4-lasergrid.md §6.5)") == "calibration (delta-robot dissertation)"


def test_compare_works_for_an_own_layout_and_shows_the_histories(tmp_path):
    from reports_runs import write_actuator_run

    from bench.reports import write_comparison

    with Store(tmp_path / "bench.db") as store:
        first, second = write_actuator_run(store, seed=1), write_actuator_run(store, seed=2)
        store.set_status(second, "aborted", "stopped by the operator")
        pose = write_pose_run(store)
        paths = write_comparison(store, first, second, tmp_path / "out", formats=("html",))
        with pytest.raises(
            ConfigError, match=f"run {first} is a actuator_accuracy run and run {pose} a iso9283_pose run"
        ):
            write_comparison(store, first, pose, tmp_path / "out", formats=("html",))
    tables = html_tables(paths.html)
    assert {"a-actuators", "b-actuators", "history"} <= set(tables)
    history = tables["history"][1:]
    assert history[0][1].endswith("started") and history[0][2].endswith("started")
    assert [row[1] for row in history if row[1] != "—"][-1].endswith("completed")  # A's history is shorter
    assert history[-1][2].endswith("aborted: stopped by the operator")
    assert tables["conditions"][1] == [
        "—",
        "same configuration, settings and calibrations in force, different history (see Run histories)",
        "",
    ]
    text = paths.html.read_text(encoding="utf-8")
    assert "The runs differ in their history" in text


def test_trend_over_three_runs_in_start_order(tmp_path, capsys):
    with Store(tmp_path / "bench.db") as store:
        ids = [write_pose_run(store, seed=s, bias_mm=(0.1 * s, 0.0, 0.0), noise_mm=0.02) for s in (1, 2, 3)]
        reports = [collect(store, i, resamples=50) for i in ids]
    out = tmp_path / "out"
    assert (
        main(
            [
                "report",
                str(ids[2]),
                "--trend",
                str(ids[0]),
                str(ids[1]),
                "--store",
                str(tmp_path / "bench.db"),
                "--out",
                str(out),
                "--format",
                "html",
                "--quiet",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out.split()
    assert printed[0] == str(out / f"trend_run{ids[0]}_run{ids[1]}_run{ids[2]}.html")
    rows = html_tables(out / Path(printed[0]).name)["trend"][1:]
    assert [row[0] for row in rows] == [str(i) for i in ids]  # start order, not the order given
    for row, report in zip(rows, reports):
        worst = max(report.poses, key=lambda p: p.accuracy.ap_mm)
        assert row[4] == f"{rounded_by_u(worst.accuracy.ap_mm, worst.ap_u.expanded_uncertainty)} ({worst.pose})"
    assert float(rows[2][4].split()[0]) > float(rows[0][4].split()[0])  # the growing bias shows
    assert (
        main(["report", str(ids[0]), "--trend", str(ids[0]), "--store", str(tmp_path / "bench.db"), "--out", str(out)])
        == 2
    )
    assert "--trend: 1 distinct run(s), expected two or more" in capsys.readouterr().err


def test_page_one_is_signable_without_placeholders(stored, capsys):
    """A station template's "Operator name" is not a name; the measuring point and the signature block are on
    page 1, and the title names the test, not "run N"."""
    folder, store, _, _ = stored
    run_id = write_pose_run(
        store, seed=4, settings={**SETTINGS, "dut": {"operator": "Operator name", "laboratory": "<lab>"}}
    )
    assert (
        main(
            [
                "report",
                str(run_id),
                "--store",
                str(store.path),
                "--out",
                str(folder / "sign"),
                "--format",
                "html",
                "--measuring-point",
                "TCP 40 mm below the platform flange",
                "--customer",
                "ACME",
            ]
        )
        == 0
    )
    capsys.readouterr()
    html = folder / "sign" / f"report_run{run_id}.html"
    tables = html_tables(html)
    rows = dict(tables["summary-identity"][1:])
    assert rows["Operator"] == "" and rows["Laboratory"] == "" and rows["Customer"] == "ACME"
    assert rows["Measuring point (TCP / reference point)"] == "TCP 40 mm below the platform flange"
    assert tables["signature"][0] == ["Role", "Name", "Signature", "Date"]
    assert [row[0] for row in tables["signature"][1:]] == ["Tested by", "Approved by"]
    text = html.read_text(encoding="utf-8")
    assert "Operator name" not in text and "&lt;lab&gt;" not in text
    assert not any("not recorded" in cell for row in tables["summary-identity"] + tables["signature"] for cell in row)
    assert f": run {run_id}<" not in text


def test_guarded_rule_says_not_proven_where_simple_passes(stored):
    """A value under the limit whose value + U is over it: simple acceptance passes it, guarded acceptance
    (ISO 14253-1) says "not proven"; a value whose value - U is over the limit fails under both."""
    folder, store, run_id, _ = stored
    report = collect(store, run_id)
    pose = max(report.poses, key=lambda p: p.accuracy.ap_mm)
    value, u = pose.ap_u.value, pose.ap_u.expanded_uncertainty
    limit = value + u / 2  # inside the uncertainty range above the value
    simple = write_report(store, run_id, folder / "simple", formats=("html",), criteria={"AP_mm": limit})
    guarded = write_report(
        store, run_id, folder / "guarded", formats=("html",), criteria={"AP_mm": limit}, decision_rule="guarded"
    )
    simple_rows = {row[1]: row[-1] for row in html_tables(simple.html)["decision"][1:]}
    guarded_rows = {row[1]: row[-1] for row in html_tables(guarded.html)["decision"][1:]}
    label = next(k for k in simple_rows if k.startswith(pose.pose + ",") or k == pose.pose)
    assert simple_rows[label] == "pass" and guarded_rows[label] == "not proven"
    assert html_tables(guarded.html)["verdict"][-1][-1] == "NOT PROVEN"
    assert "guarded acceptance (ISO 14253-1:2017" in guarded.html.read_text(encoding="utf-8")
    assert simple.report_id != guarded.report_id  # different verdicts, different report numbers


def test_report_numbers_are_unique_per_document(stored):
    """Same content issued twice: same content hash, issue counter 1 then 2; with a verdict: another hash."""
    folder, store, run_id, _ = stored
    first = write_report(store, run_id, folder / "numbers", formats=("html",))
    again = write_report(store, run_id, folder / "numbers", formats=("html",))
    judged = write_report(store, run_id, folder / "numbers", formats=("html",), criteria={"RP_mm": 10.0})
    assert first.report_id.endswith("-1") and again.report_id == first.report_id[:-1] + "2"
    assert judged.report_id.rsplit("-", 2)[1] != first.report_id.rsplit("-", 2)[1]
    assert re.fullmatch(rf"BR-{run_id:05d}-[0-9a-f]{{8}}-1", first.report_id)
    text = judged.html.read_text(encoding="utf-8")
    assert judged.report_id in text and first.report_id not in text
