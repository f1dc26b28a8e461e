"""Report numbers equal the metrology API's on the same data (bench.reports.content, raw-data CSV, HTML, PDF).

Independent paths: the stored samples read back with ``Store.samples`` and reduced with numpy by hand; the
analysis API (``bench.metrology.tables.analyze_poses``) on the raw-data CSV the report writes; the CLI
``bench analyze iso9283`` on that CSV.
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest
from reports_runs import CUBE, pose_config, rounded_by_u, write_pose_run

from bench.cli import main
from bench.errors import ConfigError, InsufficientData
from bench.metrology import instrument_rp_floor, payload_shift
from bench.metrology.tables import (
    analyze_distance,
    analyze_poses,
    pose_table,
    read_table_csv,
)
from bench.reports import collect, write_report
from bench.store import Store


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    folder = tmp_path_factory.mktemp("reports")
    store = Store(folder / "bench.db")
    run_id = write_pose_run(store, seed=4, bias_mm=(0.3, -0.2, 0.1), noise_mm=0.04)
    paths = write_report(store, run_id, folder / "out")
    report = collect(store, run_id)
    yield store, run_id, report, paths
    store.close()


def _points(store, run_id, pose):
    samples = [s for s in store.samples(run_id) if s.pose == pose]
    attained = np.array([[s.values[k] for k in ("x_mm", "y_mm", "z_mm")] for s in samples])
    command = np.array([samples[0].values[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
    return attained, command


def test_ap_rp_equal_a_hand_computation_from_the_stored_samples(stored):
    store, run_id, report, _ = stored
    assert [r.pose for r in report.poses] == ["P1", "P2", "P3", "P4", "P5"]  # natural order, not cycle order
    for result in report.poses:
        attained, command = _points(store, run_id, result.pose)
        barycentre = attained.mean(axis=0)
        distances = np.linalg.norm(attained - barycentre, axis=1)
        assert result.accuracy.ap_mm == pytest.approx(np.linalg.norm(barycentre - command), abs=1e-12)
        assert result.accuracy.ap_axes_mm == pytest.approx(tuple(barycentre - command), abs=1e-12)
        assert result.repeatability.rp_mm == pytest.approx(distances.mean() + 3 * distances.std(ddof=1), abs=1e-12)
        assert result.accuracy.n == 10
        # the injected bias is recovered within the noise (0.04 mm / sqrt(10) per axis)
        assert result.accuracy.ap_axes_mm == pytest.approx((0.3, -0.2, 0.1), abs=0.05)


def test_report_numbers_equal_the_analysis_api_on_the_raw_data_csv(stored):
    _, _, report, paths = stored
    table = pose_table(read_table_csv(paths.csv[0]))
    api = analyze_poses(table, instrument_u_mm=report.instrument.sigma_mm)
    assert [r.label for r in api] == ["P1", "P5", "P4", "P3", "P2"]  # the API keeps the cycle order
    api = sorted(api, key=lambda r: r.label)
    for ours, theirs in zip(report.poses, api):
        assert ours.accuracy.ap_mm == pytest.approx(theirs.accuracy.ap_mm, rel=1e-12)
        assert ours.repeatability.rp_mm == pytest.approx(theirs.repeatability.rp_mm, rel=1e-12)
        assert ours.ap_u.expanded_uncertainty == pytest.approx(theirs.ap_u.expanded_uncertainty, rel=1e-12)
        assert ours.rp_u.expanded_uncertainty == pytest.approx(theirs.rp_u.expanded_uncertainty, rel=1e-9)


def test_cli_analyze_on_the_raw_data_reproduces_the_report(stored, capsys):
    _, _, report, paths = stored
    code = main(
        ["analyze", "iso9283", str(paths.csv[0]), "--instrument-u-mm", f"{report.instrument.sigma_mm!r}", "--json"]
    )
    assert code == 0
    poses = json.loads(capsys.readouterr().out)["poses"]
    for result in report.poses:
        assert poses[result.label]["AP_mm"] == pytest.approx(result.accuracy.ap_mm, rel=1e-12)
        assert poses[result.label]["RP_mm"] == pytest.approx(result.repeatability.rp_mm, rel=1e-12)
        assert poses[result.label]["U_AP_mm"] == pytest.approx(result.ap_u.expanded_uncertainty, rel=1e-9)


def test_instrument_budget_and_rp_floor_from_the_mouse_settings(stored):
    _, _, report, _ = stored
    step_mm = 25.4 / 800
    sigma = math.sqrt((step_mm / math.sqrt(6)) ** 2 + (0.3 * step_mm) ** 2)  # δ/√6 and 0.3 counts of noise
    assert report.instrument.sigma_mm == pytest.approx(sigma, rel=1e-12)
    assert report.instrument.rp_floor_mm == pytest.approx(3.616 * sigma, rel=1e-3)  # iso9283.md §8.4, 3-D
    assert report.instrument.rp_floor_mm == instrument_rp_floor(sigma, dims=3)


def test_html_and_pdf_print_the_same_numbers_as_the_api(stored):
    _, _, report, paths = stored
    from pypdf import PdfReader

    html = paths.html.read_text(encoding="utf-8")
    pdf_text = " ".join(page.extract_text() for page in PdfReader(paths.pdf).pages)
    for result in report.poses:
        ap = rounded_by_u(result.ap_u.value, result.ap_u.expanded_uncertainty)
        rp = rounded_by_u(result.rp_u.value, result.rp_u.expanded_uncertainty)
        x = rounded_by_u(result.accuracy.ap_axes_mm[0], result.ap_u.expanded_uncertainty).split(" ±")[0]
        for text in (ap, rp, ("+" if not x.startswith("-") else "") + x):
            assert text in html
            assert text in pdf_text


def test_raw_data_is_cited_with_its_sha256(stored):
    _, _, _, paths = stored
    digest = hashlib.sha256(paths.csv[0].read_bytes()).hexdigest()
    assert digest in paths.html.read_text(encoding="utf-8")
    assert paths.csv[0].name in paths.html.read_text(encoding="utf-8")


def test_payload_ladder_equals_payload_shift_and_recovers_the_sag(tmp_path):
    store = Store(tmp_path / "bench.db")
    run_id = write_pose_run(
        store, config=pose_config(loads_kg=[0.0, 1.0, 2.0], cycles=5), noise_mm=0.01, load_sag_mm_per_kg=0.1
    )
    report = collect(store, run_id, resamples=50)
    row = next(r for r in report.payload if r.label == "P1")
    table = report.table[report.table["pose"] == "P1"]
    direct = payload_shift(
        {m: g[["x_mm", "y_mm", "z_mm"]].to_numpy() for m, g in table.groupby("load_kg")}, reference_load_kg=0.0
    )
    np.testing.assert_allclose(row.result.shift_mm, direct.shift_mm, atol=1e-12)
    assert row.result.shift_mm[:, 2] == pytest.approx([0.0, -0.1, -0.2], abs=0.02)
    assert len(report.poses) == 15  # 5 poses x 3 loads, never averaged over loads


def test_distance_run_equals_analyze_distance(tmp_path):
    store = Store(tmp_path / "bench.db")
    config = pose_config(protocol="iso9283_distance", cycles=6)
    run_id = write_pose_run(store, config=config, noise_mm=0.02)
    report = collect(store, run_id, resamples=50)
    (row,) = report.distances
    direct = analyze_distance(report.table, "P1", "P5")
    assert (row.first, row.second) == ("P1", "P5")
    assert row.result.ad_mm == pytest.approx(direct.ad_mm, abs=1e-12)
    assert row.result.rd_mm == pytest.approx(direct.rd_mm, abs=1e-12)
    assert row.result.commanded_distance_mm == pytest.approx(np.linalg.norm(np.subtract(CUBE["P1"], CUBE["P5"])))


def test_decision_only_against_project_criteria(stored):
    store, run_id, report, _ = stored
    assert report.decision.passed is None and "no pass/fail" in report.decision.rule
    judged = collect(store, run_id, criteria={"AP_mm": 0.36, "RP_mm": 10.0}, resamples=50)
    verdicts = {(name, label): result for name, label, _, _, _, result in judged.decision.verdicts}
    for result in judged.poses:
        assert verdicts[("AP_mm", result.label)] == ("pass" if result.accuracy.ap_mm <= 0.36 else "fail")
        assert verdicts[("RP_mm", result.label)] == "pass"
    with pytest.raises(ConfigError, match="criteria: grade_mm not known"):
        collect(store, run_id, criteria={"grade_mm": 1.0})


def test_a_run_without_pose_samples_is_refused(tmp_path):
    store = Store(tmp_path / "bench.db")
    run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config=pose_config())
    with pytest.raises(InsufficientData, match=f"run {run_id}: no 'pose' samples"):
        collect(store, run_id)


def test_multidirectional_vap_equals_the_metrology_function(tmp_path):
    from bench.metrology import multidirectional_variation, orientation_multidirectional_variation
    from bench.reports.pose_document import _results

    store = Store(tmp_path / "bench.db")
    config = pose_config(protocol="iso9283_multidirectional", cycles=4, approach_mm=10.0)
    run_id = store.start_run(
        protocol_name=config["protocol"],
        protocol_version="1",
        robot="pkm5",
        config=config,
        settings={"robot": {}, "instrument": {"instrument": "tracker", "u_mm": 0.01}},
    )
    rng, step, clouds, angles = np.random.default_rng(7), 0, {}, {}
    offsets = {"x": (0.1, 0, 0), "y": (0, 0.1, 0), "z": (0, 0, -0.2)}  # direction-dependent barycentres
    tilts = {"x": 0.0, "y": 0.3, "z": 0.1}  # and angles a (deg)
    for cycle in range(1, 5):
        for direction, offset in offsets.items():
            point = np.add(CUBE["P1"], offset) + rng.normal(0, 0.01, 3)
            clouds.setdefault(direction, []).append(point)
            a = tilts[direction] + rng.normal(0, 0.005)
            angles.setdefault(direction, []).append([a])
            values = dict(zip(("x_mm", "y_mm", "z_mm"), point)) | dict(
                zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), CUBE["P1"])
            )
            store.add_sample(
                run_id,
                step,
                values=values | {"velocity_pct": 100.0, "load_kg": 0.0, "cmd_a_deg": 0.0, "a_deg": a},
                pose=f"P1/{direction}",
                cycle=cycle,
                t_s=float(step),
            )
            step += 1
    report = collect(store, run_id, resamples=50)
    (row,) = report.multidirectional
    assert row.directions == ("P1/x", "P1/y", "P1/z")
    direct = multidirectional_variation([np.array(clouds[d]) for d in "xyz"])
    assert row.result.vap_mm == pytest.approx(direct.vap_mm, abs=1e-12)
    assert row.result.vap_mm == pytest.approx(np.hypot(0.1, 0.2), abs=0.03)  # x vs z approach
    assert row.angle_names == ("a",)
    direct_a = orientation_multidirectional_variation([np.array(angles[d]) for d in "xyz"])
    assert row.orientation.vap_deg == pytest.approx(direct_a.vap_deg, abs=1e-12)
    assert row.orientation.vap_deg[0] == pytest.approx(0.3, abs=0.03)  # x vs y approach
    (table,) = [block for block in _results(report) if getattr(block, "ident", None) == "vap"]
    assert table.header[-1] == "vAP_a (°)" and table.rows[0][-1] == f"{row.orientation.vap_deg[0]:.3f}"


def test_other_pose_protocols_take_conditions_from_the_samples_and_refuse_unknown_load(tmp_path):
    """A delta_positioning run read by another instrument than the laser grid (complete readings, no screen flags)
    gets the pose layout."""
    store = Store(tmp_path / "bench.db")
    config = {
        "protocol": "delta_positioning",
        "robot": "delta4",
        "cycles": 3,
        "settle_s": 0.5,
        "poses": {"A": [0.0, 0.0, -200.0], "B": [-70.0, -70.0, -180.0]},
    }
    run_id = store.start_run(
        protocol_name="delta_positioning",
        protocol_version="1",
        robot="delta4",
        config=config,
        settings={"robot": {}, "instrument": {"instrument": "calliper", "u_mm": 0.01}},
    )
    for step, (label, cycle) in enumerate((p, c) for c in (1, 2, 3) for p in "AB"):
        command = config["poses"][label]
        values = {
            "x_mm": command[0] + 0.1 * cycle,
            "y_mm": command[1],
            "z_mm": command[2] - 0.05 * cycle,
            "cmd_x_mm": command[0],
            "cmd_y_mm": command[1],
            "cmd_z_mm": command[2],
            "velocity_pct": 100.0,
        }
        store.add_sample(run_id, step, values=values, pose=label, cycle=cycle, t_s=float(step))
    with pytest.raises(InsufficientData, match="clause 6.6 load: not stored: config.loads_kg"):
        collect(store, run_id)
    report = collect(store, run_id, allow_unknown=True, resamples=50)
    rows = {d.topic: d for d in report.deviations}
    assert rows["load"].status == "unknown"
    assert rows["velocity"].done.startswith("100 % (no rated velocity stated)")
    assert report.title == "ISO 9283-style pose accuracy and repeatability (delta_positioning)"
    paths = write_report(store, run_id, tmp_path / "out", ("html",), allow_unknown=True)
    assert "not stored: config.loads_kg" in paths.html.read_text(encoding="utf-8")


def test_mouse_calibration_in_force_is_refitted_from_its_source_run_and_plotted(tmp_path):
    from bench.metrology import fit_axis_scale
    from bench.reports.pose_plots import mouse_calibration_plots

    store = Store(tmp_path / "bench.db")
    source = store.start_run(protocol_name="mouse_calibration", protocol_version="1", robot="pkm5", config={})
    rng, step, expected = np.random.default_rng(5), 0, {"x": ([], []), "y": ([], [])}
    for axis, counts_per_mm in (("x", 31.5), ("y", 31.0)):
        for distance in (5.0, 10.0, 20.0, 40.0):
            for repeat in (1, 2):
                counts = round(counts_per_mm * distance + rng.normal(0, 1.0))
                expected[axis][0].append(distance)
                expected[axis][1].append(counts)
                for where, cmd, c in (("start", 90.0, 100), ("end", 90.0 + distance, 100 + counts)):
                    values = {f"cmd_{axis}_mm": cmd, f"mouse_xy_{axis}_counts": float(c)}
                    store.add_sample(
                        source,
                        step,
                        kind="mouse",
                        values=values,
                        pose=f"{axis}{distance:g}/{where}",
                        cycle=repeat,
                        t_s=float(step),
                    )
                    step += 1
    calibration = store.add_calibration("mouse", {"mm_per_count": 0.032}, source_run_id=source)
    run_id = write_pose_run(store, calibration_ids=(calibration.id,), config=pose_config(cycles=3))
    report = collect(store, run_id, resamples=50)
    assert [f.axis for f in report.instrument.fits] == ["x", "y"]
    for fit in report.instrument.fits:
        direct = fit_axis_scale(*expected[fit.axis])
        assert fit.fit.scale_mm_per_count == pytest.approx(direct.scale_mm_per_count, rel=1e-12)
    assert fit.fit.scale_mm_per_count == pytest.approx(1 / 31.0, rel=0.01)
    plots = mouse_calibration_plots(report)
    assert len(plots) == 2
    for plot, axis in zip(plots, "xy"):
        assert f"Calibration mouse v1 (id {calibration.id}, from run {source}), {axis} axis" in plot.caption


def test_distance_run_with_angles_reports_ad_rd_of_each_angle(tmp_path):
    from bench.metrology import orientation_distance_characteristics
    from bench.reports.pose_document import _results

    store = Store(tmp_path / "bench.db")
    config = pose_config(protocol="iso9283_distance", cycles=4)
    run_id = store.start_run(
        protocol_name=config["protocol"],
        protocol_version="1",
        robot="pkm5",
        config=config,
        settings={"robot": {}, "instrument": {"instrument": "tracker", "u_mm": 0.01}},
    )
    rng, step, angles = np.random.default_rng(3), 0, {"P1": [], "P5": []}
    commanded = {"P1": 5.0, "P5": -5.0}  # a_c (deg): D_ca = 10°
    for cycle in range(1, 5):
        for pose in ("P1", "P5"):
            a = commanded[pose] * 1.02 + rng.normal(0, 0.01)  # the robot over-rotates by 2 %
            angles[pose].append([a])
            values = dict(zip(("x_mm", "y_mm", "z_mm"), CUBE[pose])) | dict(
                zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), CUBE[pose])
            )
            store.add_sample(
                run_id,
                step,
                values=values | {"velocity_pct": 100.0, "load_kg": 0.0, "cmd_a_deg": commanded[pose], "a_deg": a},
                pose=pose,
                cycle=cycle,
                t_s=float(step),
            )
            step += 1
    report = collect(store, run_id, resamples=50)
    (row,) = report.distances
    direct = orientation_distance_characteristics(angles["P1"], angles["P5"], [5.0], [-5.0])
    assert row.angle_names == ("a",)
    assert row.orientation.ad_deg == pytest.approx(direct.ad_deg, abs=1e-12)
    assert row.orientation.ad_deg[0] == pytest.approx(0.2, abs=0.03)  # 2 % of 10°
    (table,) = [block for block in _results(report) if getattr(block, "ident", None) == "distance"]
    assert table.header[-1] == "AD_a / RD_a (°)"
    assert table.rows[0][-1] == f"{row.orientation.ad_deg[0]:+.3f} / ±{row.orientation.rd_deg[0]:.3f}"
