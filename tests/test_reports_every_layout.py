"""Every layout, one truth: each report layout (pose, distance, path, stabilisation, actuator, payload ladder, laser grid
(hits and positioning), mouse calibration, kinematic calibration, comparison) is written as HTML and PDF, and

- every number of every table is walked: a ``value ± U`` has U to at most two significant digits and the value to
  U's decimal place (GUM 7.2.6); a number without a U of its own carries no more than 1 µm's decimals (3), unless
  it is a setting printed as the run stored it (it appears as such in the settings appendix), an exact constant
  (g, one mouse count, one motor step) or an uncertainty (a budget line, a ``u =``) to two significant digits;
- every cell of every HTML table is in the PDF's text (one content model, two renderers), and so is each verdict.

The rounding rule is checked independently of bench's formatter (decimal strings and regular expressions), so a
layout that prints ``0.031759 ± 1.3e-03`` or ``0.3507 mm`` fails here.
"""

from __future__ import annotations

import re

import pytest
from calibrated_pkm5 import calibrated_runs
from reports_runs import (
    html_tables,
    pdf_text,
    pose_config,
    simulated_run,
    write_actuator_run,
    write_grid_hit_run,
    write_grid_positioning_run,
    write_ladder_run,
    write_pose_run,
)

from bench.launch import simulated_rig_in
from bench.metrology import STANDARD_GRAVITY_M_S2
from bench.protocols import Runner
from bench.protocols.base import PROTOCOLS
from bench.reports import write_comparison, write_report
from bench.store import Store

#: value ± U as printed: sign, digits, decimals (no exponent: an exponent is itself a failure, caught below)
MEASURED = re.compile(r"([+-]?\d+(?:\.(\d+))?) ± (\d+(?:\.(\d+))?)(e[+-]?\d+)?")
#: a number with decimals that is not part of a date, a time, a version or a hash
DECIMAL = re.compile(r"(?<![\w.:-])[+-]?\d+\.(\d+)(e[+-]?\d+)?(?![\w.:])")
#: tables of stated facts, not statistics: identification, settings as stored, calibrations, run history
FACT_TABLES = {"identification", "summary-identity", "settings", "calibrations", "history", "registrations"}
#: tables of dimensionless diagnostics (condition number, O1 index, singular values): up to three significant
#: digits, an exponent allowed
DIAGNOSTIC_TABLES = {"calibration-observability"}
#: exact constants a report prints as they are: standard gravity, one count of the simulated 800 cpi mice
#: (25.4/800 mm), the pkm5's leg travel per motor step (1.25 mm lead over 200 or 400 steps: 000 Eq. 8.1)
EXACT = {f"{STANDARD_GRAVITY_M_S2:g}", f"{25.4 / 800:g}", f"{1.25 / 200:g}", f"{1.25 / 400:g}"}
LAYOUTS = (
    "pose",
    "distance",
    "path",
    "stabilisation",
    "actuator",
    "payload",
    "grid_hits",
    "grid",
    "mouse",
    "calibration",
    "comparison",
)


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """{layout: ReportPaths} of one report of each layout."""
    folder = tmp_path_factory.mktemp("every_layout")
    out = folder / "out"
    paths = {}
    with Store(folder / "bench.db") as store:
        pose = write_pose_run(store, seed=5, bias_mm=(0.3, -0.2, 0.1), noise_mm=0.04, config=pose_config())
        other = write_pose_run(store, seed=6, bias_mm=(0.2, -0.1, 0.1), noise_mm=0.04, config=pose_config())
        path = PROTOCOLS["iso9283_path"](shape="both", cycles=2, velocities_pct=[100.0], final_hold_s=0.2)
        stabilisation = PROTOCOLS["iso9283_stabilisation"](cycles=2, lead_s=1.0, hold_s=3.0)
        runs = {
            "path": simulated_run(store, path, "pkm5", seed=6, speed_factor=10000),
            "stabilisation": simulated_run(store, stabilisation, "pkm5", seed=0, speed_factor=1000),
            "actuator": write_actuator_run(store),
            "payload": write_ladder_run(store),
            "distance": write_pose_run(store, seed=7, config=pose_config(protocol="iso9283_distance", cycles=6)),
            "grid_hits": write_grid_hit_run(store),
            "grid": write_grid_positioning_run(store),
        }
        rig = simulated_rig_in(store, "pkm5", seed=2, speed_factor=20000)
        mouse = PROTOCOLS["mouse_calibration"](
            reference="calibrated-axis", reference_u_pct=0.05, settle_s=0.1, repeats=2, distances_mm=[5, 20, 40]
        )
        try:
            runs["mouse"] = Runner(rig, store).run(mouse).run_id
        finally:
            rig.close()
        paths["pose"] = write_report(store, pose, out, criteria={"AP_mm": 0.4, "RP_mm": 0.2}, decision_rule="guarded")
        stated = {"actuator": {"accuracy_mm": 0.06}, "path": {"AT_mm": 1.0, "RT_mm": 0.5}}  # a verdict each
        for layout, run_id in runs.items():
            paths[layout] = write_report(store, run_id, out, criteria=stated.get(layout), decision_rule="guarded")
        paths["comparison"] = write_comparison(store, pose, other, out)
    calibrated = calibrated_runs(tmp_path_factory)
    paths["calibration"] = write_comparison(calibrated.store, calibrated.compensated, calibrated.nominal, out)
    return paths


