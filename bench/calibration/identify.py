"""Identify a robot's geometry from a stored run: the function behind ``bench calibrate RUN_ID`` and the window's
"Identify" button, for the pkm5 and the delta4.

Reads the run's pose samples (commanded ``cmd_x_mm ..``, measured ``x_mm, y_mm, z_mm``: the axes the instrument
read), rebuilds the joints the robot received with the geometry the run commanded by (the documented one, or the
calibrated one of the kinematic calibration that was in force), identifies the parameters and stores
the result as a new version of the robot's calibration (``pkm5_kinematics``, ``delta4_kinematics``) with the source
run, the residuals, the observability, the fit and its prior (docs/calibration.md). Fits (``fit``):

* ``map`` (the default): maximum a posteriori of every parameter and the
  registration, the manufacturing tolerances (:data:`motion.pkm5.calibration.TOLERANCES`,
  :data:`motion.delta4.calibration.TOLERANCES`) as the prior (:func:`bench.metrology.kinematic_calibration.identify`);
  ``free`` given, of those and the registration only;
* ``free-set`` (the default where ``--free`` names parameters): least squares of the free
  parameters, default what the pose set and instrument can identify
  (:func:`bench.metrology.kinematic_calibration.identifiable_subset`), the others held at their documented values.

Campaign (:mod:`bench.metrology.kinematic_campaign`): the samples of one commanded pose are fitted by their mean,
weighted by its measured scatter of the mean (the instrument's stated uncertainty, ``--uncertainty-mm``, a floor);
an erratic pose is left out and named; the stored ``campaign`` keeps the robot's scatter apart from the
instrument's figure, with the run's robot time and the plan of cycles per pose for ``target_gain``. The ``map``
fit starts from the documented geometry and 7 prior draws (:func:`bench.metrology.kinematic_search.identify_global`:
the best kept, two plausible distinct solutions refused).

The in-sample mean position error before is that of
the documented geometry with only the registration fitted: ``mean_j |m_j - f(theta_reg)_j|`` over each sample's
measured axes, after ``mean_j |m_j - f(theta_hat)_j|``.

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
import math
from dataclasses import dataclass, field
from typing import Any

from bench.calibration.compensate import calibration_name
from bench.errors import ConfigError, InsufficientData
from bench.robot_kinds import robot_kind

__all__ = [
    "DEFAULT_TARGET_GAIN",
    "DEFAULT_UNCERTAINTY_MM",
    "FITS",
    "IdentifiedRun",
    "InconsistentFit",
    "MEASURED",
    "check_fit",
    "check_uncertainty",
    "identify_run",
    "summary_lines",
]

MEASURED = ("x_mm", "y_mm", "z_mm")
#: The mice's standard uncertainty per axis, mm (the pkm5 calibration protocol's pose selection assumes it).
DEFAULT_UNCERTAINTY_MM = 0.05
#: The gain a campaign plan is made for unless told (``bench calibrate --target-gain``).
DEFAULT_TARGET_GAIN = 5.0
#: The identification fits (module doc); the first is the default where the robot has a prior (both robots have).
FITS = ("map", "free-set")


@dataclass(frozen=True)
class IdentifiedRun:
    """What :func:`identify_run` stored: the calibration record, the identification and the stored parameters."""

    run_id: int
    record: Any  # bench.store CalibrationRecord
    result: Any  # bench.metrology.kinematic_calibration.Identification
    params: dict
    n_measurements: int


@dataclass(frozen=True)
class _Problem:
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


class _ReadAxes:
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


def pkm5_problem(store, run_id: int, uncertainty_mm: float | None) -> _Problem:
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
    return _Problem(
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
    )


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


def delta4_problem(store, run_id: int, uncertainty_mm: float | None) -> _Problem:
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
        return _Problem(
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
    return _Problem(
        lambda free: _ReadAxes(ForwardModel(servo, free, axes=(0, 1, 2)), mask),
        registration + BASE_PARAMETERS,
        registration,
        measured[mask][:, None],
        u,
        rows,
        len(measured),
        extra,
        **prior,
    )


def _mean_error_mm(problem: _Problem, residuals) -> float:
    """Mean over the samples of |measured - predicted| over each sample's read axes."""
    import numpy as np

    squares = np.zeros(problem.n_samples)
    np.add.at(squares, problem.sample_of, np.sum(np.asarray(residuals) ** 2, axis=1))
    return float(np.mean(np.sqrt(squares)))


class InconsistentFit(InsufficientData):
    """The fit leaves residuals the stated instrument uncertainty cannot explain: its uncertainties would be
    understated, so it is not stored."""


