"""Reports of the documents' bench tests: actuator_accuracy, payload_ladder and lasergrid_hits.

Independent paths: the stored samples read back with ``Store.samples`` and reduced with numpy by hand; the
document tables (Appendix D2 of the delta thesis); the injected truth of the written runs (an actuator scale error,
a sag per kg); the ``bench analyze`` command on the raw-data CSV the report writes; the HTML (parsed) and the PDF
(pypdf) for the printed tables.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from reports_runs import (
    APPENDIX_D2,
    LADDER_SETTINGS,
    cli_json,
    html_tables,
    pdf_text,
    rounded_by_u,
    write_actuator_run,
    write_grid_hit_run,
    write_ladder_run,
    write_pose_run,
)

from bench.cli import main
from bench.errors import ConfigError, InsufficientData
from bench.metrology import STANDARD_GRAVITY_M_S2, payload_compliance, payload_shift
from bench.metrology.formatting import reading_step_mm
from bench.reports import ActuatorReport, GridHitReport, LadderReport, collect, write_comparison, write_report
from bench.store import Store


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("layouts")
    store = Store(folder / "bench.db")
    ids = {"actuator": write_actuator_run(store), "ladder": write_ladder_run(store), "grid": write_grid_hit_run(store)}
    reports = {name: collect(store, run_id) for name, run_id in ids.items()}
    paths = {name: write_report(store, run_id, folder / "out") for name, run_id in ids.items()}
    yield store, ids, reports, paths, folder
    store.close()


def _readings(store, run_id):
    """{actuator: {target: [readings in cycle order]}} straight from the stored samples."""
    out: dict[int, dict[float, list[float]]] = {}
    for sample in sorted(store.samples(run_id, kind="actuator_travel"), key=lambda s: s.cycle):
        values = sample.values
        out.setdefault(int(values["actuator"]), {}).setdefault(values["cmd_travel_mm"], []).append(values["travel_mm"])
    return out


# ---- actuator_accuracy ----


def test_actuator_figures_equal_a_hand_computation_from_the_stored_samples(runs):
    store, ids, reports, _, _ = runs
    report = reports["actuator"]
    assert isinstance(report, ActuatorReport) and [r.actuator for r in report.actuators] == ["1", "5"]
    stored = _readings(store, ids["actuator"])
    for result, cr in zip(report.actuators, (0.00625, 0.003125)):  # 000 Eq. 8.1: 1.25 mm / 200 or 400 steps
        by_target = stored[int(result.actuator)]
        targets = sorted(by_target)
        sigma = [np.std(by_target[t], ddof=1) for t in targets]
        assert result.targets_mm == tuple(targets) and result.control_resolution_mm == cr
        assert result.groover.repeatability_mm == pytest.approx(3 * np.mean(sigma), abs=1e-12)
        assert result.groover.accuracy_mm == pytest.approx(cr / 2 + 3 * np.mean(sigma), abs=1e-12)
        bias = [np.mean(by_target[t]) - t for t in targets]
        assert result.groover.mean_deviation_mm == pytest.approx(bias, abs=1e-12)
        assert result.iso230_2.repeatability_forward_mm == pytest.approx(4 * max(sigma), abs=1e-12)
        assert result.iso230_2.systematic_forward_mm == pytest.approx(max(bias) - min(bias), abs=1e-12)
        u_gauge = report.instrument.sigma_mm
        assert u_gauge == pytest.approx(0.01 / math.sqrt(6))  # 0.01 mm readings, a zero and a reading
        for u, s, b in zip(result.bias_u, sigma, bias):
            assert (u.value, u.expanded_uncertainty) == pytest.approx((b, 2 * math.hypot(s / 2, u_gauge)), abs=1e-12)
    # the injected scale errors (+0.4 %, -0.3 %) show as a bias growing with the travel
    slopes = [np.polyfit(r.targets_mm, r.groover.mean_deviation_mm, 1)[0] for r in report.actuators]
    assert slopes == pytest.approx([0.004, -0.003], abs=0.0015)


def test_actuator_report_equals_bench_analyze_actuator_on_its_raw_data(runs, capsys):
    _, _, reports, paths, _ = runs
    report = reports["actuator"]
    result = cli_json(
        capsys,
        "analyze",
        "actuator",
        str(paths["actuator"].csv[0]),
        "--robot",
        "pkm5",
        "--instrument-u-mm",
        repr(report.instrument.sigma_mm),
        "--k",
        "2",
        "--json",
    )["actuators"]
    for ours in report.actuators:
        theirs = result[ours.actuator]
        assert theirs["repeatability_mm"] == pytest.approx(ours.groover.repeatability_mm, rel=1e-12)
        assert theirs["accuracy_mm"] == pytest.approx(ours.groover.accuracy_mm, rel=1e-12)
        assert theirs["U_repeatability_mm"] == pytest.approx(ours.repeatability_u.expanded_uncertainty, rel=1e-12)
        assert theirs["U_mean_deviation_mm"] == pytest.approx([u.expanded_uncertainty for u in ours.bias_u], rel=1e-12)
        assert theirs["iso230_2_forward"]["A_mm"] == pytest.approx(ours.iso230_2.accuracy_forward_mm, rel=1e-12)
    assert "bench analyze actuator FILE.csv --robot pkm5 --instrument-u-mm 0.00408248 --k 2" in paths[
        "actuator"
    ].html.read_text(encoding="utf-8")


def _decimals(report) -> int:
    """Decimals of the run's readings, from the written-out resolution (0.01 -> 2)."""
    text = f"{report.instrument.resolution_mm:g}"
    return len(text.split(".")[1]) if "." in text else 0


