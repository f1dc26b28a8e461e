"""``bench calibrate RUN_ID``: identify the pkm5's geometry from a stored run of commanded and measured poses.

Reads the run's pose samples (``cmd_x_mm .. cmd_b_deg`` commanded, ``x_mm, y_mm, z_mm`` measured), rebuilds the
commanded steps with the documented geometry, identifies the free parameters (default: what the pose set and
instrument can identify, docs/calibration.md) and stores the result as a new version of the calibration
``pkm5_kinematics`` with the source run, the residuals and the observability. Heavy modules load inside the handler.
"""

from __future__ import annotations

import argparse
import json

from bench.calibration_compensation import CALIBRATION_NAME
from bench.errors import ConfigError, InsufficientData

DEFAULT_STORE = "bench.db"
_COMMANDED = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg")
_MEASURED = ("x_mm", "y_mm", "z_mm")


def register(groups: argparse._SubParsersAction) -> None:
    parser = groups.add_parser("calibrate", help="identify the pkm5 geometry from a stored run of measured poses",
                               formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("run_id", metavar="RUN_ID", type=int, help="the run with commanded and measured poses")
    parser.add_argument("--free", nargs="+", metavar="PARAM", default=None,
                        help="free parameters (default: the identifiable set); see docs/calibration.md")
    parser.add_argument("--uncertainty-mm", type=float, default=0.05,
                        help="the instrument's standard uncertainty per axis, mm")
    parser.add_argument("--store", default=DEFAULT_STORE, help="run store (SQLite file)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")
    parser.set_defaults(handler=run)


def _poses_of_run(store, run_id: int):
    import numpy as np

    samples = [s for s in store.samples(run_id, "pose") if all(k in s.values for k in _MEASURED)]
    if not samples:
        raise InsufficientData(f"run {run_id}: no pose samples with measured {', '.join(_MEASURED)}; expected a run "
                               "of commanded and measured poses")
    missing = [k for k in _COMMANDED if k not in samples[0].values]
    if missing:
        raise InsufficientData(f"run {run_id}: pose samples lack {missing[0]}; expected commanded pkm5 poses")
    commanded = np.array([[s.values[k] for k in _COMMANDED] for s in samples], dtype=float)
    measured = np.array([[s.values[k] for k in _MEASURED] for s in samples], dtype=float)
    return commanded, measured


def _commanded_geometry(store, run_id: int):
    """The geometry the run's targets were commanded by: the documented one, or the calibrated one of the
    kinematic calibration that was in force (its steps are what the robot really received)."""
    from bench.calibration_compensation import calibrated_geometry
    from motion.pkm5 import DEFAULT_GEOMETRY

    entry = store.run(run_id).settings.get("kinematic_calibration") or {}
    return DEFAULT_GEOMETRY if entry.get("id") is None else calibrated_geometry(store.calibration_by_id(entry["id"]))


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from bench.metrology.kinematic_calibration import identifiable_subset, identify
    from bench.robots.pkm5_kinematics import steps_for_pose
    from bench.store import Store
    from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, modes_of_poses

    if not args.uncertainty_mm > 0:
        raise ConfigError(f"--uncertainty-mm = {args.uncertainty_mm!r}, expected a positive number")
    with Store(args.store) as store:
        store.run(args.run_id)
        commanded, measured = _poses_of_run(store, args.run_id)
        geometry = _commanded_geometry(store, args.run_id)
        steps = np.array([steps_for_pose(p, geometry) for p in commanded])
        modes = modes_of_poses(commanded)
        candidates = REGISTRATION + PARAMETERS
        if args.free:
            free = REGISTRATION + tuple(n for n in args.free if n not in REGISTRATION)
        else:
            jac = ForwardModel(steps, modes, candidates).jacobian(np.zeros(len(candidates)))
            free = identifiable_subset(jac, args.uncertainty_mm, candidates, required=REGISTRATION)
        frame_only = identify(ForwardModel(steps, modes, REGISTRATION), measured, args.uncertainty_mm)
        result = identify(ForwardModel(steps, modes, free), measured, args.uncertainty_mm)
        ap_before = float(np.mean(np.linalg.norm(frame_only.residuals, axis=1)))
        ap_after = float(np.mean(np.linalg.norm(result.residuals, axis=1)))
        params = {**result.as_dict(), "robot": "pkm5", "uncertainty_mm": args.uncertainty_mm,
                  "ap_before_mm": ap_before, "ap_after_mm": ap_after}
        settings = store.run(args.run_id).settings
        serial = (settings.get("dut") or {}).get("dut_serial")
        if serial:  # the calibration belongs to this robot: runs of other robots never use it by default
            params["dut_serial"] = serial
        if "simulator" in settings:  # a simulated robot's geometry: never in force on hardware
            params["simulated"] = True
        record = store.add_calibration(CALIBRATION_NAME, params, source_run_id=args.run_id,
                                       notes=f"bench calibrate {args.run_id}")
    obs = result.observability
    if args.json:
        print(json.dumps({"calibration": CALIBRATION_NAME, "version": record.version, "id": record.id, **params}))
        return 0
    print(f"{CALIBRATION_NAME} v{record.version} (id {record.id}) from run {args.run_id}: {len(measured)} poses, "
          f"{len(free)} free parameters")
    print(f"{'parameter':<18} {'value':>12} {'std. unc.':>12}  unit")
    for name, value, std, unit in zip(result.names, result.values, result.uncertainty, result.units):
        print(f"{name:<18} {value:12.5f} {std:12.5f}  {unit}")
    print(f"condition number {obs.condition_number:.1f} (limit 100), O1 {obs.o1:.4g}, reduced chi2 "
          f"{result.reduced_chi2:.2f}")
    print(f"mean position error on the calibration poses (in-sample): before {ap_before:.3f} mm, after "
          f"{ap_after:.3f} mm")
    return 0
