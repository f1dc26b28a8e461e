"""Identify the pkm5's geometry from a stored run: the function behind ``bench calibrate RUN_ID`` and the window's
"Identify" button.

Reads the run's pose samples (``cmd_x_mm .. cmd_b_deg`` commanded, ``x_mm, y_mm, z_mm`` measured), rebuilds the
commanded steps with the geometry the run commanded by (the documented one, or the calibrated one of the kinematic
calibration that was in force), identifies the free parameters (default: what the pose set and instrument can
identify, :func:`bench.metrology.kinematic_calibration.identifiable_subset`) and stores the result as a new version
of ``pkm5_kinematics`` with the source run, the residuals and the observability (docs/calibration.md). The in-sample
mean position error before is that of the documented geometry with only the registration fitted:
``mean_j |m_j - f(theta_reg)_j|``, after ``mean_j |m_j - f(theta_hat)_j|``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.calibration_compensation import CALIBRATION_NAME
from bench.errors import ConfigError, InsufficientData

__all__ = ["COMMANDED", "DEFAULT_UNCERTAINTY_MM", "IdentifiedRun", "MEASURED", "check_uncertainty", "identify_run",
           "summary_lines"]

COMMANDED = ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm", "cmd_a_deg", "cmd_b_deg")
MEASURED = ("x_mm", "y_mm", "z_mm")
#: The mice's standard uncertainty per axis, mm (the calibration protocol's pose selection assumes it).
DEFAULT_UNCERTAINTY_MM = 0.05


@dataclass(frozen=True)
class IdentifiedRun:
    """What :func:`identify_run` stored: the calibration record, the identification and the stored parameters."""

    run_id: int
    record: Any  # bench.store CalibrationRecord
    result: Any  # bench.metrology.kinematic_calibration.Identification
    params: dict
    n_measurements: int


def _poses_of_run(store, run_id: int):
    import numpy as np

    samples = [s for s in store.samples(run_id, "pose") if all(k in s.values for k in MEASURED)]
    if not samples:
        raise InsufficientData(f"run {run_id}: no pose samples with measured {', '.join(MEASURED)}; expected a run "
                               "of commanded and measured poses")
    missing = [k for k in COMMANDED if k not in samples[0].values]
    if missing:
        raise InsufficientData(f"run {run_id}: pose samples lack {missing[0]}; expected commanded pkm5 poses")
    commanded = np.array([[s.values[k] for k in COMMANDED] for s in samples], dtype=float)
    measured = np.array([[s.values[k] for k in MEASURED] for s in samples], dtype=float)
    return commanded, measured


def _commanded_geometry(store, run_id: int):
    """The geometry the run's targets were commanded by: the documented one, or the calibrated one of the
    kinematic calibration that was in force (its steps are what the robot really received)."""
    from bench.calibration_compensation import calibrated_geometry
    from motion.pkm5 import DEFAULT_GEOMETRY

    entry = store.run(run_id).settings.get("kinematic_calibration") or {}
    return DEFAULT_GEOMETRY if entry.get("id") is None else calibrated_geometry(store.calibration_by_id(entry["id"]))


def check_uncertainty(uncertainty_mm: float) -> None:
    """Refuse an instrument uncertainty that is not a positive number (one line)."""
    if not uncertainty_mm > 0:
        raise ConfigError(f"--uncertainty-mm = {uncertainty_mm!r}, expected a positive number")


def identify_run(store: Any, run_id: int, *, free: list[str] | tuple[str, ...] | None = None,
                 uncertainty_mm: float = DEFAULT_UNCERTAINTY_MM) -> IdentifiedRun:
    """Identify from run ``run_id`` of the open ``store`` and store a new ``pkm5_kinematics`` version (module doc).

    A run without measured poses raises ``InsufficientData``, an ill-conditioned pose set
    ``UnidentifiableParameters`` (both one line)."""
    import numpy as np

    from bench.metrology.kinematic_calibration import identifiable_subset, identify
    from bench.robots.pkm5_kinematics import steps_for_pose
    from motion.pkm5.calibration import PARAMETERS, REGISTRATION, ForwardModel, modes_of_poses

    check_uncertainty(uncertainty_mm)
    store.run(run_id)
    commanded, measured = _poses_of_run(store, run_id)
    geometry = _commanded_geometry(store, run_id)
    steps = np.array([steps_for_pose(p, geometry) for p in commanded])
    modes = modes_of_poses(commanded)
    candidates = REGISTRATION + PARAMETERS
    if free:
        chosen = REGISTRATION + tuple(n for n in free if n not in REGISTRATION)
    else:
        jac = ForwardModel(steps, modes, candidates).jacobian(np.zeros(len(candidates)))
        chosen = identifiable_subset(jac, uncertainty_mm, candidates, required=REGISTRATION)
    frame_only = identify(ForwardModel(steps, modes, REGISTRATION), measured, uncertainty_mm)
    result = identify(ForwardModel(steps, modes, chosen), measured, uncertainty_mm)
    params = {**result.as_dict(), "robot": "pkm5", "uncertainty_mm": uncertainty_mm,
              "ap_before_mm": float(np.mean(np.linalg.norm(frame_only.residuals, axis=1))),
              "ap_after_mm": float(np.mean(np.linalg.norm(result.residuals, axis=1)))}
    settings = store.run(run_id).settings
    serial = (settings.get("dut") or {}).get("dut_serial")
    if serial:  # the calibration belongs to this robot: runs of other robots never use it by default
        params["dut_serial"] = serial
    if "simulator" in settings:  # a simulated robot's geometry: never in force on hardware
        params["simulated"] = True
    record = store.add_calibration(CALIBRATION_NAME, params, source_run_id=run_id, notes=f"bench calibrate {run_id}")
    return IdentifiedRun(run_id, record, result, params, len(measured))


def summary_lines(identified: IdentifiedRun) -> list[str]:
    """The text ``bench calibrate`` prints (and the window shows): parameters, uncertainties, observability."""
    result, record, params = identified.result, identified.record, identified.params
    obs = result.observability
    lines = [f"{CALIBRATION_NAME} v{record.version} (id {record.id}) from run {identified.run_id}: "
             f"{identified.n_measurements} poses, {len(result.names)} free parameters",
             f"{'parameter':<18} {'value':>12} {'std. unc.':>12}  unit"]
    lines += [f"{name:<18} {value:12.5f} {std:12.5f}  {unit}"
              for name, value, std, unit in zip(result.names, result.values, result.uncertainty, result.units)]
    lines.append(f"condition number {obs.condition_number:.1f} (limit 100), O1 {obs.o1:.4g}, reduced chi2 "
                 f"{result.reduced_chi2:.2f}")
    lines.append(f"mean position error on the calibration poses (in-sample): before {params['ap_before_mm']:.3f} "
                 f"mm, after {params['ap_after_mm']:.3f} mm")
    return lines