def test_actuator_html_and_pdf_print_the_tables(runs):
    _, _, reports, paths, _ = runs
    report = reports["actuator"]
    tables = html_tables(paths["actuator"].html)
    summary = {row[0]: row for row in tables["actuators"][1:]}
    pdf = pdf_text(paths["actuator"].pdf)
    for result in report.actuators:
        repeatability = rounded_by_u(result.groover.repeatability_mm, result.repeatability_u.expanded_uncertainty)
        assert summary[result.actuator][4] == repeatability and repeatability in pdf
        # a figure without a U: to the calliper readings' last decimal (0.01 mm -> 2), not 4 decimals
        assert summary[result.actuator][9] == f"{result.iso230_2.accuracy_forward_mm:.{_decimals(report)}f}"
    bias_rows = [row for row in tables["actuator-targets"][1:] if row[:2] == ["5", "50"]]
    (row,) = bias_rows
    assert row[4] == rounded_by_u(
        report.actuators[1].bias_u[2].value, report.actuators[1].bias_u[2].expanded_uncertainty
    )
    assert row[4] in pdf
    deviations = {row[1]: row for row in tables["deviations"][1:]}
    assert deviations["direction"][4] == "deviates" and deviations["fixture"][4] == "conforms"
    assert deviations["travels"][4] == "deviates"  # 10, 30, 50 mm instead of 000's 10-50 mm in 10 mm steps
    assert (
        "Deviations from pkm5 dissertation §8.4 / ISO 230-2" in pdf
        and "6. Results" in pdf
        and "10. Statement of scope" in pdf
    )


