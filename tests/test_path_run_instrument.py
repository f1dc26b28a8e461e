"""U(AT_p) of a path run read by a relative counts instrument (the mice) carries the instrument as a pose report's
U(AP) does: the reading, the scale of the calibration in force at the largest distance the attained paths reach
from the registration, and the registration at home measured in the run (issue 32: "every U names its budget",
"the instrument's uncertainty comes from the station file or the calibration in force, never a silent 0").

Before, the path analysis took the reading's u alone (the calibration's scale at 0 mm, no registration): on a mice
station with the nominal cpi (±4 %) it stated U(AT_p) from 0.013 mm of instrument where ~0.9 mm applies.
"""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main
from bench.metrology.mouse_calibration import MM_PER_INCH
from bench.reports.document import _instruments
from bench.reports.path import collect_path
from bench.reports.path_run import analyze_path_run, attained_cycles
from bench.store import Store
from bench.store.record_checksum import seal_run

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "examples" / "iso9283_path_quick.toml"
#: What a mice station stores with its run (bench.rigs.mice, bench.rigs.registration): the nominal 800 cpi in
#: force and one registration at home with its u measured from the returns.
NOMINAL = {"nominal": True, "version": 1, "x_mm_per_count": 0.03175, "y_mm_per_count": 0.03175}
REGISTRATION_U_MM = 0.3817


@pytest.fixture(scope="module")
def mice_path_run(tmp_path_factory) -> Path:
    """A simulated iso9283_path_quick run whose stored instrument settings are those of a mice station."""
    store = tmp_path_factory.mktemp("path") / "bench.db"
    assert main(["run", str(QUICK), "--sim", "--store", str(store), "--no-progress"]) == 0
    db = sqlite3.connect(store)
    try:
        settings = json.loads(db.execute("SELECT settings_json FROM runs WHERE id = 1").fetchone()[0])
        settings["instrument"]["scale_calibration"] = NOMINAL
        settings["registrations"] = [{"segment": 1, "u_mm": REGISTRATION_U_MM, "utc": "2026-01-01T00:00:00+00:00"}]
        db.execute("UPDATE runs SET settings_json = ? WHERE id = 1", (json.dumps(settings),))
        seal_run(db, 1)  # an edit by hand, sealed as bench seals its own
        db.commit()
    finally:
        db.close()
    return store


def _expected_u_mm(store: Path) -> float:
    """The AT_p instrument term computed here from the stored settings and samples (GUM root sum of squares)."""
    with Store(store, read_only=True) as opened:
        run = opened.run(1)
        points = np.concatenate(
            [p for cycles in attained_cycles(opened.samples(1, kind="path")).values() for _, _, p, _ in cycles]
        )
    instrument = run.settings["instrument"]
    step_mm = MM_PER_INCH / instrument["cpi"]
    span_mm = float(np.max(np.abs(points - np.asarray(instrument["registration_mm"]))))
    assert span_mm > 10.0  # the path reaches tens of mm from home: the scale term dominates
    terms = (step_mm / math.sqrt(6.0), instrument["noise_counts"] * step_mm, 0.04 / math.sqrt(3.0) * span_mm)
    return math.sqrt(sum(t * t for t in terms) + REGISTRATION_U_MM**2)


def test_at_u_carries_the_calibration_scale_and_the_registration(mice_path_run):
    expected = _expected_u_mm(mice_path_run)
    with Store(mice_path_run, read_only=True) as opened:
        analysis = analyze_path_run(opened, 1)
        report = collect_path(opened, 1)
    stated = float(analysis.budget.split("u = ")[1].split(" mm")[0])
    assert stated == pytest.approx(expected, rel=1e-5)
    # the report's budget table names every term U(AT_p) carries, and their sum is the stated u
    (budget,) = [b for b in _instruments(report).blocks if getattr(b, "ident", "") == "budget"]
    rows = {row[0]: row[1] for row in budget.rows}
    assert "calibration scale" in rows
    assert float(rows["registration at home (the run's largest)"]) == pytest.approx(REGISTRATION_U_MM, abs=0.005)
    assert float(rows["accuracy term (AP, AT_p), per axis"]) == pytest.approx(expected, abs=0.005)


def test_av_u_carries_the_calibration_scale_in_force(mice_path_run):
    """A speed read by the mice is off by their scale error: U(AV) carries the calibration's relative u (the nominal
    cpi's ±4 % rectangular: 4/√3 = 2.31 %) and says so, where it said "excludes the instrument: none declared"."""
    scale_u_pct = 4.0 / math.sqrt(3.0)
    with Store(mice_path_run, read_only=True) as opened:
        analysis = analyze_path_run(opened, 1)
    assert analysis.speed_budget.startswith("U(AV) includes the instrument: u = ")
    assert float(analysis.speed_budget.split("u = ")[1].split(" %")[0]) == pytest.approx(scale_u_pct, rel=1e-4)
    (line,) = [f for f in analysis.figures if f.shape == "line"]
    assert line.av_u.expanded_uncertainty / line.av_u.coverage_factor >= scale_u_pct


def test_the_span_from_the_registration_compares_each_axis_with_its_own_coordinate():
    """A table without x (y and z only) is compared with the registration's y and z, not its x and y: the reach
    is 4 mm here (the shared span helper, as first written, compared y with x: 104 mm)."""
    from types import SimpleNamespace

    import pandas as pd

    from bench.reports.instrument import _span_from_registration

    run = SimpleNamespace(settings={"instrument": {"registration_mm": [100.0, 0.0, 50.0]}})
    assert _span_from_registration(run, pd.DataFrame({"y_mm": [3.0, -4.0], "z_mm": [52.0, 49.0]})) == 4.0
    assert _span_from_registration(run, pd.DataFrame({"x_mm": [90.0], "y_mm": [3.0], "z_mm": [52.0]})) == 10.0
