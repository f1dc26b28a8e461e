"""Report of a delta_positioning run (laser-grid partial readings).

Independent paths: the stored samples read back with ``Store.samples`` and reduced by hand (numpy) or with the
metrology API on arrays built from them; ``bench analyze grid-positioning`` on the raw-data CSV the report writes and
on ``bench export``'s; the HTML (parsed) and the PDF (pypdf). One short simulated run (delta4 simulator with its
laser grid, seed 4: P2 blind on both screens) and one written run with complete readings.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from reports_runs import (
    GRID_POSITIONING_SETTINGS,
    GRID_READINGS,
    cli_json,
    html_tables,
    pdf_text,
    simulated_run,
    write_grid_positioning_run,
)

from bench.cli import main
from bench.errors import ConfigError, InsufficientData
from bench.metrology import detection_rate, partial_pose_statistics, pose_accuracy, pose_repeatability
from bench.protocols import PROTOCOLS
from bench.reports import GridPositioningReport, collect, write_comparison, write_report
from bench.store import Store

AXES = ("x_mm", "y_mm", "z_mm")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """(store, run id, report, paths, folder) of a 2-cycle delta_positioning run on the simulator."""
    folder = tmp_path_factory.mktemp("positioning")
    store = Store(folder / "bench.db")
    run_id = simulated_run(
        store, PROTOCOLS["delta_positioning"](settle_s=0.1, cycles=2), "delta4", seed=4, speed_factor=20000
    )
    yield store, run_id, collect(store, run_id), write_report(store, run_id, folder / "out"), folder
    store.close()


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("positioning-written")
    store = Store(folder / "bench.db")
    run_id = write_grid_positioning_run(store)
    yield store, run_id, collect(store, run_id), write_report(store, run_id, folder / "out")
    store.close()


def _stored(store, run_id):
    """{pose: (command (3,), readings (n, 3) with NaN where the sample stored no axis, samples)}."""
    out = {}
    for sample in store.samples(run_id, kind="pose"):
        command, rows, samples = out.setdefault(
            sample.pose, (np.array([sample.values[f"cmd_{a}"] for a in AXES]), [], [])
        )
        rows.append([sample.values.get(a, np.nan) for a in AXES])
        samples.append(sample)
    return {pose: (command, np.array(rows), samples) for pose, (command, rows, samples) in out.items()}


def _same(ours, theirs):
    """A report figure against the CLI's JSON: None is null, numbers equal to rounding."""
    if ours is None:
        assert theirs is None
    else:
        assert theirs == pytest.approx(ours, rel=1e-12, abs=1e-12)


def _check_against_cli(report, cli):
    assert cli["k"] == report.coverage_factor
    for p in report.poses:
        figures = cli["poses"][p.pose]
        assert figures["n"] == p.statistics.n_readings and figures["commanded_mm"] == list(p.commanded_mm)
        for screen in ("horizontal", "vertical"):
            for kind in ("valid", "lit"):
                ours, theirs = getattr(p, kind)[screen], figures["screens"][screen][kind]
                assert (theirs["k"], theirs["n"]) == (ours.k, ours.n)
                for value, their in zip((ours.rate, ours.low, ours.high), (theirs["rate"], *theirs["wilson"])):
                    _same(value, their)
        for name, axis in zip("xyz", p.statistics.axes):
            theirs = figures["axes"][name]
            assert theirs["n"] == axis.n
            for ours, key in (
                (axis.ap_mm, "AP_mm"),
                (axis.spread_3s_mm, "spread_3s_mm"),
                (axis.max_abs_error_mm, "max_abs_error_mm"),
                (axis.mean_abs_error_mm, "mean_abs_error_mm"),
            ):
                _same(ours, theirs[key])
        assert figures["n_complete"] == p.statistics.n_complete
        _same(p.statistics.ap_mm, figures["AP_mm"])
        _same(p.statistics.rp_mm, figures["RP_mm"])
    for name, axis in zip("xyz", report.pooled):
        assert cli["all_poses"]["axes"][name]["n"] == axis.n
        _same(axis.ap_mm, cli["all_poses"]["axes"][name]["AP_mm"])


def test_simulated_figures_equal_the_metrology_api_on_the_stored_samples(simulated):
    store, run_id, report, _, _ = simulated
    assert isinstance(report, GridPositioningReport) and [p.pose for p in report.poses] == ["P1", "P2", "P3"]
    for p in report.poses:
        command, readings, samples = _stored(store, run_id)[p.pose]
        assert p.statistics == partial_pose_statistics(readings, command)
        for screen in ("horizontal", "vertical"):
            assert p.valid[screen] == detection_rate([s.values[f"{screen}_valid"] for s in samples])
            assert p.lit[screen] == detection_rate([s.values[f"{screen}_hits"] > 0 for s in samples])
            # the screen is valid exactly when the raw decoding says ok and the screens agree (never invented)
            assert p.valid[screen].k == sum(
                s.raw["status"][screen] == "ok" and not s.raw["screens_disagree"] for s in samples
            )
        for k, axis in enumerate(p.statistics.axes):  # by hand: mean error over the readings that measured it
            present = readings[~np.isnan(readings[:, k]), k]
            assert axis.n == len(present)
            if len(present):
                assert axis.ap_mm == pytest.approx(present.mean() - command[k], abs=1e-12)
    assert report.poses[1].valid["horizontal"].k == report.poses[1].valid["vertical"].k == 0  # P2 blind (seed 4)