def _two_significant_digits(u_text: str) -> bool:
    digits = u_text.replace(".", "").lstrip("0")
    if "." not in u_text:  # a U of whole tens, hundreds (210): its trailing zeros only place the digits
        digits = digits.rstrip("0") or "0"
    return 1 <= len(digits) <= 2


def _rounded_to_the_place_of(value: str, u_text: str) -> bool:
    """A value beside a U of whole tens, hundreds (``10 ± 210``: U's two significant digits end at the tens) is
    rounded to that place (never ``12 ± 210``; ``-9 ± 40`` is right: 40 to two significant digits ends at units)."""
    if "." in u_text or "." in value:
        return True
    zeros = max(0, len(u_text.lstrip("0")) - 2)
    digits = value.lstrip("+-")
    return digits == "0" or len(digits) - len(digits.rstrip("0")) >= zeros


def _stated(tables) -> set[str]:
    """Every number the settings appendix prints as the run stored it."""
    return {m.group(0).lstrip("+") for row in tables.get("settings", [])[1:] for m in DECIMAL.finditer(row[-1])}


def _significant_digits(number: str) -> int:
    return len(number.split("e")[0].replace(".", "").lstrip("0").rstrip("0") or "0")


def _cells(header, row):
    """The cells of ``row``, a value and its uncertainty in two columns (header "... uncertainty") joined as one
    ``value ± u`` cell."""
    cells = list(row)
    for j in range(len(header) - 1, 0, -1):
        if "uncertainty" in header[j].lower() and j < len(cells):
            cells[j - 1 : j + 1] = [f"{cells[j - 1]} ± {cells[j]}"]
    return cells


def _misrounded(tables) -> list[str]:
    stated = _stated(tables) | EXACT
    wrong = []
    for ident, rows in tables.items():
        if ident in FACT_TABLES:
            continue
        for row in rows[1:]:
            for cell in _cells(rows[0], row):
                for value, decimals, u, u_decimals, exponent in MEASURED.findall(cell):
                    if (
                        exponent
                        or len(decimals) != len(u_decimals)
                        or not _two_significant_digits(u)
                        or not _rounded_to_the_place_of(value, u)
                    ):
                        wrong.append(f"{ident}: {cell}")
                for match in DECIMAL.finditer(MEASURED.sub("", cell)):
                    number, decimals, exponent = match.group(0).lstrip("+-"), match.group(1), match.group(2)
                    is_uncertainty = ident == "budget" or "u = " in cell
                    if ident in DIAGNOSTIC_TABLES and _significant_digits(match.group(0)) <= 3:
                        continue
                    if exponent or (
                        len(decimals) > 3
                        and number not in stated
                        and not (is_uncertainty and _two_significant_digits(number))
                    ):
                        wrong.append(f"{ident}: {cell}")
    return wrong


