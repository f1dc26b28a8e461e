"""A mouse_calibration run (issue 32, item 5): against a stated reference, printed with its U, stored but not put
in force, and its export analysed and reported to the same numbers."""

from __future__ import annotations

import json
import logging
from types import SimpleNamespace

import numpy as np
import pytest
from reports_runs import rounded_by_u

from bench.cli import main
from bench.errors import ConfigError
from bench.launch import simulated_rig_in
from bench.protocols import Runner
from bench.protocols.base import PROTOCOLS
from bench.protocols.dissertation import mouse_calibration_moves
from bench.store import Store, export_run

QUICK = {"settle_s": 0.1, "repeats": 2, "distances_mm": [5, 20, 40]}


def test_the_reference_must_be_stated():
    with pytest.raises(ConfigError, match="reference missing, expected 'calliper' or 'calibrated-axis'"):
        PROTOCOLS["mouse_calibration"](**QUICK).validate()
    with pytest.raises(ConfigError, match="reference_u_pct missing"):
        PROTOCOLS["mouse_calibration"](reference="calliper", **QUICK).validate()


def test_a_run_is_stored_printed_exported_analysed_and_reported(tmp_path, caplog, capsys):
    protocol = PROTOCOLS["mouse_calibration"](reference="calibrated-axis", reference_u_pct=0.05, **QUICK)
    caplog.set_level(logging.WARNING)
    with Store(tmp_path / "b.db") as store:
        rig = simulated_rig_in(store, "pkm5", seed=2, speed_factor=20000)
        try:
            result = Runner(rig, store).run(protocol)
        finally:
            rig.close()
        assert result.exit_status == "completed"
        stored = next(c for c in store.calibrations() if c.source_run_id == result.run_id)
        export_run(store, result.run_id, tmp_path / "mouse.csv", fmt="csv", kind="mouse")
    params = stored.params
    assert f"stored mouse calibration mouse-v{stored.version}" in caplog.text
    assert f"not in force until a station names it ([mice] calibration = {stored.version})" in caplog.text
    # the scale and its cpi rounded by their U (GUM 7.2.6), not 0.031759 ± 1.3e-03 (799.8 cpi): rounded_by_u is
    # independent of bench's formatter
    big_u = params["k"] * params["u_x_mm_per_count"]
    scale = params["x_mm_per_count"]
    assert f"x {rounded_by_u(scale, big_u)} mm/count ({rounded_by_u(25.4 / scale, 25.4 * big_u / scale**2)} cpi)" in (
        caplog.text
    )
    assert params["reference"] == "calibrated-axis" and params["k"] > 2.0  # Student's t at the fit's dof
    # 3 lengths x 2 repeats per axis: 6 steps there and 5 back per axis
    assert params["dof"] == 22 - 6
    capsys.readouterr()
    assert main(["analyze", "mouse", str(tmp_path / "mouse.csv"), "--json"]) == 0
    analysed = json.loads(capsys.readouterr().out)
    assert np.array(analysed["A_mm_per_count"]) == pytest.approx(np.array(params["matrix_mm_per_count"]), rel=1e-12)
    assert analysed["k"] == pytest.approx(params["k"])
    assert (
        main(
            [
                "report",
                str(result.run_id),
                "--store",
                str(tmp_path / "b.db"),
                "--out",
                str(tmp_path / "r"),
                "--format",
                "html",
                "--quiet",
            ]
        )
        == 0
    )
    page = (tmp_path / "r" / f"report_run{result.run_id}.html").read_text()
    a = np.array(params["matrix_mm_per_count"])
    u = params["k"] * np.array(params["u_matrix_mm_per_count"])
    assert f"+{rounded_by_u(a[0, 0], u[0, 0])}" in page and f"[mice] calibration = {stored.version}" in page


def _sample(pose, cycle, **values):
    return SimpleNamespace(pose=pose, cycle=cycle, values=values)


def test_a_calliper_reference_replaces_the_robots_commanded_travel():
    """The robot under test travels 3 % short of its commands; the calliper reads the true travel, which the mouse
    counts at exactly 31.5 counts/mm: the fit against the calliper finds 31.5, the commanded one would not."""
    samples, references, counts_per_mm = [], [], 31.5
    for distance in (5.0, 20.0, 40.0):
        for cycle in (1, 2):
            for where, commanded in (("start", 90.0), ("end", 90.0 + distance)):
                true_x = 90.0 + 0.97 * (commanded - 90.0)
                samples.append(
                    _sample(
                        f"x{distance:g}/{where}",
                        cycle,
                        cmd_x_mm=commanded,
                        cmd_y_mm=-20.0,
                        mouse_xy_x_counts=round(true_x * counts_per_mm),
                        mouse_xy_y_counts=0.0,
                    )
                )
                references.append(_sample(f"x{distance:g}/{where}", cycle, reference_mm=true_x))
    calliper, counts, readings = mouse_calibration_moves(samples, references)
    commanded, *_ = mouse_calibration_moves(samples)
    assert len(calliper) == 11 and (calliper[:, 1] == 0).all()
    assert readings.tolist() == [
        [k, k + 1] for k in range(11)
    ]  # one out-and-back chain: each starts where the last ended
    slope = np.linalg.lstsq(calliper[:, :1], counts[:, 0], rcond=None)[0][0]
    assert slope == pytest.approx(counts_per_mm, rel=2e-3)
    assert np.linalg.lstsq(commanded[:, :1], counts[:, 0], rcond=None)[0][0] == pytest.approx(
        0.97 * counts_per_mm, rel=2e-3
    )


def test_a_move_table_says_which_moves_share_a_reading(tmp_path, capsys):
    """``bench analyze mouse`` on a move table: the optional start_reading and end_reading columns give the
    weighted fit the chain (its U is the one fit_matrix states with them, whatever the row order); a reading
    number that is not whole is one line naming it."""
    from bench.metrology import fit_matrix
    from bench.simulators.mouse_calibration_mc import calibration_moves

    reference, counts, readings = calibration_moves(np.random.default_rng(6), 30, "both directions")
    rows = [f"{r[0]},{r[1]},{c[0]:g},{c[1]:g},{s},{e}" for r, c, (s, e) in zip(reference, counts, readings)]
    path = tmp_path / "moves.csv"
    header = "ref_x_mm,ref_y_mm,counts_x,counts_y,start_reading,end_reading"
    path.write_text("\n".join([header, *rows[::-1]]) + "\n")
    assert main(["analyze", "mouse", str(path), "--json"]) == 0
    analysed = json.loads(capsys.readouterr().out)
    weighted = fit_matrix(reference, counts, per_direction=True, readings=readings)
    unshared = fit_matrix(reference, counts, per_direction=True, readings=np.arange(60).reshape(30, 2))
    assert np.array(analysed["U_A_mm_per_count"]) == pytest.approx(weighted.expanded_a_mm_per_count, rel=1e-9)
    assert not np.allclose(weighted.u_a_mm_per_count, unshared.u_a_mm_per_count, rtol=1e-3)
    path.write_text(path.read_text().replace(f",{readings[-1, 1]}\n", ",1.5\n", 1))
    assert main(["analyze", "mouse", str(path)]) == 2
    err = capsys.readouterr().err
    assert "row 1, column end_reading: 1.5, expected a whole reading number" in err and err.count("\n") == 1