def test_simulated_report_equals_bench_analyze_on_its_raw_data_and_on_the_export(simulated, capsys, tmp_path):
    store, run_id, report, paths, folder = simulated
    _check_against_cli(report, cli_json(capsys, "analyze", "grid-positioning", str(paths.csv[0]), "--json"))
    exported = tmp_path / "run.csv"
    assert (
        main(["export", str(run_id), "--kind", "pose", "--store", str(folder / "bench.db"), "--out", str(exported)])
        == 0
    )
    _check_against_cli(report, cli_json(capsys, "analyze", "grid-positioning", str(exported), "--json"))
    html = paths.html.read_text(encoding="utf-8")
    assert hashlib.sha256(paths.csv[0].read_bytes()).hexdigest() in html
    assert (
        f"bench export {run_id} --kind pose --store bench.db --out run{run_id}.csv, then bench "
        f"analyze grid-positioning run{run_id}.csv --k 2 --json" in html
    )
    assert int(html_tables(paths.html)["rawdata"][1][2]) == len(store.samples(run_id)) == len(report.table)


def test_an_axis_never_measured_is_printed_as_no_reading_not_zero(simulated):
    store, run_id, report, paths, _ = simulated
    never = {
        (pose, a[0])
        for pose, (_, readings, _) in _stored(store, run_id).items()
        for k, a in enumerate(AXES)
        if np.isnan(readings[:, k]).all()
    }
    assert ("P2", "x") in never and ("P2", "z") in never
    rows = {(row[0], row[1]): row for row in html_tables(paths.html)["grid-axes"][1:]}
    assert len(rows) == 9
    for key, row in rows.items():
        if key in never:
            assert row[3:] == ["no reading", "—", "—", "—", "—"]
        else:
            assert row[3].isdigit() and int(row[3]) > 0
    pdf = pdf_text(paths.pdf)
    assert pdf.count("no reading") >= len(never) and "P2 x -70 no reading" in pdf
    assert any("P2: x, y, z were never measured in 2 readings" in note for note in report.notes)


def test_written_run_spatial_figures_come_from_the_complete_readings_only(written):
    store, run_id, report, paths = written
    p1, p2, p3 = report.poses
    command = np.array([0.0, 0.0, -200.0])
    complete = np.array([r for r in GRID_READINGS["P1"] if None not in r], dtype=float)
    assert p1.statistics.n_complete == 3 and p2.statistics.n_complete == p3.statistics.n_complete == 0
    assert p1.statistics.ap_mm == pytest.approx(pose_accuracy(complete, command).ap_mm, abs=1e-12)
    assert p1.statistics.rp_mm == pytest.approx(pose_repeatability(complete).rp_mm, abs=1e-12)
    # by hand: barycentre of the three complete readings, and l̄ + 3 S_l around it
    centre = complete.mean(axis=0)
    distances = np.linalg.norm(complete - centre, axis=1)
    assert p1.statistics.ap_mm == pytest.approx(np.linalg.norm(centre - command), abs=1e-12)
    assert p1.statistics.rp_mm == pytest.approx(distances.mean() + 3 * distances.std(ddof=1), abs=1e-12)
    x1 = np.array([r[0] for r in GRID_READINGS["P1"]])  # x of all four readings, incomplete one included
    assert p1.statistics.axes[0].n == 4 and p1.statistics.axes[0].ap_mm == pytest.approx(x1.mean())
    tables = html_tables(paths.html)
    spatial = {row[0]: row for row in tables["grid-spatial"][1:]}
    # the grid reads a 2.5 mm lattice: one decimal, never more than the readings carry (not 0.0000)
    assert spatial["P1"] == ["P1", "3 / 4", f"{p1.statistics.ap_mm:.1f}", f"{p1.statistics.rp_mm:.1f}"]
    assert spatial["P2"][2:] == ["— (no complete reading)", "— (fewer than 2 complete readings)"]
    axes = {(row[0], row[1]): row for row in tables["grid-axes"][1:]}
    assert axes[("P2", "x")][3] == "no reading" and axes[("P2", "z")][3:5] == ["3", f"{-2.5 / 3:+.1f}"]
    assert all(axes[("P3", a)][3] == "no reading" for a in "xyz")
    screens = {row[0]: row for row in tables["grid-screens"][1:]}
    rate = p1.valid["vertical"]  # 3 of 4: Wilson at z = 2 by its closed form
    centre_w, half_w = (0.75 + 4 / 8) / 2, math.sqrt(0.75 * 0.25 / 4 + 4 / 64) * 2 / 2
    assert (rate.low, rate.high) == pytest.approx((centre_w - half_w, centre_w + half_w), abs=1e-12)
    assert screens["P1"][5] == f"3 / 4, 75.00 % [{100 * rate.low:.1f}, {100 * rate.high:.1f}]"
    pdf = pdf_text(paths.pdf)
    for text in (
        screens["P1"][5],
        f"{p1.statistics.rp_mm:.1f}",
        "Deviations from thesis §8.4.2 / ISO 9283",
        "Reading the figures: they are conditional on detection",
    ):
        assert text in pdf, text