def _refuse_if_inconsistent(result, uncertainty_mm: float, run_id: int, campaign=None) -> None:
    """Refuse a fit whose reduced chi^2 an honest one would exceed once in a million
    (:func:`bench.metrology.kinematic_calibration.reduced_chi2_limit`). Decision: such a calibration is not stored
    with a warning. Its parameter uncertainties come from the stated instrument uncertainty, which the residuals
    show is wrong (or the model misses an error source), so every uncertainty it would print and put in force is
    too small. The line says what to do: state the real uncertainty (the residuals suggest ``u sqrt(chi^2)``; the fit
    is then stored with honest uncertainties) or free what the model holds."""
    from bench.metrology.kinematic_calibration import reduced_chi2_limit

    limit = reduced_chi2_limit(result.degrees_of_freedom)
    if not result.reduced_chi2 > limit:
        return
    ratio = float(result.reduced_chi2**0.5)
    if campaign is not None and campaign.scatter_dof > 0 and (campaign.scatter_mm > campaign.instrument_mm).any():
        # weighted by the measured scatter, not by the stated figure
        raise InconsistentFit(
            f"run {run_id}: the pose means differ from the fitted model by {ratio:.3g} times their measured "
            f"scatter of the mean (reduced chi^2 {result.reduced_chi2:.3g} over {result.degrees_of_freedom:.3g} "
            f"degrees of freedom, above the {limit:.3g} an honest fit exceeds once in a million); nothing stored. "
            "The scatter is measured, so a larger stated uncertainty is not the cure: the robot errs in a way the "
            "geometric model lacks (backlash larger than the play, a loose or slipping joint, a load, a drifting "
            "instrument mount); check the per-pose residuals (--json) and the robot"
        )
    free_more = "" if result.fit == "map" else ", free what the fit held (--fit map frees every parameter)"
    raise InconsistentFit(
        f"run {run_id}: the fit leaves residuals {ratio:.3g} times the stated uncertainty {uncertainty_mm:.3g} mm "
        f"(reduced chi^2 {result.reduced_chi2:.3g} over {result.degrees_of_freedom:.3g} degrees of freedom, above "
        f"the {limit:.3g} an honest fit exceeds once in a million), so its uncertainties would be understated; "
        f"nothing stored. State the instrument's real uncertainty (--uncertainty-mm {uncertainty_mm * ratio:.2g})"
        f"{free_more} or check the run for an error source the model lacks"
    )


def _cycles_advice(plan, campaign) -> str:
    """What a refusal for too little information adds: the cycles per pose with which the measured scatter would
    inform the fit (the plan), or that none would (then the poses, not the cycles, are short)."""
    from bench.metrology.kinematic_campaign import MAX_CYCLES

    if plan is None or campaign is None:
        return ""
    now = int(round(float(campaign.cycles.mean())))
    if plan.informing_cycles is None or plan.informing_cycles <= now:
        return (
            (
                f" (more cycles would not help: with the measured scatter even {MAX_CYCLES} cycles per pose leave "
                "the data short; it is the poses)"
            )
            if plan.informing_cycles is None
            else ""
        )
    wanted = max(plan.calibration_cycles or MAX_CYCLES, plan.informing_cycles)
    return (
        f". Here the cycles are short, not the poses: with the measured scatter ({plan.scatter_mm:.2g} mm a "
        f"reading) the poses inform half the parameters from {plan.informing_cycles} cycles per pose (this run: "
        f"{now}); measure {wanted} cycles per pose (the plan for a {plan.target_gain:g}x gain; set cycles in the "
        "protocol file)"
    )


def _separation_advice(separation: float) -> str:
    """What an ambiguous fit's refusal adds. The two solutions' predictions differ by ``separation`` (chi^2 over the
    readings); measured, it stays ~1 as the cycles grow (true-geometry seed 76: 0.68 with 1 cycle, 0.90 with 8):
    each solution refits the better data, so the difference lies where these poses see nothing and only the poses
    can resolve it."""
    return (
        f"; these poses cannot tell them apart (their predictions differ by chi^2 {separation:.2g} over all the "
        "readings) and more cycles do not change that: add poses that move the named parameters (other "
        "orientations, the workspace's edges)"
    )


def check_fit(fit: str | None) -> None:
    """Refuse an unknown fit name (one line); None: the robot's default."""
    if fit is not None and fit not in FITS:
        raise ConfigError(f"--fit = {fit!r}, expected one of {', '.join(FITS)}")


