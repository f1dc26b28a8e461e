"""Kinematic identification: weighted least squares, parameter uncertainties, observability and pose selection.

Robot-agnostic: a *model* has ``free`` (parameter names), ``units``, ``predict(theta) -> (N, a)`` measured
coordinates and ``jacobian(theta) -> (N, a, K)`` (e.g. :class:`motion.pkm5.calibration.ForwardModel`). Pure
computation, arrays in and arrays out.

Method (methods-turn2.md §1.1-1.2): residuals ``r = (m - f(theta)) / u`` weighted by the instrument's standard
uncertainty ``u`` per coordinate, minimised by :func:`scipy.optimize.least_squares`. With the weighted Jacobian
``J_w`` at the solution the covariance is ``(J_w^T J_w)^{-1}`` (GUM: the instrument's uncertainty is known, type B,
so it is not rescaled by the residuals; the reduced chi^2 is reported as the check), the standard uncertainties its
diagonal's square roots and the correlations ``C_ij / (u_i u_j)``.

Observability uses the *scaled* Jacobian ``J_s`` (columns of ``J_w`` divided by their RMS over the m poses, so units
drop out) and its
singular values sigma_1 >= ... >= sigma_L: the condition number sigma_1 / sigma_L (Schroer et al.: below 100 for
reliable results) and the O1 index of Borm & Menq, ``(sigma_1 ... sigma_L)^{1/L} / sqrt(m)`` with L parameters and
m poses (invariant to repeating the pose set). Right singular vectors of the singular values below sigma_1 / 100
name the parameter combinations the pose set cannot identify.

Maximum a posteriori (``identify(..., prior_sigma=...)``, the pkm5's default fit): the manufacturing tolerances
``sigma_j`` as a zero-mean Gaussian prior on the deviations (``inf``: no prior, e.g. a registration): rows
``theta_j / sigma_j`` appended to the weighted residuals (Tikhonov weighted by the prior, Tarantola 2005 §3.2),
posterior covariance ``(J_w^T J_w + diag(sigma^-2))^{-1}``. Every parameter can then be free: what the pose set
cannot identify the prior holds near its documented value, with an honest (prior-sized) uncertainty, instead of
the identified parameters absorbing it with a bias. The refusal rule restated for a posterior (applied at the start
and at the solution): the observability above describes the *data part* ``J_w`` and is reported; a parameter with
a prior is *fixed by the prior* when the data carry less information on it than the prior, i.e. its posterior
standard uncertainty exceeds ``sigma_j / sqrt(2)`` (named in the result, ``prior_only``); the fit is refused
(:class:`UnidentifiableParameters`, naming them) when the data inform fewer than half of the parameters with a
prior (the result would be the drawing, not a measurement: poses on one line inform none of the pkm5's 36), or
when the parameters without a prior have a data-part condition number above the limit (only the data fix them).
The reduced chi^2 divides the data residuals' chi^2 by their degrees of freedom ``m - tr(H)``, ``H = J_w C J_w^T``
the hat matrix, ``tr(H) = K - sum_j C_jj / sigma_j^2`` the parameters the data fit (``K`` without a prior, as for
least squares; less for a MAP fit, since a parameter the prior holds costs the data nothing): its expectation is 1
when the instrument's uncertainty and the prior are right (chi^2 per coordinate, ``/ m``, would be below 1 by the
share of the parameters the data fit).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import qr
from scipy.optimize import least_squares

from bench.errors import ConfigError, InsufficientData

__all__ = [
    "CHI2_FALSE_ALARM",
    "CONDITION_LIMIT",
    "FOLD_MARGIN",
    "FREE_SET_LIMIT",
    "Identification",
    "MIN_INFORMED_SHARE",
    "Observability",
    "PRIOR_ONLY_RATIO",
    "UnidentifiableParameters",
    "away_from_folds",
    "identifiable_subset",
    "identify",
    "observability",
    "parameter_covariance",
    "reduced_chi2_limit",
    "select_poses",
]

#: Largest condition number of the scaled identification Jacobian that is accepted (Schroer et al., in Nahvi &
#: Hollerbach 1996: "a condition number below 100 is required for reliable results").
CONDITION_LIMIT = 100.0
_SHOWN_WEIGHT = 0.2  # components of a null-space vector smaller than this are left out of its description
#: A parameter with a prior is fixed by the prior (the data did not inform it) when its posterior standard
#: uncertainty exceeds this fraction of the prior's: the data then carry less information on it than the prior.
PRIOR_ONLY_RATIO = 1.0 / np.sqrt(2.0)
#: A maximum a posteriori fit is refused when the data inform fewer than this share of the parameters with a prior.
MIN_INFORMED_SHARE = 0.5
#: Pose selection leaves out candidates whose FK fold ratio is below this fraction of the candidates' median.
FOLD_MARGIN = 0.01
#: A fit whose reduced chi^2 an honest fit (the instrument's stated uncertainty right, the model complete) exceeds
#: with at most this probability is inconsistent: its parameter uncertainties, computed from the stated uncertainty,
#: would be understated (:func:`reduced_chi2_limit`).
CHI2_FALSE_ALARM = 1e-6


class UnidentifiableParameters(ConfigError):
    """The pose set and instrument cannot identify some free parameters (condition number above the limit)."""


@dataclass(frozen=True)
class Observability:
    """Singular-value analysis of a scaled identification Jacobian (module docstring)."""

    names: tuple[str, ...]
    singular_values: np.ndarray
    condition_number: float
    o1: float
    n_poses: int
    unidentifiable: tuple[str, ...]  # "name" or "0.71 a + 0.71 b" per weak direction, weakest first

    def as_dict(self) -> dict[str, Any]:
        return {
            "names": list(self.names),
            "singular_values": [float(s) for s in self.singular_values],
            "condition_number": float(self.condition_number),
            "o1": float(self.o1),
            "n_poses": self.n_poses,
            "unidentifiable": list(self.unidentifiable),
        }


def _weighted(jac: ArrayLike, uncertainty: ArrayLike) -> np.ndarray:
    """``jac`` (N, a, K) over the standard uncertainty of each coordinate ((a,) per axis or (N, a) per pose and
    axis), rows stacked (N a, K)."""
    jac = np.asarray(jac, dtype=float)
    u = np.broadcast_to(np.asarray(uncertainty, dtype=float), jac.shape[:2])
    return (jac / u[:, :, None]).reshape(-1, jac.shape[-1])


def _finite_weighted(jac: ArrayLike, uncertainty: ArrayLike) -> np.ndarray:
    """:func:`_weighted`, refused (``InsufficientData``, one line) where the model could not give a Jacobian."""
    weighted = _weighted(jac, uncertainty)
    if not np.all(np.isfinite(weighted)):
        raise InsufficientData("identification Jacobian is not finite (forward kinematics failed at some pose)")
    return weighted


def observability(
    jac: ArrayLike, uncertainty: ArrayLike, names: Sequence[str], limit: float = CONDITION_LIMIT
) -> Observability:
    """Observability of parameters ``names`` from the Jacobian ``jac`` (N, a, K) and instrument uncertainty (a,)."""
    names = tuple(names)
    weighted = _finite_weighted(jac, uncertainty)
    n_poses = len(np.asarray(jac))
    norms = np.linalg.norm(weighted, axis=0) / np.sqrt(n_poses)  # RMS per pose, so repeating the set scales J_s
    dead = norms <= 1e-12 * max(norms.max(initial=0.0), 1e-300)
    scaled = weighted / np.where(dead, 1.0, norms)
    _, sv, vt = np.linalg.svd(scaled, full_matrices=False)
    with np.errstate(divide="ignore"):
        condition = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
        o1 = float(np.exp(np.mean(np.log(sv))) / np.sqrt(n_poses)) if sv[-1] > 0 else 0.0
    weak = [f"{names[j]} (no effect on the measurements)" for j in np.flatnonzero(dead)]
    for i in range(len(sv) - 1, -1, -1):
        if sv[i] * limit >= sv[0]:
            break
        v = vt[i] / np.abs(vt[i]).max()
        shown = [j for j in np.argsort(-np.abs(v)) if abs(v[j]) >= _SHOWN_WEIGHT and not dead[j]]
        if len(shown) == 1:
            weak.append(names[shown[0]])
        elif shown:
            weak.append(" ".join(f"{'+' if v[j] > 0 else '-'}{abs(v[j]):.2f}*{names[j]}" for j in shown).lstrip("+"))
    return Observability(names, sv, condition, o1, n_poses, tuple(dict.fromkeys(weak)))


def reduced_chi2_limit(degrees_of_freedom: float, false_alarm: float = CHI2_FALSE_ALARM) -> float:
    """The reduced chi^2 that an honest fit with ``nu`` degrees of freedom exceeds with probability ``false_alarm``:
    ``chi2.isf(p, nu) / nu = 2 Q^-1(nu / 2, p) / nu``, with ``Q^-1`` the inverse of the regularised upper incomplete
    gamma function (the chi^2 distribution's upper quantile, Press et al., Numerical Recipes 3rd ed. §6.2; ``nu`` may
    be fractional, as a MAP fit's ``m - tr(H)`` is). ``inf`` below one degree of freedom (nothing to test).

    >>> round(reduced_chi2_limit(60.0), 3)
    2.118
    """
    from scipy.special import gammainccinv

    nu = float(degrees_of_freedom)
    if not np.isfinite(nu) or nu < 1.0:
        return float("inf")
    return float(2.0 * gammainccinv(nu / 2.0, false_alarm) / nu)


def _refuse_if_poor(obs: Observability, limit: float) -> None:
    if obs.condition_number > limit:
        raise UnidentifiableParameters(
            f"kinematic calibration refused: condition number {obs.condition_number:.3g} > {limit:g}; the "
            f"{obs.n_poses} poses cannot identify {'; '.join(obs.unidentifiable) or 'the free set'}; fix these "
            "parameters (--free) or add poses that spread over the workspace and its orientations"
        )


def parameter_covariance(jac: ArrayLike, uncertainty: ArrayLike, precision: ArrayLike | None = None) -> np.ndarray:
    """``(J_w^T J_w + diag(precision))^{-1}`` (pseudo-inverse), the parameters' covariance for known instrument
    uncertainty; with a Gaussian prior's ``precision`` ``sigma_j^-2`` per parameter (0: none) the posterior one
    (module docstring). A Jacobian that is not finite is refused (``InsufficientData``, one line)."""
    weighted = _finite_weighted(jac, uncertainty)
    normal = weighted.T @ weighted
    return np.linalg.pinv(normal if precision is None else normal + np.diag(precision))


@dataclass(frozen=True)
class Identification:
    """Identified parameters (deviations from the nominal model) with uncertainties and diagnostics."""

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray  # (K,)
    uncertainty: np.ndarray  # (K,) standard uncertainties
    correlation: np.ndarray  # (K, K)
    residuals: np.ndarray  # (N, a) measured - predicted, instrument units
    residuals_before: np.ndarray  # (N, a) at theta0
    reduced_chi2: float
    observability: Observability
    iterations: int
    prior_sigma: np.ndarray | None = None  # (K,) the prior's 1-sigma per parameter (inf: none); None: no prior
    prior_only: tuple[str, ...] = ()  # parameters the prior alone fixes (posterior ~ prior)
    degrees_of_freedom: float = float("nan")  # of the data residuals, the reduced chi^2's divisor (module doc)

    @property
    def fit(self) -> str:
        """'map' (maximum a posteriori, with a prior) or 'free-set' (least squares of the free parameters)."""
        return "free-set" if self.prior_sigma is None else "map"

    def as_dict(self) -> dict[str, Any]:
        """Plain data (stored as the calibration's parameters)."""
        prior = (
            None
            if self.prior_sigma is None
            else {n: (None if np.isinf(s) else float(s)) for n, s in zip(self.names, self.prior_sigma)}
        )
        return {
            "fit": self.fit,
            "prior_sigma": prior,
            "prior_only": list(self.prior_only),
            "parameters": {
                n: {"value": float(v), "uncertainty": float(u), "unit": unit}
                for n, v, u, unit in zip(self.names, self.values, self.uncertainty, self.units)
            },
            "correlation": np.round(self.correlation, 6).tolist(),
            "residual_rms": float(np.sqrt(np.mean(self.residuals**2))),
            "residual_rms_before": float(np.sqrt(np.mean(self.residuals_before**2))),
            "residuals": np.round(self.residuals, 6).tolist(),
            "reduced_chi2": float(self.reduced_chi2),
            "degrees_of_freedom": float(self.degrees_of_freedom),
            "observability": self.observability.as_dict(),
            "iterations": self.iterations,
        }


def _prior_only(names: Sequence[str], std: np.ndarray, sigma: np.ndarray) -> tuple[str, ...]:
    return tuple(n for n, s, p in zip(names, std, sigma) if np.isfinite(p) and s > PRIOR_ONLY_RATIO * p)


def _refuse_if_uninformed(
    jac: ArrayLike,
    uncertainty: ArrayLike,
    names: Sequence[str],
    sigma: np.ndarray,
    std: np.ndarray,
    n_poses: int,
    limit: float,
) -> tuple[str, ...]:
    """The refusal rule of a maximum a posteriori fit (module docstring); returns the prior-only parameters."""
    free = np.flatnonzero(~np.isfinite(sigma))
    if free.size:
        _refuse_if_poor(
            observability(np.asarray(jac)[:, :, free], uncertainty, [names[int(j)] for j in free], limit), limit
        )
    prior_only = _prior_only(names, std, sigma)
    with_prior = int(np.sum(np.isfinite(sigma)))
    informed = with_prior - len(prior_only)
    if with_prior and informed < MIN_INFORMED_SHARE * with_prior:
        raise UnidentifiableParameters(
            f"kinematic calibration refused: the {n_poses} poses inform only {informed} of the {with_prior} "
            f"parameters with a prior (posterior uncertainty above {PRIOR_ONLY_RATIO:.2f} of the prior's for "
            f"{', '.join(prior_only)}), expected at least {MIN_INFORMED_SHARE:.0%}; the poses cannot identify "
            "them: add poses that spread over the workspace (and its orientations), read them with a finer "
            "instrument, or fit only what they identify (the free-set fit)"
        )
    return prior_only


def identify(
    model: Any,
    measured: ArrayLike,
    uncertainty: ArrayLike,
    *,
    theta0: ArrayLike | None = None,
    limit: float = CONDITION_LIMIT,
    prior_sigma: ArrayLike | None = None,
    check_start: bool = True,
) -> Identification:
    """Identification of ``model.free`` from ``measured`` (N, a) (module docstring): weighted least squares, or
    maximum a posteriori when ``prior_sigma`` (K,) gives each parameter's 1-sigma prior about 0 (``inf``: none).

    Raises :class:`UnidentifiableParameters` (one line naming the weak parameters or combinations), before and after
    the solve (``check_start`` False: after it only): without a prior when the scaled Jacobian's condition number
    exceeds ``limit``; with a prior by the restated rule of the module docstring. ``uncertainty``: per axis (a,) or
    per pose and axis (N, a).
    """
    measured = np.asarray(measured, dtype=float)
    if measured.ndim != 2 or len(measured) == 0:
        raise InsufficientData(f"measured has shape {measured.shape}, expected (N, a) with N >= 1 measured poses")
    if not np.all(np.isfinite(measured)):
        raise InsufficientData(
            f"measured poses: {int(np.sum(~np.isfinite(measured).all(1)))} rows are not finite, "
            "expected a measured coordinate for every pose"
        )
    u = np.broadcast_to(np.asarray(uncertainty, dtype=float), measured.shape)  # per axis or per pose and axis
    if not np.all((u > 0) & np.isfinite(u)):
        raise ConfigError(f"instrument uncertainty = {np.asarray(uncertainty).tolist()}, expected finite values > 0")
    k = len(model.free)
    sigma = None if prior_sigma is None else np.broadcast_to(np.asarray(prior_sigma, dtype=float), (k,))
    if sigma is not None and not np.all(sigma > 0):
        raise ConfigError(f"prior_sigma = {sigma.tolist()}, expected values > 0 (inf: no prior)")
    constrained = 0 if sigma is None else int(np.sum(np.isfinite(sigma)))
    if measured.size + constrained <= k:
        raise InsufficientData(
            f"{len(measured)} measured poses give {measured.size} coordinates for {k} free "
            "parameters; expected more coordinates than parameters"
        )
    theta0 = np.zeros(k) if theta0 is None else np.asarray(theta0, dtype=float)
    before = measured - model.predict(theta0)
    failed = np.flatnonzero(~np.all(np.isfinite(before), axis=1))
    if failed.size:
        raise InsufficientData(
            f"forward kinematics failed at {failed.size} measured poses (first: pose "
            f"{failed[0]}); expected commanded steps the model can solve"
        )
    precision = np.zeros(k) if sigma is None else np.where(np.isfinite(sigma), 1.0 / np.square(sigma), 0.0)
    weight = np.sqrt(precision)

    def check(jac: ArrayLike) -> tuple[Observability | None, np.ndarray, tuple[str, ...]]:
        """The refusal rule at ``jac``: the observability (a prior's: None, reported at the solution only), the
        covariance and the prior-only parameters."""
        if sigma is None:
            obs = observability(jac, u, model.free, limit)
            _refuse_if_poor(obs, limit)
            return obs, parameter_covariance(jac, u), ()
        cov = parameter_covariance(jac, u, precision)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        return None, cov, _refuse_if_uninformed(jac, u, model.free, sigma, std, len(measured), limit)

    latest: list[Any] = [None, None]  # (theta, model Jacobian) of the latest Jacobian: the solver asks at theta0 and
    # at its solution, where the checks need it too

    def model_jacobian(theta: ArrayLike) -> np.ndarray:
        if latest[0] is None or not np.array_equal(latest[0], theta):
            latest[:] = [np.array(theta), model.jacobian(theta)]  # poses solved at theta (the last fun call may
            # be a rejected trial)
        return latest[1]

    if check_start:  # a search's other starts (kinematic_search) are judged at their solution only
        check(model_jacobian(theta0))

    def residual(theta: np.ndarray) -> np.ndarray:
        r = np.nan_to_num((measured - model.predict(theta)) / u, nan=1e6).ravel()
        return r if sigma is None else np.concatenate([r, weight * theta])

    def jac(theta: np.ndarray) -> np.ndarray:
        data = -_weighted(model_jacobian(theta), u)
        return data if sigma is None else np.vstack([data, np.diag(weight)])

    if sigma is None:  # the plausibility box bounds the plain fit (trf: bounded)
        bounds = (theta0 - model.bound, theta0 + model.bound) if hasattr(model, "bound") else (-np.inf, np.inf)
        fit = least_squares(
            residual, theta0, jac=jac, method="trf", x_scale="jac", xtol=1e-10, ftol=1e-10, bounds=bounds
        )
    else:
        # the prior bounds the posterior itself; MINPACK's Levenberg-Marquardt (its own QR, no SVD per step)
        # needed 9-15 Jacobians against trf's 13-22 and 0.2-0.6 s against 1.1-2.9 s for 100 poses on a loaded
        # 2-core machine, to the same solution within 0.003 standard uncertainties
        fit = least_squares(residual, theta0, jac=jac, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10)
    theta, nfev = fit.x, int(fit.nfev)
    if not fit.success:  # status 0: the evaluation budget ran out; a solution short of the minimum is no calibration
        raise InsufficientData(
            f"kinematic calibration refused: the solver stopped after {nfev} model evaluations "
            f"without converging ({fit.message}); expected a fit that converges: check the "
            "measurements against the commanded poses"
        )
    final_jac = model_jacobian(theta)
    after = measured - model.predict(theta)
    failed = np.flatnonzero(~np.all(np.isfinite(after), axis=1))
    if failed.size:  # a solution where the model cannot place a pose explains nothing there: no calibration
        raise InsufficientData(
            f"kinematic calibration refused: at the solution the forward kinematics fails at "
            f"{failed.size} measured poses (first: pose {failed[0]}); expected poses the fitted "
            "geometry reaches: leave such poses out or measure them again"
        )
    obs, cov, prior_only = check(final_jac)
    obs = obs or observability(final_jac, u, model.free, limit)  # a prior's: the data part, reported
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    correlation = cov / np.outer(std, std)
    # the parameters the data fit, tr(J_w C J_w^T) = K - sum_j C_jj / sigma_j^2: K without a prior (m - K degrees of
    # freedom), less what a prior holds; chi^2 over m - that has expectation 1 when the instrument and prior are right
    dof = max(measured.size - (k - float(np.sum(np.diag(cov) * precision))), 1.0)
    return Identification(
        tuple(model.free),
        tuple(model.units),
        theta,
        std,
        correlation,
        after,
        before,
        float(np.sum((after / u) ** 2) / dof),
        obs,
        nfev,
        None if sigma is None else np.array(sigma),
        prior_only,
        dof,
    )


#: Condition number the default free set is built to: half the acceptance limit, since the Jacobian at the
#: identified parameters differs from the one at the nominal ones the set is chosen with.
FREE_SET_LIMIT = CONDITION_LIMIT / 2


def identifiable_subset(
    jac: ArrayLike,
    uncertainty: ArrayLike,
    names: Sequence[str],
    limit: float = FREE_SET_LIMIT,
    required: Sequence[str] = (),
) -> tuple[str, ...]:
    """The default free set: the largest subset of ``names`` the pose set and instrument can identify.

    Subset selection by QR with column pivoting of the scaled Jacobian (Golub & Van Loan §5.5.7; Khalil & Dombre's
    base parameters): ``required`` names (e.g. the registration of a relative instrument) come first and are
    projected out; the other columns are ranked by pivoted QR of what remains; the first r are kept, r being the
    largest count, below the number of coordinates, whose combined scaled Jacobian has a condition number <=
    ``limit``. A parameter left out is (nearly) a combination of the kept ones, so its error is absorbed by them and
    the fit still explains the data.
    """
    names = tuple(names)
    index = {n: i for i, n in enumerate(names)}
    forced = [index[n] for n in required]
    others = [i for i in range(len(names)) if i not in forced]
    weighted = _weighted(jac, uncertainty)
    norms = np.linalg.norm(weighted, axis=0)
    scaled = weighted / np.where(norms > 0, norms, 1.0)
    rest = scaled[:, others]
    if forced:
        basis, _ = np.linalg.qr(scaled[:, forced])
        rest = rest - basis @ (basis.T @ rest)
    _, _, pivots = qr(rest, mode="economic", pivoting=True)
    ranked = [others[p] for p in pivots if norms[others[p]] > 0]
    for count in range(len(ranked), -1, -1):
        trial = forced + ranked[:count]
        if not trial:
            return ()
        if len(trial) >= len(scaled):  # identify needs more coordinates than parameters (and an SVD of m rows has
            continue  # only m singular values: a wider matrix would look well conditioned)
        sv = np.linalg.svd(scaled[:, trial], compute_uv=False)
        if sv[-1] > 0 and sv[0] / sv[-1] <= limit:
            return tuple(names[i] for i in sorted(trial))
    return tuple(names[i] for i in sorted(forced))


def away_from_folds(fold_ratio: ArrayLike, margin: float = FOLD_MARGIN) -> np.ndarray:
    """Which candidates (bool (N,)) lie away from a fold of the forward kinematics: fold ratio (e.g.
    :meth:`motion.pkm5.calibration.ForwardModel.fold_ratio`) at least ``margin`` times the candidates' median.

    Near a fold the FK solves of nearby geometries may change branch, a barrier a fit cannot cross (seen: a beta
    pose 58 mm away at 0.4 of the way from a fit to the truth, docs/calibration.md); D-optimal selection favours
    exactly such sensitive poses, so they are left out before it."""
    ratio = np.asarray(fold_ratio, dtype=float)
    return np.isfinite(ratio) & (ratio >= margin * np.median(ratio[np.isfinite(ratio)]))


def select_poses(
    jac: ArrayLike, uncertainty: ArrayLike, n: int, *, first: Sequence[int] = (), fold_ratio: ArrayLike | None = None
) -> np.ndarray:
    """Greedy D-optimal choice of ``n`` poses from candidates with Jacobian blocks ``jac`` (N, a, K).

    Each step adds the candidate that most increases ``log det(M)``, ``M = sum J_s,i^T J_s,i`` over the chosen poses
    of the column-scaled weighted Jacobian (maximising det M maximises the product of singular values, i.e. the O1
    index). The increment is ``log det(I_a + B M^{-1} B^T)`` (matrix determinant lemma), computed for all candidates
    at once; M starts at a small ridge so the first picks are defined. ``fold_ratio`` (N,) given, candidates near
    an FK fold are never picked (:func:`away_from_folds`). Returns the chosen indices in pick order.
    """
    jac = np.asarray(jac, dtype=float)
    count, a, k = jac.shape
    usable = np.ones(count, bool) if fold_ratio is None else away_from_folds(fold_ratio)
    if not 1 <= n <= int(usable.sum()):
        raise ConfigError(
            f"n = {n!r} poses to select, expected 1..{int(usable.sum())} (the number of candidates"
            f"{'' if fold_ratio is None else ' away from an FK fold'})"
        )
    u = np.broadcast_to(np.asarray(uncertainty, dtype=float), (a,))
    blocks = jac / u[None, :, None]
    norms = np.linalg.norm(blocks[usable].reshape(-1, k), axis=0) / np.sqrt(usable.sum())  # over the usable ones
    blocks = blocks / np.where(norms > 0, norms, 1.0)
    info = 1e-6 * np.eye(k)
    chosen = [int(i) for i in first]
    for i in chosen:
        info += blocks[i].T @ blocks[i]
    available = usable.copy()
    available[chosen] = False
    while len(chosen) < n:
        inverse = np.linalg.inv(info)
        gain = np.linalg.slogdet(np.eye(a) + blocks @ inverse @ blocks.transpose(0, 2, 1))[1]
        gain[~available] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        available[best] = False
        info += blocks[best].T @ blocks[best]
    return np.asarray(chosen)
