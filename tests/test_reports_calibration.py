"""The kinematic-calibration page of ``bench report AFTER --compare BEFORE``, end to end on the simulated pkm5 with a
seeded true geometry: a calibration run (examples/kinematic_calibration.toml), ``bench calibrate``, the held-out
validation poses (examples/kinematic_validation.toml) with and without the calibration in force (the runs of
tests/calibrated_pkm5.py, which tests/test_kinematic_compensation.py checks), then the report.

Independent paths: ``bench analyze iso9283 --json`` on the raw data the report writes (the gain and per-pose
tables), the JSON ``bench calibrate --json`` printed (the parameter and
observability tables), the HTML (parsed) and the PDF (pypdf)."""

from __future__ import annotations

import numpy as np
import pytest
from calibrated_pkm5 import calibrated_runs
from figure_support import printed_font_sizes
from reports_runs import cli_json, html_tables, pdf_text, rounded_by_u

from bench.cli import main
from bench.reports import collect
from bench.reports.calibration import calibration_comparison, error_vectors
from bench.reports.document import fmt_mm
from bench.reports.plots import MIN_FONT_PT
from bench.store import Store
from motion.pkm5.calibration import PARAMETERS


@pytest.fixture(scope="module")
def validated(tmp_path_factory):
    runs = calibrated_runs(tmp_path_factory)
    folder = tmp_path_factory.mktemp("calibration_report")
    store, after, before = runs.store, runs.compensated, runs.nominal
    # A (the first run named) is the calibrated run: the page orders the pair by the calibrations, not by A and B
    assert (
        main(
            [
                "report",
                str(after),
                "--compare",
                str(before),
                "--store",
                str(store),
                "--out",
                str(folder / "out"),
                "--quiet",
            ]
        )
        == 0
    )
    html = folder / "out" / f"compare_run{after}_run{before}.html"
    return {
        "store": store,
        "folder": folder,
        "calibration": runs.calibration,
        "before": before,
        "after": after,
        "html": html,
        "tables": html_tables(html),
    }


def _instrument_u(store, run_id) -> float:
    with Store(store, read_only=True) as s:
        return collect(s, run_id).instrument.sigma_mm


def _shown(value: float, u: float) -> str:
    """A value as the report prints it beside no U of its own: to the decimal place of ``u`` (U = 0, as the ideal
    robot's RP can be: to 1 µm, the report's stated fallback)."""
    return f"{value:.3f}" if u == 0 else rounded_by_u(value, u).split(" ± ")[0]