def test_deviations_name_partial_readings_detection_and_the_screen_placement(written, simulated):
    rows = {d.topic: d for d in written[2].deviations}
    assert rows["thesis poses"].status == "conforms" and rows["readings"].status == "deviates"  # 4, not 15
    assert rows["poses"].status == "deviates"  # not the ISO cube
    assert rows["partial readings"].done.endswith("x in 4, y in 7, z in 6 of 12 readings")
    assert rows["detection"].status == "deviates" and "conditional on detection" in rows["detection"].effect
    assert rows["spatial AP/RP"].done.endswith("P1 3/4, P2 0/4, P3 0/4")
    assert rows["screen placement"].status == "conforms"  # a measured placement is stored
    assert rows["settling"].status == "conforms" and rows["velocity"].status == "deviates"
    simulated_rows = {d.topic: d for d in simulated[2].deviations}
    placement = simulated_rows["screen placement"]  # the simulator's grid uses the GUI drawing
    assert placement.status == "deviates" and "lasergrid-gui-default (the legacy GUI drawing" in placement.done
    assert "r = 1 mm" in simulated_rows["instrument"].done


def test_a_run_without_instrument_settings_is_refused_unless_allowed(tmp_path):
    with Store(tmp_path / "b.db") as store:
        run_id = write_grid_positioning_run(store, settings={"robot": GRID_POSITIONING_SETTINGS["robot"]})
        with pytest.raises(InsufficientData, match="clause thesis §8.4.2 instrument: not stored: settings.instrument"):
            collect(store, run_id)
        report = collect(store, run_id, allow_unknown=True)
        assert report.instrument.sigma_mm is None and report.poses[0].statistics.n_complete == 3


def test_options_of_other_layouts_are_refused(written, capsys, tmp_path):
    store, run_id, _, _ = written
    assert main(["report", str(run_id), "--store", store.path, "--out", str(tmp_path), "--format", "html"]) == 0
    assert capsys.readouterr().out.split() == [
        str(tmp_path / f"report_run{run_id}.html"),
        str(tmp_path / f"run{run_id}_samples.csv"),
    ]
    with pytest.raises(
        ConfigError,
        match=f"--band-mm: applies to iso9283_stabilisation, iso9283_positioning_time "
        f"runs; run {run_id} is a delta_positioning run",
    ):
        collect(store, run_id, bands_mm=[0.1])
    compared = write_comparison(store, run_id, run_id, tmp_path, formats=("html",))  # every layout compares
    assert "Results of B" in compared.html.read_text(encoding="utf-8")
    assert main(["report", str(run_id), "--store", store.path, "--out", str(tmp_path), "--hysteresis-mm", "0.1"]) == 2
    err = capsys.readouterr().err
    assert "--hysteresis-mm: applies to iso9283_stabilisation, iso9283_positioning_time runs" in err


def test_k_is_the_z_of_every_wilson_interval_in_the_report_and_the_cli(written, capsys, tmp_path):
    store, run_id, _, _ = written
    report = collect(store, run_id, k=3.0)
    samples = [s for s in store.samples(run_id, kind="pose") if s.pose == "P1"]
    rate = report.poses[0].valid["vertical"]  # 3 of 4: Wilson at z = 3 by its closed form
    centre, half = (0.75 + 9 / 8) / (1 + 9 / 4), 3 * math.sqrt(0.75 * 0.25 / 4 + 9 / 64) / (1 + 9 / 4)
    assert (rate.k, rate.n) == (3, 4) and (rate.low, rate.high) == pytest.approx((centre - half, centre + half))
    assert rate == detection_rate([s.values["vertical_valid"] for s in samples], k=3.0)
    paths = write_report(store, run_id, tmp_path, ("html",), k=3.0)
    html = paths.html.read_text(encoding="utf-8")
    assert "Wilson score interval, z = 3" in html and f"grid-positioning run{run_id}.csv --k 3 --json" in html
    _check_against_cli(report, cli_json(capsys, "analyze", "grid-positioning", str(paths.csv[0]), "--k", "3", "--json"))
