"""A stored calibration run -> the identification problem of its robot: the joints the robot received, the
readings of the axes the instrument read and their uncertainty, the per-pose means of a campaign
(:func:`bench.calibration.identify.identify_run` solves it; docs/calibration.md).

* pkm5: commanded poses ``cmd_x_mm .. cmd_b_deg`` -> steps (:func:`bench.robots.pkm5_kinematics.steps_for_pose`);
  the mice read x, y, z (0.05 mm per axis unless told).
* delta4: commanded positions ``cmd_x_mm .. cmd_z_mm`` -> the servo angles the controller received: the IK of the
  geometry in force, through the run's servo mapping (``settings.robot.mapping``: its bytes, 0.75 deg a byte for
  ``legacy_vb``, are what the servos were sent; or, where the run's ``settings.robot.fine_reference`` says fine
  references were in use, their 0.01 deg values on the controller's step, 0.01125 deg). The camera spot sensor
  reads the two axes of its plane (its uncertainty: the plane calibration's ``u_mm``); the laser grid reads per
  screen, so a sample holds x, y, z or only some (its uncertainty: the detection window's uniform half width /
  sqrt 3, 0.58 mm for +-1 mm). The candidates are the registration of the axes read and
  :data:`motion.delta4.calibration.BASE_PARAMETERS`. Stored besides the fit: ``command_resolution_mm``, the mean
  over the samples of |p(sent angles) - p(IK angles)| on the axes read (the documented robot): what the byte (or
  fine) steps alone cost, the floor of any compensation (docs/calibration.md).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field
from typing import Any

from bench.errors import ConfigError, InsufficientData
from bench.robot_kinds import robot_kind

__all__ = [
    "DEFAULT_UNCERTAINTY_MM",
    "MEASURED",
    "Problem",
    "ReadAxes",
    "WORKSPACE_POSES",
    "check_uncertainty",
    "delta4_problem",
    "mean_error_mm",
    "pkm5_problem",
    "pkm5_workspace",
]

MEASURED = ("x_mm", "y_mm", "z_mm")
#: The mice's standard uncertainty per axis, mm (the pkm5 calibration protocol's pose selection assumes it).
DEFAULT_UNCERTAINTY_MM = 0.05
#: Workspace poses at which two ambiguous pkm5 solutions are compared (the calibration protocol's 300 candidates).
WORKSPACE_POSES = 300


@dataclass(frozen=True)
class Problem:
    """One run's identification problem: ``model(free)`` builds the forward model of free parameters, of which
    ``candidates`` may be free and ``required`` always are (the registration); ``measured`` (N, a) readings with
    ``uncertainty_mm``; ``sample_of`` maps each reading row to its sample (rows of one sample make its error)."""

    model: Any
    candidates: tuple[str, ...]
    required: tuple[str, ...]
    measured: Any
    uncertainty_mm: float
    sample_of: Any
    n_samples: int
    #: stored with the calibration besides the fit (the delta4: ``command_resolution_mm``)
    extra: dict = field(default_factory=dict)
    #: ``prior(names)`` -> each parameter's 1-sigma prior (inf: none) and ``prior_source`` what it is; None: the
    #: robot has no prior, only the free-set fit
    prior: Any = None
    prior_source: dict | None = None
    #: the per-pose means and their scatter (:class:`bench.metrology.kinematic_campaign.PoseMeans`); None: the
    #: readings are fitted one by one (the laser grid, whose samples read different axes)
    campaign: Any = None
    #: ``workspace(free)`` -> (poses (M, c) in the protocol's units, the forward model of ``free`` at them): a sample
    #: of the robot's workspace where two ambiguous solutions are compared (None: not offered for this robot)
    workspace: Any = None


class ReadAxes:
    """A forward model of x, y, z restricted to the axes each sample read (``mask`` (N, 3) bool): one row per read
    coordinate, so samples that read different axes (the laser grid's screens) are fitted together."""

    def __init__(self, model: Any, mask: Any) -> None:
        self._model, self._mask = model, mask
        self.free, self.units = model.free, model.units
        self.bound = model.bound

    def predict(self, theta):
        return self._model.predict(theta)[self._mask][:, None]

    def jacobian(self, theta):
        return self._model.jacobian(theta)[self._mask][:, None, :]


def _measured_pose_samples(store, run_id: int) -> list:
    return [s for s in store.samples(run_id, "pose") if any(k in s.values for k in MEASURED)]


def _pose_samples(store, run_id: int, robot: str):
    """Pose samples with at least one measured axis; their commanded values (N, c) and measured mask (N, 3)."""
    import numpy as np

    samples = _measured_pose_samples(store, run_id)
    if not samples:
        raise InsufficientData(
            f"run {run_id}: no pose samples with measured {', '.join(MEASURED)}; expected a run "
            "of commanded and measured poses"
        )
    commanded_fields = robot_kind(robot).commanded
    missing = [k for k in commanded_fields if k not in samples[0].values]
    if missing:
        raise InsufficientData(f"run {run_id}: pose samples lack {missing[0]}; expected commanded {robot} poses")
    commanded = np.array([[s.values[k] for k in commanded_fields] for s in samples], dtype=float)
    mask = np.array([[k in s.values for k in MEASURED] for s in samples])
    measured = np.array([[s.values.get(k, np.nan) for k in MEASURED] for s in samples], dtype=float)
    return commanded, measured, mask


def _commanded_geometry(store, run_id: int, documented):
    """The geometry the run's targets were commanded by: ``documented``, or the calibrated one of the kinematic
    calibration that was in force (its joints are what the robot really received)."""
    from bench.calibration.compensate import calibrated_geometry

    entry = store.run(run_id).settings.get("kinematic_calibration") or {}
    return documented if entry.get("id") is None else calibrated_geometry(store.calibration_by_id(entry["id"]))


def check_uncertainty(uncertainty_mm: float | None) -> None:
    """Refuse an instrument uncertainty that is not a positive finite number (one line); None: the instrument's own."""
    if uncertainty_mm is not None and not 0 < uncertainty_mm < math.inf:
        raise ConfigError(
            f"--uncertainty-mm = {uncertainty_mm!r}, expected a positive finite number (the "
            "instrument's standard uncertainty per axis, mm)"
        )


def pkm5_problem(store, run_id: int, uncertainty_mm: float | None) -> Problem:
    import numpy as np

    from bench.robots.pkm5_kinematics import steps_for_pose
    from motion.pkm5 import DEFAULT_GEOMETRY
    from motion.pkm5.calibration import PARAMETERS, REGISTRATION, TOLERANCES, ForwardModel, modes_of_poses, tolerance

    commanded, measured, mask = _pose_samples(store, run_id, "pkm5")
    complete = mask.all(axis=1)  # the mice read x, y, z together
    if not complete.any():
        raise InsufficientData(
            f"run {run_id}: no pose samples with measured {', '.join(MEASURED)}; expected a run "
            "of commanded and measured poses"
        )
    commanded, measured = commanded[complete], measured[complete]
    instrument = DEFAULT_UNCERTAINTY_MM if uncertainty_mm is None else uncertainty_mm
    commanded, campaign = _campaign(commanded, measured, instrument)
    geometry = _commanded_geometry(store, run_id, DEFAULT_GEOMETRY)
    steps = np.array([steps_for_pose(p, geometry) for p in commanded])
    modes = modes_of_poses(commanded)
    return Problem(
        lambda free: ForwardModel(steps, modes, free),
        REGISTRATION + PARAMETERS,
        REGISTRATION,
        campaign.mean_mm,
        campaign.uncertainty_mm,
        np.arange(len(commanded)),
        len(commanded),
        {"campaign": {**campaign.as_dict(), **_robot_time(store, run_id)}},
        campaign=campaign,
        prior=lambda names: np.array([tolerance(n) for n in names]),
        prior_source={
            "name": "manufacturing tolerances (motion.pkm5.calibration.TOLERANCES)",
            "sigma": dict(TOLERANCES),
        },
        workspace=lambda free: (pkm5_workspace()[0], ForwardModel(*pkm5_workspace()[1:], free)),
    )


@functools.lru_cache(maxsize=1)
def pkm5_workspace():
    """Where two pkm5 solutions are compared: :data:`WORKSPACE_POSES` reachable poses of the three motion modes
    (seed 1, the calibration protocol's candidates; mm, deg rounded as a protocol states them), those the pre-flight
    passes: the poses, their steps (the documented geometry) and modes."""
    import numpy as np

    from bench.errors import UnreachableTarget
    from bench.robots.pkm5_kinematics import steps_for_pose
    from motion import pkm5
    from motion.pkm5.calibration import modes_of_poses

    poses = np.array(pkm5.sample_reachable(WORKSPACE_POSES, kinds=("constant-orientation", "alpha", "beta"), seed=1))
    poses[:, 3:] = np.degrees(poses[:, 3:])
    poses = np.round(poses, 2)
    kept, steps = [], []
    for pose in poses:
        try:
            steps.append(steps_for_pose(pose))
        except UnreachableTarget:
            continue
        kept.append(pose)
    return np.array(kept), np.array(steps), modes_of_poses(np.array(kept))


def _campaign(commanded, measured, instrument_mm: float):
    """The distinct commanded poses (P, c) in first-visit order and the per-pose means of their readings, weighted
    by the measured scatter of the mean (:func:`bench.metrology.kinematic_campaign.pose_means`)."""
    import numpy as np

    from bench.metrology.kinematic_campaign import erratic_poses, pose_means

    poses, first, index = np.unique(commanded, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # first-visit order, so pose i is the protocol's i-th
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    labels, poses = rank[np.ravel(index)], poses[order]
    erratic = erratic_poses(measured, labels, instrument_mm)
    if erratic.any():  # left out: their means measure no geometry (erratic_poses); the summary names them
        keep = ~erratic[labels]
        renumber = np.cumsum(~erratic) - 1
        campaign = pose_means(measured[keep], renumber[labels[keep]], instrument_mm)
        return poses[~erratic], dataclasses.replace(campaign, left_out=tuple(int(i) for i in np.flatnonzero(erratic)))
    return poses, pose_means(measured, labels, instrument_mm)


def _robot_time(store, run_id: int) -> dict:
    """The run's robot time per measured pose sample (s): from its first to its last pose sample, over the samples
    between (the moves, settling and readings one more sample costs)."""
    times = sorted(s.t_s for s in _measured_pose_samples(store, run_id))
    if len(times) < 2:
        return {}
    return {
        "robot_time_s": float(times[-1] - times[0]),
        "seconds_per_sample": float((times[-1] - times[0]) / (len(times) - 1)),
    }


def _instrument_uncertainty_mm(settings: dict, run_id: int) -> float:
    """The standard uncertainty per axis of the delta4 run's instrument, from its stored settings (module doc)."""
    instrument = settings.get("instrument") or {}
    if instrument.get("u_mm"):
        return float(instrument["u_mm"])  # the camera spot sensor: its plane calibration's RMS
    half_width = (instrument.get("decoder") or {}).get("spot_half_width_mm")
    if half_width:
        return float(half_width) / math.sqrt(3.0)  # the laser grid: a uniform error over the detection window
    raise ConfigError(
        f"run {run_id}: its instrument settings state no uncertainty (settings.instrument.u_mm or "
        "decoder.spot_half_width_mm), expected --uncertainty-mm"
    )


def delta4_problem(store, run_id: int, uncertainty_mm: float | None) -> Problem:
    import numpy as np

    from bench.robots.delta4_wire import fine_from_settings, mapping_from_settings
    from motion import delta4
    from motion.delta4.calibration import (
        BASE_PARAMETERS,
        REGISTRATION,
        TOLERANCES,
        ForwardModel,
        attained_positions,
        prior_sigma,
    )

    settings = store.run(run_id).settings
    mapping_settings = (settings.get("robot") or {}).get("mapping")
    if mapping_settings is None:
        raise ConfigError(
            f"run {run_id}: settings.robot.mapping is missing, expected the servo mapping the run "
            "commanded by (its bytes are the angles the servos were sent)"
        )
    mapping = mapping_from_settings(mapping_settings)
    fine_settings = (settings.get("robot") or {}).get("fine_reference") or {}
    if fine_settings.get("in_use"):  # the run sent fine references (the controller answered the probe)
        mapping = fine_from_settings(fine_settings)
    commanded, measured, mask = _pose_samples(store, run_id, "delta4")
    ik = delta4.inverse_kinematics(commanded, _commanded_geometry(store, run_id, delta4.NOMINAL))
    if not ik.reachable.all():
        first = int(np.flatnonzero(~ik.reachable)[0])
        raise InsufficientData(
            f"run {run_id}: commanded position {commanded[first].tolist()} is not reachable "
            f"({ik.reason[first]}), expected the positions the run commanded"
        )
    servo = mapping.sent_deg(ik.servo_deg)
    read = tuple(int(a) for a in np.flatnonzero(mask.any(axis=0)))
    registration = tuple(REGISTRATION[a] for a in read)
    u = _instrument_uncertainty_mm(settings, run_id) if uncertainty_mm is None else uncertainty_mm
    # the byte steps alone: where the servos' sent angles put the documented robot, against the angles asked for
    rounding = attained_positions(servo) - attained_positions(ik.servo_deg)
    extra = {
        "command_resolution_mm": float(np.mean(np.linalg.norm(rounding[:, read], axis=1))),
        "servo_mapping": mapping_settings,
        "servo_references": mapping.name,
    }
    prior = {
        "prior": prior_sigma,
        "prior_source": {
            "name": "manufacturing tolerances (motion.delta4.calibration.TOLERANCES; servo axis "
            "positions sqrt 2 of it, measured from the frame legs 1 and 4 fix)",
            "sigma": dict(TOLERANCES),
        },
    }
    if mask[:, read].all():  # every sample read the same axes (the camera's plane): per-position means
        positions, campaign = _campaign(np.column_stack([commanded, servo]), measured[:, read], u)
        servo = positions[:, commanded.shape[1] :]
        extra["campaign"] = {**campaign.as_dict(), **_robot_time(store, run_id)}
        return Problem(
            lambda free: ForwardModel(servo, free, axes=read),
            registration + BASE_PARAMETERS,
            registration,
            campaign.mean_mm,
            campaign.uncertainty_mm,
            np.arange(len(servo)),
            len(servo),
            extra,
            campaign=campaign,
            **prior,
        )
    rows = np.nonzero(mask)[0]
    return Problem(
        lambda free: ReadAxes(ForwardModel(servo, free, axes=(0, 1, 2)), mask),
        registration + BASE_PARAMETERS,
        registration,
        measured[mask][:, None],
        u,
        rows,
        len(measured),
        extra,
        **prior,
    )


def mean_error_mm(problem: Problem, residuals) -> float:
    """Mean over the samples of |measured - predicted| over each sample's read axes."""
    import numpy as np

    squares = np.zeros(problem.n_samples)
    np.add.at(squares, problem.sample_of, np.sum(np.asarray(residuals) ** 2, axis=1))
    return float(np.mean(np.sqrt(squares)))