def test_the_gain_equals_bench_analyze_on_the_raw_data(validated, capsys):
    before, after, folder = validated["before"], validated["after"], validated["folder"]
    analyzed = {}
    for name, run_id in (("before", before), ("after", after)):
        u = _instrument_u(validated["store"], run_id)
        raw = cli_json(
            capsys,
            "analyze",
            "iso9283",
            str(folder / "out" / f"run{run_id}_samples.csv"),
            "--instrument-u-mm",
            repr(u),
            "--json",
        )["poses"]
        analyzed[name] = raw
    poses = sorted(analyzed["before"])
    assert poses == sorted(analyzed["after"]) and len(poses) == 12

    def column(name, key):
        return np.array([analyzed[name][p][key] for p in poses])

    runs = ("before", "after")
    smallest_u_ap = [column(n, "U_AP_mm").min() for n in runs]  # a mean: to the place of the smallest U it averages
    expected = {
        "mean AP_P": ([column(n, "AP_mm").mean() for n in runs], smallest_u_ap),
        "largest AP_P": (
            [column(n, "AP_mm").max() for n in runs],
            [column(n, "U_AP_mm")[column(n, "AP_mm").argmax()] for n in runs],
        ),
        **{f"mean |AP_{a}|": ([np.abs(column(n, f"AP{a}_mm")).mean() for n in runs], smallest_u_ap) for a in "xyz"},
        "mean RP_l": ([column(n, "RP_mm").mean() for n in runs], [column(n, "U_RP_mm").min() for n in runs]),
    }
    gain = validated["tables"]["calibration-gain"]
    assert gain[0] == ["Quantity (over the poses of both runs)", "Before (mm)", "After (mm)", "Factor before / after"]
    assert [row[0] for row in gain[1:]] == list(expected)
    for row in gain[1:]:
        (b, a), (u_b, u_a) = expected[row[0]]
        assert row[1:3] == [_shown(b, u_b), _shown(a, u_a)]
        if row[0] != "mean RP_l":  # the ideal robot's RP is a count or two: its ratio says nothing
            assert row[3] == f"{b / a:.1f}"
    expected = {name: values for name, (values, _) in expected.items()}
    mean_before, mean_after = expected["mean AP_P"]
    assert mean_before > 0.5 and mean_before / mean_after > 5  # 0.982 -> 0.063 mm, 15.6x measured with seed 3

    rows = {row[0]: row for row in validated["tables"]["calibration-poses"][1:]}
    assert sorted(rows) == poses
    for pose in poses:
        b, a = analyzed["before"][pose], analyzed["after"][pose]
        assert rows[pose][1:3] == [rounded_by_u(b["AP_mm"], b["U_AP_mm"]), rounded_by_u(a["AP_mm"], a["U_AP_mm"])]
        for cell, result in zip(rows[pose][9:11], (b, a)):  # RP: a count or two, its U can be 0 (3 decimals then)
            if result["U_RP_mm"] == 0:  # a U of 0 is no uncertainty: said so, never "± 0.000"
                assert cell == f"{result['RP_mm']:.3f} (U not determined)"
                continue
            value, u = (float(part) for part in cell.split(" ± "))
            assert (value, u) == pytest.approx((result["RP_mm"], result["U_RP_mm"]), abs=0.0005)
        for i, axis in enumerate("xyz"):
            signed = [float(rows[pose][3 + 2 * i]), float(rows[pose][4 + 2 * i])]
            assert signed == pytest.approx([b[f"AP{axis}_mm"], a[f"AP{axis}_mm"]], abs=0.0051)


def test_the_parameter_and_observability_tables_are_the_stored_calibration(validated):
    calibration = validated["calibration"]
    identified = calibration["parameters"]
    rows = validated["tables"]["calibration-parameters"]
    assert rows[0] == ["Parameter", "Deviation from documented", "Standard uncertainty", "Unit"]
    assert [r[0] for r in rows[1 : 3 + 1]] == ["reg_x_mm", "reg_y_mm", "reg_z_mm"]  # the model's order
    assert sorted(r[0] for r in rows[1:]) == sorted(identified)
    for name, value, u, unit in rows[1:]:
        assert float(value) == pytest.approx(identified[name]["value"], abs=float(u) / 10 + 1e-12)
        assert float(u) == pytest.approx(identified[name]["uncertainty"], rel=0.05)
        assert unit == identified[name]["unit"]
    observed = dict(validated["tables"]["calibration-observability"][1:])
    condition = calibration["observability"]["condition_number"]
    # the default fit is MAP: every parameter free, the tolerances as the prior, the data part's condition reported
    assert calibration["fit"] == "map" and observed["Fit"].startswith("maximum a posteriori, prior: manufacturing")
    assert observed["Condition number of the data part"] == f"{condition:.3g} (the prior holds the weak directions)"
    assert observed["Fixed by the prior (the data did not inform them)"] == (
        ", ".join(calibration["prior_only"]) or "none"
    )
    assert observed["Combinations the data alone cannot identify"] == "; ".join(
        calibration["observability"]["unidentifiable"]
    )
    assert observed["Source run"] == "1"
    assert observed["Poses (each fitted by its mean)"] == "30" and observed["Cycles per pose"] == "2"
    # the instrument's stated figure and the robot's measured scatter, apart
    assert observed["Instrument standard uncertainty (mm per axis, stated)"] == "0.05"
    scatter = calibration["campaign"]["scatter_mm"]
    assert observed["Robot scatter of one reading (mm per axis, measured)"].startswith(
        " / ".join(fmt_mm(v) for v in scatter)
    )
    assert observed["Reduced chi^2 of the fit"] == (
        f"{calibration['reduced_chi2']:.2f} over {calibration['degrees_of_freedom']:.1f} degrees of freedom"
    )
    html = validated["html"].read_text(encoding="utf-8")
    assert sorted(identified) == sorted(PARAMETERS + ("reg_x_mm", "reg_y_mm", "reg_z_mm"))
    assert (
        "Held at their documented values (not identifiable from this pose set and instrument, or not freed): "
        "none." in html
    )