@pytest.mark.parametrize("layout", LAYOUTS)
def test_every_number_of_the_layout_is_rounded_by_its_u(reports, layout):
    tables = html_tables(reports[layout].html)
    assert len(tables) >= 3
    assert _misrounded(tables) == []


def test_the_walk_finds_false_precision():
    """The check itself can fail: the figures issue 36 found (a mouse scale, an overshoot, a slope in e-notation)."""
    tables = {
        "mouse-matrix": [["A"], ["+0.031759 ± 1.3e-03"]],
        "stabilisation": [["OV"], ["0.3507"]],
        "legs": [["slope"], ["-1.93e-03 ± 8.22e-05"]],
        "results": [["AP"], ["0.4405 ± 0.2343"]],
        "path": [["AT", "RV"], ["0.12 ± 0.05", "10 ± 210"]],  # rounded to tens by a U of 210: right
        "path-tens": [["RV"], ["12 ± 210"]],
        "path-three-digits": [["RV"], ["10 ± 205"]],
        "mouse-intercepts": [["b"], ["-9 ± 40"]],  # right: U of 40 at two significant digits, the value to units
        "calibration-parameters": [["Parameter", "Value", "Standard uncertainty"], ["a", "+0.00471", "0.00044"]],
        "calibration-observability": [["Item", "Value"], ["O1 index", "0.03893"], ["condition", "7.07e+10"]],
        "settings": [["Setting", "Value"], ["instrument.resolution_mm", "0.03175"]],
        "conditions": [["h"], ["0.03175 (one instrument count)"]],
    }
    assert [w.split(":")[0] for w in _misrounded(tables)] == [
        "mouse-matrix",
        "stabilisation",
        "legs",
        "results",
        "path-tens",
        "path-three-digits",
        "calibration-observability",
    ]


@pytest.mark.parametrize("layout", LAYOUTS)
def test_html_and_pdf_state_the_same_figures_and_verdicts(reports, layout):
    paths = reports[layout]
    tables = html_tables(paths.html)
    pdf = pdf_text(paths.pdf)
    squashed = pdf.replace(" ", "")
    missing = [
        f"{ident}: {cell}"
        for ident, rows in tables.items()
        for row in rows
        for cell in row
        if cell and cell.replace(" ", "") not in squashed  # table cells may wrap in the PDF: compared without spaces
    ]
    assert missing == []
    assert paths.report_id in pdf


@pytest.mark.parametrize("layout", LAYOUTS)
def test_page_one_of_every_layout_is_signable(reports, layout):
    """Page 1 (the summary, before section 1) names customer, order, device, measuring point, operator, laboratory,
    date and report number, states a verdict under its rule or why there is none, and ends with a signature block
    tall enough to sign (14 mm rows); the SIMULATED banner when simulated; no template placeholder printed."""
    paths = reports[layout]
    page = paths.html.read_text(encoding="utf-8")
    summary = page[page.index("<h2>Summary</h2>") : page.index("<h2>1. Identification</h2>")]
    tables = html_tables(paths.html)
    items = [row[0] for row in tables["summary-identity"][1:]]
    assert items[:6] == [
        "Customer",
        "Order",
        "Device under test (serial / asset)",
        "Measuring point (TCP / reference point)",
        "Operator",
        "Laboratory",
    ]
    assert any(i.startswith("Test date") for i in items) and ["Report", paths.report_id] in tables["summary-identity"]
    assert tables["summary-identity"][4][1]  # the measuring point is always stated (ISO 9283 6.3)
    assert 'id="verdict"' in summary or "Decision: " in summary or "Decision rule: " in summary
    assert [row[0] for row in tables["signature"]] == ["Role", "Tested by", "Approved by"]
    assert summary.count('style="height: 14.0mm"') == 2 and summary.rindex("<table") == summary.index(
        '<table id="signature"'
    )
    for placeholder in ("Operator name", "not recorded", "TBD", "&lt;customer&gt;"):
        assert placeholder not in summary
    # the runs written by hand (reports_runs) name no simulator; the others ran on one
    assert ("SIMULATED DATA" in page) == (layout not in ("actuator", "grid_hits", "grid"))
