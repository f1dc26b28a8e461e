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

How a run of each robot becomes an identification problem (the joints it received, the axes read, the
instrument's uncertainty): :mod:`bench.calibration.problems`; the text ``bench calibrate`` prints:
:mod:`bench.calibration.summary`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bench.calibration.compensate import calibration_name
from bench.calibration.problems import (
    DEFAULT_UNCERTAINTY_MM,
    MEASURED,
    check_uncertainty,
    delta4_problem,
    mean_error_mm,
    pkm5_problem,
)
from bench.calibration.summary import summary_lines
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
    "delta4_problem",
    "identify_run",
    "pkm5_problem",
    "summary_lines",
]

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


def _separation_advice(separation: float, where: str = "") -> str:
    """What an ambiguous fit's refusal adds. The two solutions' predictions differ by ``separation`` (chi^2 over the
    readings); measured, it stays ~1 as the cycles grow (true-geometry seed 76: 0.68 with 1 cycle, 0.90 with 8):
    each solution refits the better data, so the difference lies where these poses see nothing and only the poses
    can resolve it: ``where`` names the workspace poses where they differ most (followed, seed 33 was stored)."""
    return (
        f"; these poses cannot tell them apart (their predictions differ by chi^2 {separation:.2g} over all the "
        "readings) and more cycles do not change that: "
        + (
            f"add poses where they differ most: {where}"
            if where
            else "add poses that move the named parameters (other orientations, the workspace's edges)"
        )
    )


def _resolved_or_refused(problem, chosen, exc):
    """An ambiguous fit (two plausible, distinct solutions) stored when, at every pose of a sample of the robot's
    workspace, the two predict positions within the best one's own stated uncertainty of prediction at k = 2
    (:func:`bench.metrology.kinematic_search.rival_apart`: commanding by it is then as good as it claims whichever
    is true), with each parameter's uncertainty widened to cover the rival
    (:func:`bench.metrology.kinematic_search.covering_rival`); else refused, naming the workspace poses where they
    differ most (measuring those resolves it). Returns the search, the identification to store and the stored
    ``ambiguity`` record."""
    import numpy as np

    from bench.metrology.kinematic_search import covering_rival, rival_apart

    best, rival = exc.search.best, exc.rival
    if problem.workspace is None:
        raise type(exc)(f"{exc}{_separation_advice(exc.separation)}", exc.separation) from None
    poses, model = problem.workspace(chosen)
    apart, beyond = rival_apart(best, rival, model)
    if not np.all(beyond <= 1.0):
        where = ", ".join(
            f"[{', '.join(f'{v:g}' for v in poses[i])}] ({apart[i]:.3g} mm apart, {beyond[i]:.2g} times the k = 2 "
            "uncertainty there)"
            for i in np.argsort(-np.nan_to_num(beyond, nan=np.inf))[:3]
        )
        raise type(exc)(f"{exc}{_separation_advice(exc.separation, where)}", exc.separation) from None
    z = np.abs(rival.values - best.values) / best.uncertainty
    record = {
        "rival": {n: float(v) for n, v in zip(best.names, rival.values)},
        "workspace_difference_mm": float(apart.max()),
        "workspace_difference_of_k2_uncertainty": float(beyond.max()),
        "workspace_poses": len(poses),
        "widened": [n for n, zj in zip(best.names, z) if zj > 1.0],
    }
    return exc.search, covering_rival(best, rival), record


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
    before_mm = mean_error_mm(problem, frame_only.residuals)
    prior_sigma = problem.prior(chosen) if fit == "map" else None
    plan = (
        None
        if problem.campaign is None or prior_sigma is None
        else plan_campaign(
            problem.model(chosen).jacobian(np.zeros(len(chosen))), problem.campaign, prior_sigma, before_mm, target_gain
        )
    )
    search, ambiguity = None, None
    try:
        if fit == "map":  # several starts from the prior: a local solver may stop in a wrong basin (kinematic_search)
            search = identify_global(problem.model(chosen), problem.measured, u, prior_sigma=prior_sigma, seed=run_id)
            result = search.best
        else:
            result = identify(problem.model(chosen), problem.measured, u, prior_sigma=prior_sigma)
    except AmbiguousFit as exc:
        search, result, ambiguity = _resolved_or_refused(problem, chosen, exc)
    except UnidentifiableParameters as exc:
        raise type(exc)(f"{exc}{_cycles_advice(plan, problem.campaign)}") from None
    _refuse_if_inconsistent(result, problem.campaign.instrument_mm if problem.campaign else u, run_id, problem.campaign)
    params = {
        **result.as_dict(),
        "prior": problem.prior_source if fit == "map" else None,
        "robot": run.robot,
        "uncertainty_mm": problem.campaign.instrument_mm if problem.campaign else u,
        "ap_before_mm": before_mm,
        "ap_after_mm": mean_error_mm(problem, result.residuals),
        **problem.extra,
    }
    if search is not None:
        params["search"] = search.as_dict()
    if ambiguity:
        params["ambiguity"] = ambiguity
    if plan is not None:
        params["campaign"] = {**params["campaign"], "plan": plan.as_dict()}
    settings = run.settings
    serial = (settings.get("dut") or {}).get("dut_serial")
    if serial:  # the calibration belongs to this robot: runs of other robots never use it by default
        params["dut_serial"] = serial
    # how the poses were arrived at: the legs' backlash is in the identified offsets for that approach only
    params["approach_from_below_mm"] = float(run.config.get("approach_from_below_mm") or 0.0)
    if "simulator" in settings:  # a simulated robot's geometry: never in force on hardware
        params["simulated"] = True
    record = store.add_calibration(name, params, source_run_id=run_id, notes=f"bench calibrate {run_id}")
    return IdentifiedRun(run_id, record, result, params, problem.n_samples)