def test_the_page_is_in_the_pdf_and_its_order_does_not_depend_on_which_run_is_named_first(validated):
    before, after, store, folder = validated["before"], validated["after"], validated["store"], validated["folder"]
    pdf = pdf_text(validated["html"].with_suffix(".pdf"))
    gain = validated["tables"]["calibration-gain"][1]
    assert "5. Kinematic calibration: before and after" in pdf
    assert f"mean AP_P goes from {gain[1]} mm to {gain[2]} mm: {gain[3]} times smaller" in pdf
    assert (
        main(
            [
                "report",
                str(before),
                "--compare",
                str(after),
                "--store",
                str(store),
                "--out",
                str(folder / "swapped"),
                "--quiet",
                "--format",
                "html",
            ]
        )
        == 0
    )
    swapped = html_tables(folder / "swapped" / f"compare_run{before}_run{after}.html")
    assert swapped["calibration-gain"] == validated["tables"]["calibration-gain"]


def test_runs_with_the_same_calibration_get_no_page_and_the_figure_is_readable(validated):
    with Store(validated["store"], read_only=True) as store:
        before, after = collect(store, validated["before"]), collect(store, validated["after"])
        assert calibration_comparison(store, after, after) is None
        assert calibration_comparison(store, before, before) is None
        pair = calibration_comparison(store, after, before)
    assert (pair.before.run.id, pair.after.run.id) == (validated["before"], validated["after"])
    assert pair.before_calibration is None and pair.after_calibration.id == validated["calibration"]["id"]
    plot = error_vectors(pair)
    assert min(printed_font_sizes(plot)) >= MIN_FONT_PT
    assert f"before (run {validated['before']}, no kinematic calibration)" in plot.caption


def test_a_map_fit_stored_before_its_degrees_of_freedom_keeps_its_chi2_per_coordinate_label():
    # the first MAP calibrations (2026-12-03) stored chi^2 per coordinate under reduced_chi2, without
    # degrees_of_freedom: their report must not call that a reduced chi^2
    from types import SimpleNamespace

    from bench.reports.calibration import _fit_rows

    params = {
        "fit": "map",
        "prior": {"name": "tolerances"},
        "prior_only": [],
        "reduced_chi2": 0.55,
        "observability": {"condition_number": 5e12, "singular_values": [1.0, 2e-13], "n_poses": 90},
    }
    old = dict(_fit_rows(SimpleNamespace(params=params, source_run_id=1, created_utc="2026-12-03T08:00:00")))
    assert old["Chi^2 per coordinate of the fit"] == "0.55" and "Reduced chi^2 of the fit" not in old
    new = dict(
        _fit_rows(
            SimpleNamespace(
                params={**params, "reduced_chi2": 0.74, "degrees_of_freedom": 66.75},
                source_run_id=1,
                created_utc="2026-12-03T09:00:00",
            )
        )
    )
    assert new["Reduced chi^2 of the fit"] == "0.74 over 66.8 degrees of freedom"
    free_set = dict(
        _fit_rows(
            SimpleNamespace(
                params={**params, "fit": "free-set", "reduced_chi2": 1.2, "degrees_of_freedom": 67.0},
                source_run_id=1,
                created_utc="2026-12-03T09:00:00",
            )
        )
    )
    assert free_set["Reduced chi^2 of the fit"] == "1.20"