def identify_run(
    store: Any,
    run_id: int,
    *,
    free: list[str] | tuple[str, ...] | None = None,
    uncertainty_mm: float | None = None,
    fit: str | None = None,
    target_gain: float = DEFAULT_TARGET_GAIN,
) -> IdentifiedRun:
    """Identify from run ``run_id`` of the open ``store`` and store a new version of its robot's kinematic
    calibration (module doc). ``uncertainty_mm`` None: the instrument's; ``fit`` None: ``map`` where the robot has
    a prior and no ``free`` names are given, else ``free-set`` (module doc). ``target_gain``: the gain the stored
    campaign plan (cycles per pose, robot time) is made for.

    A run without measured poses raises ``InsufficientData``, an ill-conditioned pose set
    ``UnidentifiableParameters``, a robot without a calibration model or a fit it lacks ``ConfigError`` (all one
    line)."""
    import numpy as np

    from bench.metrology.kinematic_calibration import UnidentifiableParameters, identifiable_subset, identify
    from bench.metrology.kinematic_campaign import plan_campaign
    from bench.metrology.kinematic_search import AmbiguousFit, identify_global

    check_uncertainty(uncertainty_mm)
    check_fit(fit)
    run = store.run(run_id)
    name = calibration_name(run.robot)
    problem = robot_kind(run.robot).resolved("calibration_problem")(store, run_id, uncertainty_mm)
    if fit is None:
        fit = "map" if problem.prior is not None and not free else "free-set"
    if fit == "map" and problem.prior is None:
        raise ConfigError(f"--fit map: the {run.robot} has no tolerance prior, expected --fit free-set")
    if free:
        chosen = problem.required + tuple(n for n in free if n not in problem.required)
    elif fit == "map":
        chosen = problem.candidates
    else:
        candidates = problem.candidates
        jac = problem.model(candidates).jacobian(np.zeros(len(candidates)))
        chosen = identifiable_subset(jac, problem.uncertainty_mm, candidates, required=problem.required)
    u = problem.uncertainty_mm
    frame_only = identify(problem.model(problem.required), problem.measured, u)
    before_mm = _mean_error_mm(problem, frame_only.residuals)
    prior_sigma = problem.prior(chosen) if fit == "map" else None
    plan = (
        None
        if problem.campaign is None or prior_sigma is None
        else plan_campaign(
            problem.model(chosen).jacobian(np.zeros(len(chosen))), problem.campaign, prior_sigma, before_mm, target_gain
        )
    )
    search = None
    try:
        if fit == "map":  # several starts from the prior: a local solver may stop in a wrong basin (kinematic_search)
            search = identify_global(problem.model(chosen), problem.measured, u, prior_sigma=prior_sigma, seed=run_id)
            result = search.best
        else:
            result = identify(problem.model(chosen), problem.measured, u, prior_sigma=prior_sigma)
    except AmbiguousFit as exc:
        raise AmbiguousFit(f"{exc}{_separation_advice(exc.separation)}", exc.separation) from None
    except UnidentifiableParameters as exc:
        raise type(exc)(f"{exc}{_cycles_advice(plan, problem.campaign)}") from None
    _refuse_if_inconsistent(result, problem.campaign.instrument_mm if problem.campaign else u, run_id, problem.campaign)
    params = {
        **result.as_dict(),
        "prior": problem.prior_source if fit == "map" else None,
        "robot": run.robot,
        "uncertainty_mm": problem.campaign.instrument_mm if problem.campaign else u,
        "ap_before_mm": before_mm,
        "ap_after_mm": _mean_error_mm(problem, result.residuals),
        **problem.extra,
    }
    if search is not None:
        params["search"] = search.as_dict()
    if plan is not None:
        params["campaign"] = {**params["campaign"], "plan": plan.as_dict()}
    settings = run.settings
    serial = (settings.get("dut") or {}).get("dut_serial")
    if serial:  # the calibration belongs to this robot: runs of other robots never use it by default
        params["dut_serial"] = serial
    if "simulator" in settings:  # a simulated robot's geometry: never in force on hardware
        params["simulated"] = True
    record = store.add_calibration(name, params, source_run_id=run_id, notes=f"bench calibrate {run_id}")
    return IdentifiedRun(run_id, record, result, params, problem.n_samples)


