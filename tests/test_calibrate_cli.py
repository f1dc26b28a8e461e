"""``bench calibrate RUN_ID`` on a stored run of simulated mice measurements of a seeded true geometry."""

import json

import numpy as np
import pytest

from bench.cli import main
from bench.errors import ConfigError
from bench.metrology.kinematic_calibration import identifiable_subset, select_poses
from bench.simulators.true_geometry import attained_poses, true_deviations, true_geometry
from bench.store import Store
from motion import pkm5
from motion.pkm5.calibration import (
    PARAMETERS,
    REGISTRATION,
    ForwardModel,
    geometry_from_calibration,
    modes_of_poses,
    parameter_deviations,
)

ALL = REGISTRATION + PARAMETERS
UNCERTAINTY_MM = 0.05


def _store_run(path, commanded_deg, measured):
    with Store(path) as store:
        run_id = store.start_run(protocol_name="kinematic_calibration", protocol_version="1", robot="pkm5", config={})
        for i, (cmd, meas) in enumerate(zip(commanded_deg, measured)):
            values = {
                **dict(zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg"), map(float, cmd))),
                **dict(zip(("x_mm", "y_mm", "z_mm"), map(float, meas))),
            }
            store.add_sample(run_id, i, values=values, kind="pose", pose=f"P{i}", cycle=1, t_s=float(i))
    return run_id


def _design():
    """30 D-optimal poses away from FK folds of 200 candidates, as a protocol file states them (deg)."""
    poses = pkm5.sample_reachable(200, kinds=("constant-orientation", "alpha", "beta"), seed=3)
    poses_deg = np.array(poses)
    poses_deg[:, 3:] = np.round(np.degrees(poses_deg[:, 3:]), 3)  # as a protocol file states them
    poses_rad = poses_deg.copy()
    poses_rad[:, 3:] = np.radians(poses_rad[:, 3:])
    steps = pkm5.lengths_to_steps(pkm5.inverse_kinematics(poses_rad).lengths_mm)
    modes = modes_of_poses(poses_deg)
    model = ForwardModel(steps, modes, ALL)
    jac = model.jacobian(np.zeros(len(ALL)))
    pick = select_poses(jac, UNCERTAINTY_MM, 30, fold_ratio=model.fold_ratio(np.zeros(len(ALL))))
    return poses_deg[pick], steps[pick], modes[pick], jac[pick]


def test_calibrate_identifies_and_stores_a_version(tmp_path, capsys):
    commanded, steps, modes, jac = _design()
    truth = true_geometry(11)  # every parameter perturbed
    rng = np.random.default_rng(11)
    measured = attained_poses(steps, modes, truth)[:, :3] + rng.normal(0, UNCERTAINTY_MM, (30, 3))
    path = tmp_path / "bench.db"
    run_id = _store_run(path, commanded, measured)

    assert main(["calibrate", str(run_id), "--store", str(path), "--json"]) == 0  # the default fit: MAP
    out = json.loads(capsys.readouterr().out)
    assert out["calibration"] == "pkm5_kinematics" and out["version"] == 1
    assert out["fit"] == "map" and out["prior"]["sigma"] == {"leg_offset": 0.3, "scale": 0.005, "joint": 0.3}
    assert out["prior_sigma"]["reg_x_mm"] is None and out["prior_sigma"]["scale_2"] == 0.005
    expected = true_deviations(11)
    params = out["parameters"]
    assert set(params) == set(ALL)
    for name in PARAMETERS:
        assert abs(params[name]["value"] - expected[name]) < 3 * params[name]["uncertainty"], name
    assert set(out["prior_only"]) <= set(PARAMETERS)
    assert out["ap_after_mm"] < out["ap_before_mm"] / 10
    with Store(path) as store:
        record = store.calibration("pkm5_kinematics")
    assert record.version == 1 and record.source_run_id == run_id and record.params["fit"] == "map"
    calibrated = geometry_from_calibration(record.params)
    for name in PARAMETERS:
        assert parameter_deviations(calibrated)[name] == pytest.approx(params[name]["value"], abs=1e-12)

    # The free set holds the other parameters at the drawing, whose error stays in the residuals: reduced chi^2
    # ~7, so its uncertainties would be understated; refused (nothing stored) and stored once the residuals' own
    # scale is stated as the uncertainty.
    assert main(["calibrate", str(run_id), "--store", str(path), "--json", "--fit", "free-set"]) == 1
    err = capsys.readouterr().err
    assert "--fit map frees every parameter" in err and "nothing stored" in err
    suggested = err.split("--uncertainty-mm ")[1].split(")")[0]
    assert (
        main(
            [
                "calibrate",
                str(run_id),
                "--store",
                str(path),
                "--json",
                "--fit",
                "free-set",
                "--uncertainty-mm",
                suggested,
            ]
        )
        == 0
    )
    out = json.loads(capsys.readouterr().out)
    free = identifiable_subset(jac, float(suggested), ALL, required=REGISTRATION)
    assert out["version"] == 2 and out["fit"] == "free-set" and out["prior"] is None
    assert set(out["parameters"]) == set(free) and out["observability"]["condition_number"] <= 100


def test_calibrate_prints_which_parameters_only_the_prior_fixes(tmp_path, capsys):
    commanded, steps, modes, _ = _design()
    measured = attained_poses(steps, modes, true_geometry(11))[:, :3]
    path = tmp_path / "bench.db"
    run_id = _store_run(path, commanded, measured)
    assert main(["calibrate", str(run_id), "--store", str(path), "--json"]) == 0
    stored = json.loads(capsys.readouterr().out)
    assert main(["calibrate", str(run_id), "--store", str(path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    # ... the approach, the search, the parameters widened by their profile likelihood, the scatter and the plan
    assert len(lines) == 2 + 36 + 3 + 4 + bool(stored["search"]["profile_widened"])
    assert (
        "poses approached directly (the legs' backlash, whose sign follows the pose before, is not modelled)" in lines
    )
    for line in lines[2 : 2 + 36]:  # GUM 7.2.6, as the report: the uncertainty to 2 significant digits, the value to
        name, value, u, unit = line.split()  # the same decimal place (not 0.13474 +- 0.14998 mm)
        decimals = len(u.split(".")[1]) if "." in u else 0
        assert len(u.replace(".", "").lstrip("0")) == 2 and len(value.split(".")[1]) == decimals, line
        entry = stored["parameters"][name]
        assert float(u) == pytest.approx(entry["uncertainty"], abs=0.5 * 10.0**-decimals), line
        assert float(value) == pytest.approx(entry["value"], abs=0.5 * 10.0**-decimals), line
        assert unit == entry["unit"] and (value[0] in "+-" or float(value) == 0), line
    fit_at = len(lines) - 6 - bool(stored["search"]["profile_widened"])
    assert lines[fit_at] == (
        "fit: maximum a posteriori, prior: manufacturing tolerances (motion.pkm5.calibration."
        "TOLERANCES); fixed by the prior (the data did not inform them): " + (", ".join(stored["prior_only"]) or "none")
    )
    assert lines[fit_at + 1].startswith(
        f"data part: condition number {stored['observability']['condition_number']:.3g} "
    )
    assert lines[fit_at + 1].endswith(
        f"reduced chi2 {stored['reduced_chi2']:.2f} over {stored['degrees_of_freedom']:.1f} degrees of freedom"
    )
    assert 90 - 36 < stored["degrees_of_freedom"] < 90 - 3  # the prior holds part of the 33, none of the registration


def test_calibrate_a_run_without_measured_poses_is_one_line(tmp_path, capsys):
    path = tmp_path / "bench.db"
    with Store(path) as store:
        run_id = store.start_run(protocol_name="pose_test", protocol_version="1", robot="pkm5", config={})
    assert main(["calibrate", str(run_id), "--store", str(path)]) == 1
    err = capsys.readouterr().err
    assert err == (
        f"bench: error: run {run_id}: no pose samples with measured x_mm, y_mm, z_mm; expected a run of "
        "commanded and measured poses\n"
    )


def test_calibrate_a_singular_pose_set_names_the_parameters(tmp_path, capsys):
    x = np.linspace(120.0, 170.0, 12)
    commanded = np.column_stack([x, np.zeros(12), np.full(12, 300.0), np.zeros(12), np.zeros(12)])
    path = tmp_path / "bench.db"
    run_id = _store_run(path, commanded, commanded[:, :3])
    code = main(["calibrate", str(run_id), "--store", str(path), "--free", "leg_offset_1_mm", "scale_1", "oa_12_x_mm"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "condition number" in err and "oa_12_x_mm" in err
    # the default fit (MAP of every parameter): the line informs none of them, refused naming them
    assert main(["calibrate", str(run_id), "--store", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the 12 poses inform only 0 of the 33 parameters with a prior" in err
    assert "leg_offset_1_mm" in err and "pd_6_z_mm" in err


@pytest.mark.parametrize("value", ["inf", "0", "-0.05", "nan"])
def test_calibrate_refuses_an_uncertainty_that_is_not_a_positive_finite_number_in_one_line(tmp_path, capsys, value):
    # inf used to pass the check and be refused later as "reg_x_mm (no effect on the measurements)"
    path = tmp_path / "bench.db"
    run_id = _store_run(path, np.zeros((2, 5)), np.zeros((2, 3)))
    assert main(["calibrate", str(run_id), "--store", str(path), "--uncertainty-mm", value]) == 2
    assert capsys.readouterr().err == (
        f"bench: error: --uncertainty-mm = {float(value)!r}, expected a positive finite "
        "number (the instrument's standard uncertainty per axis, mm)\n"
    )


def test_a_fit_the_stated_uncertainty_cannot_explain_is_refused_and_stored_once_stated_right(tmp_path, capsys):
    """Readings with 0.05 mm noise stated as 0.01 mm: reduced chi^2 ~25, far above the 2.1 an honest fit of ~60
    degrees of freedom exceeds once in a million; nothing is stored, and the line names the uncertainty the
    residuals suggest, with which the same run is then stored with a reduced chi^2 near 1."""
    commanded, steps, modes, _ = _design()
    rng = np.random.default_rng(5)
    measured = attained_poses(steps, modes, true_geometry(5))[:, :3] + rng.normal(0, UNCERTAINTY_MM, (30, 3))
    path = tmp_path / "bench.db"
    run_id = _store_run(path, commanded, measured)
    assert main(["calibrate", str(run_id), "--store", str(path), "--uncertainty-mm", "0.01"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"bench: error: run {run_id}: the fit leaves residuals ") and err.count("\n") == 1
    assert "times the stated uncertainty 0.01 mm" in err and "nothing stored" in err
    suggested = float(err.split("--uncertainty-mm ")[1].split(")")[0])
    assert 0.035 < suggested < 0.07  # the residuals' own scale: the noise drawn, 0.05 mm
    with Store(path) as store, pytest.raises(ConfigError, match="not found"):
        store.calibration("pkm5_kinematics")
    assert main(["calibrate", str(run_id), "--store", str(path), "--json", "--uncertainty-mm", str(suggested)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["version"] == 1 and 0.5 < out["reduced_chi2"] < 1.5
