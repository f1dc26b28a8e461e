"""Profile-likelihood standard uncertainties of a kinematic identification, for parameters whose linearised
(Laplace) uncertainty understates the posterior's width.

Why: the MAP fit's stated uncertainty is the linearised one, ``u_j = sqrt(C_jj)`` with ``C = (J_w^T J_w +
diag(sigma^-2))^-1`` at the solution (:func:`bench.metrology.kinematic_calibration.identify`). It is exact when the
objective is quadratic in the parameters. The pkm5's forward model is not: along its weakest directions (the
platform joints ``pd_5_x`` / ``pd_6_x``) the objective rises slower than its quadratic model, and the truth then
lies beyond the linear interval more often than it claims (on the ideal simulator, seed 55 stored ``pd_6_x_mm``
5.06 u from its truth, every start landing in that one basin; docs/calibration.md).

Method (profile likelihood, Venzon & Moolgavkar 1988, "A method for computing profile-likelihood-based confidence
intervals", Appl. Statist. 37:87; Raue et al. 2009, Bioinformatics 25:1923; for a posterior, the profile posterior
of the MAP objective): with the MAP objective

.. math:: \\Phi(\\theta) = \\sum_i |(m_i - f_i(\\theta)) / u_i|^2 + \\sum_j (\\theta_j / \\sigma_j)^2

and its profile in parameter ``j``, :math:`P_j(c) = \\min_{\\theta: \\theta_j = c} \\Phi(\\theta) - \\Phi(\\hat\\theta)`,
the interval of coverage factor ``k`` is where :math:`P_j \\le k^2` (Wilks: :math:`P_j` is :math:`\\chi^2_1`
distributed, so ``k = 2`` covers 95.45 %, as ``+-2 u`` of a Gaussian). Under the linearisation :math:`P_j(\\hat
\\theta_j + t u_j) = t^2`, so the linear endpoints are ``t = +-k``. Each parameter's endpoints are found by a secant
on :math:`s(t) = \\sqrt{P_j}`, which is linear in ``t`` where the model is (``s(t) = |t|``), started at the
linear endpoint; the others are refitted at each trial from the linearised conditional point :math:`\\hat\\theta +
t u_j C_{:,j} / \\sqrt{C_{jj}}`. The nonlinearity check is the first trial: where :math:`\\sqrt{P_j(\\pm k)}` is
within :data:`LINEAR_TOLERANCE` of ``k`` the linear interval stands. The stated uncertainty becomes
``u'_j = max(u_j, max(|t_-|, |t_+|) u_j / k)``: the wider side of the profile interval over ``k``, never narrower
than the linear one (a symmetric ``u`` cannot state a skew interval, so the wider side bounds it). Pure
computation, arrays in and out.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares

from bench.metrology.kinematic_calibration import Identification

__all__ = ["LINEAR_TOLERANCE", "MAX_STEPS", "PROFILE_K", "ProfileUndetermined", "profile_ratios", "profile_widths"]

#: Coverage factor of the profile interval the stated uncertainty is read from (k = 2, 95.45 % under Wilks).
PROFILE_K = 2.0
#: Relative difference of sqrt(profile rise) from the linear prediction ``k`` within which the linearisation is
#: taken as exact (the secant stops there too): 1 % of the interval's half-width.
LINEAR_TOLERANCE = 0.01
#: Secant steps per side at most (each a refit of the other parameters from a nearby start).
MAX_STEPS = 6


def _objective_terms(
    model: Any, measured: np.ndarray, u: np.ndarray, weight: np.ndarray
) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]:
    """The MAP objective's whitened residual vector (data rows over ``u``, prior rows ``theta / sigma``; ``Phi`` is
    its squared norm) and its Jacobian, as :func:`identify` solves them."""

    def residual(theta: np.ndarray) -> np.ndarray:
        r = np.nan_to_num((measured - model.predict(theta)) / u, nan=1e6).ravel()
        return np.concatenate([r, weight * theta])

    def jacobian(theta: np.ndarray) -> np.ndarray:
        jac = np.asarray(model.jacobian(theta), dtype=float)
        data = -(jac / u[:, :, None]).reshape(-1, jac.shape[-1])
        return np.vstack([data, np.diag(weight)])

    return residual, jacobian


class ProfileUndetermined(ValueError):
    """A profile endpoint that cannot be found: the model cannot place a measured pose at a trial (the interval
    reaches the edge of the forward kinematics' domain), or the profile stops rising outward."""


def _sqrt_profile_rise(
    model: Any,
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray,
    j: int,
    best: float,
) -> float:
    """``sqrt(P_j(start_j))``: the others refitted from ``start`` with parameter ``j`` held at ``start[j]``. Raises
    :class:`ProfileUndetermined` where the refitted geometry cannot place every measured pose."""
    others = np.delete(np.arange(len(start)), j)
    if not others.size:
        theta = start
    else:
        theta = np.insert(_refit_others(residual, jacobian, start, j, others), j, start[j])
    if not np.all(np.isfinite(model.predict(theta))):
        raise ProfileUndetermined(f"the forward kinematics fails at parameter {j} = {start[j]:.6g}")
    return float(np.sqrt(max(float(np.sum(residual(theta) ** 2)) - best, 0.0)))


def _refit_others(
    residual: Callable[[np.ndarray], np.ndarray],
    jacobian: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray,
    j: int,
    others: np.ndarray,
) -> np.ndarray:
    """The parameters other than ``j`` minimising the objective with ``j`` held at ``start[j]``."""
    sol = least_squares(
        lambda x: residual(np.insert(x, j, start[j])),
        start[others],
        jac=lambda x: jacobian(np.insert(x, j, start[j]))[:, others],
        method="lm",
        x_scale="jac",
        xtol=1e-6,  # P to ~1e-5 of its value: far below LINEAR_TOLERANCE
        ftol=1e-6,
    )
    return np.asarray(sol.x)


def profile_widths(
    model: Any, measured: ArrayLike, uncertainty: ArrayLike, fit: Identification, k: float = PROFILE_K
) -> np.ndarray:
    """Per parameter the wider side of its profile interval at coverage ``k``, in units of its linear standard
    uncertainty times ``k`` (module docstring): 1 where the linearisation holds, above 1 where the objective rises
    slower than its quadratic model, below 1 where faster. NaN where it is undetermined (:class:`ProfileUndetermined`,
    or a refit fails)."""
    measured = np.asarray(measured, dtype=float)
    u = np.broadcast_to(np.asarray(uncertainty, dtype=float), measured.shape)
    n = len(fit.values)
    sigma = np.full(n, np.inf) if fit.prior_sigma is None else np.asarray(fit.prior_sigma, dtype=float)
    weight = np.where(np.isfinite(sigma), 1.0 / sigma, 0.0)
    residual, jacobian = _objective_terms(model, measured, u, weight)
    best = float(np.sum(residual(fit.values) ** 2))
    covariance = fit.correlation * np.outer(fit.uncertainty, fit.uncertainty)
    widths = np.full(n, np.nan)
    for j in range(n):
        direction = covariance[:, j] / fit.uncertainty[j]  # the linearised conditional point per unit t
        ends = []
        try:
            for side in (1.0, -1.0):  # secant on s(t) = sqrt(P_j), from (0, 0) and the linear endpoint
                t0, s0, t1 = 0.0, 0.0, side * k
                s1 = _sqrt_profile_rise(model, residual, jacobian, fit.values + t1 * direction, j, best)
                for _ in range(MAX_STEPS + 1):
                    if abs(s1 - k) <= LINEAR_TOLERANCE * k:
                        break
                    if (s1 - s0) * (t1 - t0) * side <= 0:  # not rising outward between the last two trials
                        raise ProfileUndetermined(f"the profile of parameter {j} stops rising at t = {t1:.3g}")
                    t0, s0, t1 = t1, s1, t1 + (k - s1) * (t1 - t0) / (s1 - s0)
                    s1 = _sqrt_profile_rise(model, residual, jacobian, fit.values + t1 * direction, j, best)
                else:
                    raise ProfileUndetermined(f"no endpoint of parameter {j}'s profile within {MAX_STEPS} steps")
                ends.append(abs(t1) / k)
        except (ValueError, np.linalg.LinAlgError):  # outside the model's domain, or no endpoint: undetermined
            continue
        widths[j] = max(ends)
    return widths


def profile_ratios(
    model: Any, measured: ArrayLike, uncertainty: ArrayLike, fit: Identification, k: float = PROFILE_K
) -> np.ndarray:
    """Per parameter the factor ``u'_j / u_j = max(1, profile_widths)`` (module docstring); NaN where the profile is
    undetermined (the linear value stands there, and the caller says so)."""
    widths = profile_widths(model, measured, uncertainty, fit, k)
    return np.where(np.isnan(widths), np.nan, np.maximum(widths, 1.0))