def summary_lines(identified: IdentifiedRun) -> list[str]:
    """The text ``bench calibrate`` prints (and the window shows): parameters, uncertainties, observability."""
    from bench.metrology.formatting import format_pair

    result, record, params = identified.result, identified.record, identified.params
    obs = result.observability
    lines = [
        f"{record.name} v{record.version} (id {record.id}) from run {identified.run_id}: "
        f"{identified.n_measurements} poses, {len(result.names)} free parameters",
        f"{'parameter':<18} {'value':>12} {'std. unc.':>12}  unit",
    ]
    for name, value, std, unit in zip(result.names, result.values, result.uncertainty, result.units):
        shown, u = format_pair(value, std, signed=True)  # to the uncertainty's 2 significant digits, as the report
        lines.append(f"{name:<18} {shown:>12} {u:>12}  {unit}")
    if result.fit == "map":
        source = params.get("prior") or {}
        lines.append(
            f"fit: maximum a posteriori, prior: {source.get('name', 'the tolerances')}; fixed by the prior "
            f"(the data did not inform them): {', '.join(result.prior_only) or 'none'}"
        )
        lines.append(
            f"data part: condition number {obs.condition_number:.3g} (the prior holds its weak directions; "
            f"refused when the data inform under half the parameters), O1 {obs.o1:.4g}, reduced chi2 "
            f"{result.reduced_chi2:.2f} over {result.degrees_of_freedom:.1f} degrees of freedom"
        )
    else:
        lines.append(
            f"condition number {obs.condition_number:.1f} (limit 100), O1 {obs.o1:.4g}, reduced chi2 "
            f"{result.reduced_chi2:.2f}"
        )
    lines.append(
        f"mean position error on the calibration poses (in-sample): before {params['ap_before_mm']:.3f} "
        f"mm, after {params['ap_after_mm']:.3f} mm"
    )
    lines += _campaign_lines(params)
    if "command_resolution_mm" in params:
        steps = (
            "fine steps (0.01 deg references)"
            if params.get("servo_references") == "fine_centidegree"
            else f"byte steps ({params['servo_mapping']['name']} mapping)"
        )
        lines.append(
            f"command resolution: the servos' {steps} move these poses by "
            f"{params['command_resolution_mm']:.3f} mm on average, which no compensation goes below"
        )
    return lines


def _campaign_lines(params: dict) -> list[str]:
    """The campaign's part of the summary: the robot's scatter apart from the instrument's figure, the search, the
    plan for the target gain (cycles per pose, robot time) and the gain the play lets a validation show."""
    campaign, lines = params.get("campaign"), []
    search = params.get("search")
    if search:
        lines.append(
            f"search: {search['starts']} starts from the prior, kept start {search['kept_start']} "
            "(lowest MAP objective; no other plausible solution differs beyond 5 standard uncertainties)"
        )
    if not campaign:
        return lines
    cycles = campaign["cycles_per_pose"]
    scatter = campaign["scatter_mm"]
    shown = (
        "not measured (one reading per pose)"
        if scatter[0] is None
        else ", ".join(f"{s:.3f}" for s in scatter) + f" mm per axis ({campaign['scatter_dof']} degrees of freedom)"
    )
    lines.append(
        f"robot scatter of one reading: {shown}; instrument: {campaign['instrument_uncertainty_mm']:.3g} mm "
        f"(stated, the floor); {min(cycles)}-{max(cycles)} cycles per pose, so each pose's mean is "
        f"uncertain by {', '.join(f'{u:.3f}' for u in campaign['mean_uncertainty_mm'])} mm (RMS per axis)"
    )
    if campaign.get("left_out_poses"):
        lines.append(
            "left out, erratic (a scatter beyond the other poses', F-test at 1e-6; their means measure no "
            "geometry): the poses visited "
            + ", ".join(f"#{i + 1}" for i in campaign["left_out_poses"])
            + " first-visit order"
        )
    plan, per_sample = campaign.get("plan"), campaign.get("seconds_per_sample")
    if plan:
        poses = len(cycles)

        def robot_time(n):
            clock = " by the simulator's clock" if params.get("simulated") else ""
            return "" if per_sample is None else f", {n * poses * per_sample / 60:.0f} min of robot time{clock}"

        wanted = plan["calibration_cycles"]
        lines.append(
            f"plan for {plan['target_gain']:g}x over the {plan['geometric_error_mm']:.3f} mm the geometry explains: "
            + (f"{wanted} cycles per pose{robot_time(wanted)}" if wanted else "out of reach by cycles")
            + (
                f"; a validation run needs {plan['validation_cycles']} cycles per pose to show it (the measured "
                f"scatter, {plan['scatter_mm']:.2f} mm a reading over the axes)"
                if plan["validation_cycles"]
                else ""
            )
        )
    return lines