def test_actuator_criteria_are_judged_under_the_chosen_rule_on_page_1_and_in_the_decision(runs):
    """--criterion for an own layout: each actuator's repeatability ± U against the limit, by hand under the guarded
    rule (ISO 14253-1: pass when value + U <= limit, fail when value - U > limit, else not proven)."""
    store, ids, reports, _, folder = runs
    figures = [
        (r.groover.repeatability_mm, r.repeatability_u.expanded_uncertainty) for r in reports["actuator"].actuators
    ]
    limit = sorted(v for v, _ in figures)[len(figures) // 2]  # the median: some actuators each side of it
    expected = ["pass" if v + u <= limit else "fail" if v - u > limit else "not proven" for v, u in figures]
    judged = collect(store, ids["actuator"], criteria={"repeatability_mm": limit}, decision_rule="guarded")
    assert [v[-1] for v in judged.decision.verdicts] == expected
    assert [v[2:4] for v in judged.decision.verdicts] == [pytest.approx(f) for f in figures]
    paths = write_report(
        store, ids["actuator"], folder / "judged", criteria={"repeatability_mm": limit}, decision_rule="guarded"
    )
    tables = html_tables(paths.html)
    assert [row[-1] for row in tables["decision"][1:]] == expected
    assert tables["verdict"][1][0] == "repeatability (mm)" and tables["verdict"][-1][0] == "Overall"
    with pytest.raises(
        ConfigError, match="--criterion AP_mm: not a characteristic of this report, expected NAME=LIMIT"
    ):
        collect(store, ids["actuator"], criteria={"AP_mm": 0.5})


def test_actuator_deviations_follow_the_stored_configuration(tmp_path):
    with Store(tmp_path / "b.db") as store:
        conforming = write_actuator_run(
            store,
            distances_mm=(10.0, 20.0, 30.0, 40.0, 50.0),
            repeats=10,
            settings={"instrument": {"instrument": "depth gauge", "mpe_mm": 0.02}},
        )
        report = collect(store, conforming, resamples=50)
        rows = {d.topic: d for d in report.deviations}
        assert {t: rows[t].status for t in ("fixture", "travels", "repeats", "instrument")} == dict.fromkeys(
            ("fixture", "travels", "repeats", "instrument"), "conforms"
        )
        assert rows["targets"].status == "deviates" and "evenly spaced" in rows["targets"].done  # ISO 230-2
        assert report.instrument.sigma_mm == pytest.approx(math.hypot(0.01 / math.sqrt(6), 0.02 / math.sqrt(3)))
        bare = write_actuator_run(store, settings={})
        with pytest.raises(InsufficientData, match="clause 000 §8.4 instrument: not stored: settings.instrument"):
            collect(store, bare)
        assert collect(store, bare, allow_unknown=True, resamples=50).deviations


def test_actuator_run_with_a_missing_reading_drops_that_repeat_and_says_so(tmp_path):
    with Store(tmp_path / "b.db") as store:
        run_id = write_actuator_run(store, repeats=4)
        samples = store.samples(run_id, kind="actuator_travel")
        # a run cut short: copy every sample but the last reading of actuator 5 into a failed run
        cut = store.start_run(
            protocol_name="actuator_accuracy",
            protocol_version="1",
            robot="pkm5",
            config=store.run(run_id).config,
            settings=store.run(run_id).settings,
        )
        for sample in samples[:-1]:
            store.add_sample(
                cut,
                sample.step_index,
                kind=sample.kind,
                values=sample.values,
                pose=sample.pose,
                cycle=sample.cycle,
                t_s=sample.t_s,
            )
        store.set_status(cut, "failed", "operator stopped")
        report = collect(store, cut, resamples=50)
        five = report.actuators[1]
        assert five.groover.n == 3 and five.dropped == 2  # repeat 4 kept only 10 and 30 mm
        assert any("actuator 5: 2 readings of repeats missing a travel left out" in n for n in report.notes)
        assert any(n.startswith("run status failed (operator stopped)") for n in report.notes)
        assert {d.topic: d for d in report.deviations}[
            "repeats"
        ].done == "4 planned, 3 complete (fewest at any actuator)"


# ---- payload_ladder ----


def test_ladder_leg_summary_equals_bench_analyze_payload_on_its_raw_data(runs, capsys):
    store, ids, reports, paths, _ = runs
    report = reports["ladder"]
    assert isinstance(report, LadderReport)
    legs = cli_json(capsys, "analyze", "payload", str(paths["ladder"].csv[0]), "--json")["legs"]
    for i, leg in enumerate(str(n) for n in range(1, 7)):
        assert legs[leg]["max_error_mm"] == pytest.approx(report.summary.max_error_mm[i], abs=1e-12)
        assert legs[leg]["load_at_max_kg"] == report.summary.load_at_max_kg[i]
        assert legs[leg]["mean_error_mm"] == pytest.approx(report.summary.mean_error_mm[i], abs=1e-12)
    # by hand: the mean signed error per load of leg 3, from the stored samples
    samples = [s.values for s in store.samples(ids["ladder"], kind="leg_length") if s.values["leg"] == 3]
    for load in (0.0, 2.0, 5.0, 10.0):
        errors = [v["length_mm"] - v["cmd_length_mm"] for v in samples if v["load_kg"] == load]
        assert report.leg_errors.loc[load, "3"] == pytest.approx(np.mean(errors), abs=1e-12)
    assert report.lifts_per_load == (3, 3, 3, 3)


def test_ladder_payload_error_and_compliance_recover_the_injected_sag(runs):
    from motion import pkm5

    store, ids, reports, _, _ = runs
    report = reports["ladder"]
    # independently: FK of each lift's six stored lengths, then the metrology API
    lifts: dict[tuple, dict[int, float]] = {}
    for sample in store.samples(ids["ladder"], kind="leg_length"):
        lifts.setdefault((sample.values["load_kg"], sample.cycle), {})[int(sample.values["leg"])] = sample.values[
            "length_mm"
        ]
    keys = sorted(lifts)
    fk = pkm5.forward_kinematics(np.array([[lifts[k][leg] for leg in range(1, 7)] for k in keys]), mode="translation")
    by_load: dict[float, list] = {}
    for (load, _), pose in zip(keys, fk.pose[:, :3]):
        by_load.setdefault(load, []).append(pose)
    direct = payload_shift(by_load, reference_load_kg=0.0)
    np.testing.assert_allclose(report.shift.shift_mm, direct.shift_mm, atol=1e-9)
    z0 = direct.barycentre_mm[0, 2]
    k = payload_compliance([load for load, _ in keys], fk.pose[:, 2] - z0, reference_load_kg=0.0)
    assert report.compliance.compliance_mm_per_n == pytest.approx(k.compliance_mm_per_n, rel=1e-9)
    # the truth written into the run: 0.02 mm of sag per kg, straight down
    assert report.shift.shift_mm[:, 2] == pytest.approx([0.0, -0.04, -0.1, -0.2], abs=0.01)
    assert report.compliance.compliance_mm_per_n == pytest.approx(
        -0.02 / STANDARD_GRAVITY_M_S2, abs=3 * report.compliance.u_compliance_mm_per_n
    )
    assert all(lift.used and lift.residual_mm < 0.02 for lift in report.lifts) and len(report.lifts) == 12


def test_ladder_html_and_pdf_print_the_tables_and_the_deviations(runs):
    _, _, reports, paths, _ = runs
    report = reports["ladder"]
    tables = html_tables(paths["ladder"].html)
    assert tables["ladder"][0][:3] == ["Load (kg)", "Lifts", "e_1 (mm)"] and len(tables["ladder"]) == 5
    assert tables["ladder"][4][2] == f"{report.leg_errors.loc[10.0, '1']:+.{_decimals(report)}f}"
    shift = {row[0]: row for row in tables["payload-shift"][1:]}
    assert shift["10"][3] == f"{report.shift.shift_norm_mm[3]:.{_decimals(report)}f}"
    assert len(tables["lifts"]) == 13
    deviations = {row[1]: row for row in tables["deviations"][1:]}
    assert deviations["repeats"][4] == "conforms"  # 3 lifts per load (project §12.3)
    assert deviations["ladder"][4] == "deviates" and deviations["reference runs"][4] == "deviates"
    assert "describe the rig's two simulated optical mice" in deviations["instrument"][3]
    assert tables["instrument"][1] == [
        "Readings",
        "digital calliper, leg lengths entered by the operator (pkm5 dissertation §8.7)",
    ]
    pdf = pdf_text(paths["ladder"].pdf)
    for text in (
        "Leg actuation error e_i(m)",
        shift["10"][2],
        f"{report.compliance.compliance_mm_per_n:+.3e}",
        "Deviations from pkm5 dissertation §8.7 / project definition",
        "bench analyze payload FILE.csv",
    ):
        assert text in pdf, text


def test_ladder_with_unloaded_references_ascending_then_descending_conforms(tmp_path):
    with Store(tmp_path / "b.db") as store:
        run_id = write_ladder_run(store, loads_kg=(0.0, 5.0, 10.0, 5.0, 0.0), repeats=3)
        report = collect(store, run_id)
        rows = {d.topic: d.status for d in report.deviations}
        assert rows["reference runs"] == rows["hysteresis"] == "conforms"
        assert list(report.leg_errors.index) == [0.0, 5.0, 10.0]  # both visits of a load averaged, ladder order
        assert report.lifts_per_load == (6, 6, 3)


# ---- lasergrid_hits ----


def test_grid_hit_rates_reproduce_appendix_d2(runs):
    store, ids, reports, _, _ = runs
    report = reports["grid"]
    assert isinstance(report, GridHitReport)
    assert [(h.height_mm, h.expected.k, h.expected.n) for h in report.hits.heights] == [
        (140.0, 397, 400),
        (170.0, 395, 400),
        (200.0, 392, 400),
    ]
    assert [h.expected.rate for h in report.hits.heights] == [0.9925, 0.9875, 0.98]  # Appendix D2, "%" column
    at_200 = [s.expected.k for s in report.hits.sensors if s.height_mm == 200.0]
    assert tuple(at_200) == APPENDIX_D2[200.0]
    # by hand from the stored samples: misses at 200 mm that lit another sensor (every second miss)
    misses = [
        s.values
        for s in store.samples(ids["grid"], kind="grid_hit")
        if s.values["cmd_z_mm"] == -200.0 and not s.values["hit_expected"]
    ]
    any_200 = next(h.any for h in report.hits.heights if h.height_mm == 200.0)
    assert any_200.k == 392 + sum(v["hit_any"] for v in misses) and len(misses) == 8
    for h in report.hits.heights:  # Wilson at z = 2 contains the rate and stays in [0, 1]
        assert 0.0 <= h.expected.low < h.expected.rate < h.expected.high <= 1.0


def test_grid_hit_html_and_pdf_print_the_tables_and_the_decision(runs):
    _, _, reports, paths, _ = runs
    tables = html_tables(paths["grid"].html)
    heights = {row[0]: row for row in tables["hit-heights"][1:]}
    assert heights["140"][2] == "397 / 400" and heights["140"][3].startswith("99.25 % [")
    assert heights["200"][5] == "98.00 %"  # the thesis's own figure beside ours
    assert len(tables["hit-sensors"]) == 1 + 48
    assert [row[3] for row in tables["decision"][1:]] == ["pass", "pass", "pass"]  # >= 97 % (thesis specification)
    deviations = {row[1]: row[4] for row in tables["deviations"][1:]}
    assert deviations == {
        "sensors": "conforms",
        "attempts": "conforms",
        "heights": "conforms",
        "approach": "conforms",
        "hit": "conforms",
        "instrument": "conforms",
    }
    pdf = pdf_text(paths["grid"].pdf)
    for text in ("397 / 400", heights["140"][3], "Deviations from thesis §8.4.3", "grid_hit_rates"):
        assert text in pdf, text


def test_grid_hit_failing_the_specification(tmp_path):
    with Store(tmp_path / "b.db") as store:
        run_id = write_grid_hit_run(store, hits={170.0: (2,) * 16}, attempts=3)
        report = collect(store, run_id)
        rows = {d.topic: d for d in report.deviations}
        assert rows["attempts"].status == rows["heights"].status == "deviates"
        paths = write_report(store, run_id, tmp_path / "out", ("html",))
        decision = html_tables(paths.html)["decision"]
        assert decision[1][2:] == ["66.67 %", "fail"]


# ---- shared: raw data, CLI, refusals ----


@pytest.mark.parametrize("name", ["actuator", "ladder", "grid"])
def test_raw_data_is_the_tidy_table_cited_with_its_sha256(runs, name):
    store, ids, reports, paths, _ = runs
    csv = paths[name].csv[0]
    html = paths[name].html.read_text(encoding="utf-8")
    assert hashlib.sha256(csv.read_bytes()).hexdigest() in html
    kind = {"actuator": "actuator_travel", "ladder": "leg_length", "grid": "grid_hit"}[name]
    assert (
        len(reports[name].table)
        == len(store.samples(ids[name], kind=kind))
        == int(html_tables(paths[name].html)["rawdata"][1][2])
    )
    assert "Every number above can be recomputed from these files: bench" in html


def test_cli_reports_the_three_kinds_and_refuses_criteria_and_comparisons(runs, capsys, tmp_path):
    _, ids, _, _, folder = runs
    store = str(folder / "bench.db")
    for run_id in ids.values():
        assert main(["report", str(run_id), "--store", store, "--out", str(tmp_path), "--format", "pdf"]) == 0
    assert capsys.readouterr().out.split() == [
        str(tmp_path / f"{stem}{i}{ext}")
        for i in ids.values()
        for stem, ext in (("report_run", ".pdf"), ("run", "_samples.csv"))
    ]
    assert main(["report", str(ids["grid"]), "--store", store, "--out", str(tmp_path), "--criterion", "AP_mm=0.5"]) == 2
    assert (
        "--criterion AP_mm: this report states no verdict (the hit rate is judged against the thesis's own "
        "specification (>= 97 % at every height))" in capsys.readouterr().err
    )
    with Store(folder / "bench.db") as opened:
        pose = write_pose_run(opened, config=None)
        with pytest.raises(
            ConfigError,
            match=f"--compare: run {pose} is a iso9283_pose run and run "
            f"{ids['actuator']} a actuator_accuracy run; compare runs of the same",
        ):
            write_comparison(opened, pose, ids["actuator"], tmp_path)


@given(st.lists(st.integers(-100_000, 100_000), min_size=1, max_size=20), st.integers(0, 4))
def test_reading_step_is_the_coarsest_decimal_every_reading_is_a_multiple_of(counts, decimals):
    step = 10.0**-decimals
    readings = [round(c * step, decimals) for c in counts]
    found = reading_step_mm(readings)
    assert found is not None and found >= step * (1 - 1e-9)
    assert all(abs(r / found - round(r / found)) < 1e-6 for r in readings)
    assert reading_step_mm([0.123456]) is None


def test_ladder_settings_never_pass_the_mice_for_the_calliper():
    from bench.reports.instrument import reading_instrument

    class Run:  # the one attribute of a RunRecord that reading_instrument reads
        settings = {**LADDER_SETTINGS, "instrument": {**LADDER_SETTINGS["instrument"], "u_mm": 0.5}}

    info = reading_instrument(Run(), (), [238.31, 238.32], difference=False, reader="calliper")
    assert info.sigma_mm == pytest.approx(0.01 / math.sqrt(12))  # the mice's u_mm is not the calliper's
    assert info.settings["readings"] == "calliper" and info.settings["rig"]["u_mm"] == 0.5


def _printed_text(path) -> str:
    """The report's visible text without its figures, styles and the verbatim recomputing command."""
    import re

    text = path.read_text(encoding="utf-8")
    for pattern in (r"<svg.*?</svg>", r"<style>.*?</style>", r"<p>Every number above can be recomputed.*?</p>"):
        text = re.sub(pattern, "", text, flags=re.DOTALL)
    return text


def test_reports_speak_customer_language(runs):
    from bench.reports.language import INTERNAL_PATTERNS

    _, _, _, paths, _ = runs
    for name, written in paths.items():
        text = _printed_text(written.html)
        pdf = pdf_text(written.pdf)
        for pattern in INTERNAL_PATTERNS:
            assert not pattern.search(text), f"{name}: {pattern.pattern} in {pattern.search(text).group(0)!r}"
            assert not pattern.search(pdf.replace("Every number above", "")) or "recomputed" in pdf, name
