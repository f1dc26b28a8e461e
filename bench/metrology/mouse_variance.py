"""What scatters a mouse calibration move's counts, and the feasible generalised least squares fit that weighs it.

A move's count increment is the difference of two whole-count readings of the mouse's counter (its sub-count
remainder carried from move to move), so its error is made of

- quantisation: each reading is off by a rectangular error of one count's width, a known Type B component of
  variance 1/12 count² a reading (GUM, JCGM 100:2008, F.2.2.1); a move differences two readings and two moves that
  share a reading (the protocol's out-and-back chain) share its error, with opposite signs;
- the reference's error a reading (a calliper reading, or where a calibrated axis arrived): along the step axis
  only, so it shows on the sensor axis along the move, shared like the quantisation; variance unknown;
- the sensor's tracking noise, independent from move to move; variance unknown.

The unknown variances are estimated by REML and the fit is the GLS with the estimated covariance (feasible GLS).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology.uncertainty import resolution_uncertainty

__all__ = ["GlsFit", "feasible_gls", "move_error_structures", "shared_reading_matrix"]

#: Largest |∂(-log L_R)/∂φ| a move (φ = θ / residual variance) of a free component, or descent into a bound one,
#: that a REML solution may leave (the objective grows with the moves; the optimiser stops at its rounding).
_KKT_TOLERANCE = 1e-3
#: Most Fisher scoring steps that polish the optimiser's solution (each gains digits; a few reach the rounding).
_POLISH_STEPS = 10


@dataclass(frozen=True)
class GlsFit:
    """A feasible GLS fit y = X β + e, Cov(e) = Σ θ_j G_j + Q."""

    coefficients: np.ndarray  #: (p,) β̂
    covariance: np.ndarray  #: (p, p) (Xᵀ V̂⁻¹ X)⁻¹
    components: np.ndarray  #: (m,) θ̂, the REML estimates of the unknown variances (>= 0)
    residuals: np.ndarray  #: (K,) y - X β̂


def shared_reading_matrix(readings: ArrayLike, mask: ArrayLike | None = None) -> np.ndarray:
    """D Dᵀ of the moves' readings: the covariance, in units of one reading's variance, of the difference of a
    move's two readings when each reading carries an independent error.

    ``readings`` (K, 2) numbers each move's start and end reading; two moves that name one number share that
    reading. D is the (K x readings) incidence matrix (+1 at a move's end, -1 at its start), so D Dᵀ has 2 on the
    diagonal and -1 between a move and the next that starts at its end reading (+1 where two moves share a start
    or an end). ``mask`` (K,) keeps only the moves whose readings carry the error (others are zeroed).

    Examples
    --------
    Out, back, then a move read on its own:

    >>> shared_reading_matrix([[0, 1], [1, 2], [5, 6]]).astype(int).tolist()
    [[2, -1, 0], [-1, 2, 0], [0, 0, 2]]
    """
    numbers = np.asarray(readings)
    if numbers.ndim != 2 or numbers.shape[1] != 2:
        raise ConfigError(f"readings: shape {numbers.shape}, expected (moves, 2): each move's start and end reading")
    _, index = np.unique(numbers, return_inverse=True)
    index = index.reshape(-1, 2)
    moves = np.arange(len(index))
    incidence = np.zeros((len(index), int(index.max(initial=-1)) + 1))
    np.add.at(incidence, (moves, index[:, 1]), 1.0)
    np.add.at(incidence, (moves, index[:, 0]), -1.0)
    if mask is not None:
        incidence *= np.asarray(mask, dtype=float).reshape(-1, 1)
    return incidence @ incidence.T


def move_error_structures(readings: ArrayLike, along: ArrayLike) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """The covariance structures of one sensor axis's move errors: the unknown ones (tracking noise, every move
    independent: I; the reference's error a reading, on the moves ``along`` this sensor axis: D Dᵀ there) and the
    known one, the quantisation of the readings: Q = D Dᵀ / 12 count² (GUM F.2.2.1, one count's resolution)."""
    along_mask = np.asarray(along, dtype=bool).reshape(-1)
    chain = shared_reading_matrix(readings)
    if chain.shape[0] != along_mask.size:
        raise ConfigError(f"readings: {chain.shape[0]} moves, along: {along_mask.size}, expected one row per move")
    unknown = (np.eye(len(along_mask)), shared_reading_matrix(readings, along_mask))
    return unknown, resolution_uncertainty(1.0) ** 2 * chain


def _projection(design: np.ndarray, covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V⁻¹, (Xᵀ V⁻¹ X)⁻¹ and the REML projection P = V⁻¹ - V⁻¹ X (Xᵀ V⁻¹ X)⁻¹ Xᵀ V⁻¹."""
    inverse = np.linalg.inv(covariance)
    weighted = inverse @ design
    information = np.linalg.inv(design.T @ weighted)
    return inverse, information, inverse - weighted @ information @ weighted.T


def _covariance(theta: np.ndarray, unknown: tuple[np.ndarray, ...], known: np.ndarray) -> np.ndarray:
    """V(θ) = Σ_j θ_j G_j + Q."""
    return known + np.einsum("j,jkl->kl", theta, np.array(unknown).reshape(len(theta), *known.shape))


def _reml_objective(
    theta: np.ndarray, y: np.ndarray, design: np.ndarray, unknown: tuple[np.ndarray, ...], known: np.ndarray
) -> tuple[float, np.ndarray]:
    """-log L_REML(θ) up to a constant and its gradient (Harville 1977, eqs. 4.4 and 4.7)."""
    covariance = _covariance(theta, unknown, known)
    _, information, projection = _projection(design, covariance)
    projected = projection @ y
    value = 0.5 * (np.linalg.slogdet(covariance)[1] - np.linalg.slogdet(information)[1] + projected @ y)
    gradient = np.array([0.5 * (np.sum(projection * g) - projected @ g @ projected) for g in unknown])
    return float(value), gradient


def _polished(
    theta: np.ndarray, y: np.ndarray, design: np.ndarray, unknown: tuple[np.ndarray, ...], known: np.ndarray
) -> np.ndarray:
    """Fisher scoring on the components the optimum leaves free (θ_j > 0), θ_f += I_ff⁻¹ s_f (Harville 1977,
    eq. 4.9), to the objective's rounding: the optimiser stops within its tolerance, which would leave the fit
    depending on the order of the moves in the 7th digit."""
    free = np.flatnonzero(theta > 0.0)
    for _ in range(_POLISH_STEPS if free.size else 0):
        _, _, projection = _projection(design, _covariance(theta, unknown, known))
        projected = projection @ y
        weighted = [projection @ unknown[j] for j in free]
        score = np.array([0.5 * (projected @ unknown[j] @ projected - np.trace(w)) for j, w in zip(free, weighted)])
        information = np.array([[0.5 * np.sum(a * b.T) for b in weighted] for a in weighted])
        step = np.linalg.lstsq(information, score, rcond=None)[0]
        if (theta[free] + step < 0.0).any():
            break
        theta = theta.copy()
        theta[free] += step
        if (np.abs(step) <= 1e-14 * theta[free]).all():
            break
    return theta


def _scaled(objective: tuple[float, np.ndarray], scale: float) -> tuple[float, np.ndarray]:
    """The objective in φ = θ / scale (the residual variance), so the optimiser's tolerances are scale-free."""
    return objective[0], objective[1] * scale


def feasible_gls(y: ArrayLike, design: ArrayLike, unknown: tuple[np.ndarray, ...], known: np.ndarray) -> GlsFit:
    """GLS of y = X β + e with Cov(e) = V(θ) = Σ_j θ_j G_j + Q, θ >= 0 estimated by REML.

    REML (Patterson & Thompson 1971): θ̂ minimises, over θ >= 0 (truncated Newton, TNC, with the analytic
    gradient; Harville 1977, eqs. 4.4 and 4.7),

    .. math::

        -\\log L_R(\\theta) = \\tfrac12 \\left(\\log|V| + \\log|X^T V^{-1} X| + y^T P y\\right), \\quad
        P = V^{-1} - V^{-1} X (X^T V^{-1} X)^{-1} X^T V^{-1}, \\quad
        \\frac{\\partial}{\\partial \\theta_j} = \\tfrac12 \\left(\\operatorname{tr}(P G_j) - y^T P G_j P y\\right)

    then β̂ = (Xᵀ V̂⁻¹ X)⁻¹ Xᵀ V̂⁻¹ y with Cov(β̂) = (Xᵀ V̂⁻¹ X)⁻¹. The known Q (positive definite) keeps V
    invertible when every θ_j is 0.

    Parameters
    ----------
    y : array_like, shape (K,)
        Observations.
    design : array_like, shape (K, p)
        Full column rank, K > p.
    unknown : tuple of ndarray, each (K, K)
        The structures G_j of the unknown variance components.
    known : ndarray, shape (K, K)
        The known covariance Q.

    Raises
    ------
    InsufficientData
        The REML optimisation did not converge (its message is given).

    References
    ----------
    H. D. Patterson, R. Thompson, "Recovery of inter-block information when block sizes are unequal",
    Biometrika 58 (1971) 545-554. D. A. Harville, "Maximum likelihood approaches to variance component
    estimation and to related problems", J. Am. Stat. Assoc. 72 (1977) 320-338.

    Examples
    --------
    With no unknown component, it is the GLS with the known covariance:

    >>> x = np.column_stack([np.arange(4.0), np.ones(4)])
    >>> fit = feasible_gls(2.0 * np.arange(4.0) + 1.0, x, (), np.eye(4))
    >>> np.round(fit.coefficients, 6).tolist()
    [2.0, 1.0]
    """
    from scipy.optimize import minimize  # here, not at import: bench.metrology resolves its names lazily

    observations = np.asarray(y, dtype=float).reshape(-1)
    x = np.asarray(design, dtype=float)
    theta = np.zeros(len(unknown))
    if unknown:
        ordinary = np.linalg.lstsq(x, observations, rcond=None)[0]
        residuals = observations - x @ ordinary
        scale = max(float(residuals @ residuals) / max(len(observations) - x.shape[1], 1), 1e-12)
        result = minimize(
            lambda phi: _scaled(_reml_objective(phi * scale, observations, x, unknown, known), scale),
            np.full(len(unknown), 1.0 / len(unknown)),
            jac=True,
            method="TNC",
            bounds=[(0.0, None)] * len(unknown),
        )
        theta = _polished(result.x * scale, observations, x, unknown, known)
        # an optimiser that stops near the optimum (its line search at the rounding) is polished there; the KKT
        # conditions of the polished θ decide whether it is the REML estimate
        gradient = _reml_objective(theta, observations, x, unknown, known)[1] * scale
        violation = np.where(theta > 0.0, np.abs(gradient), np.maximum(-gradient, 0.0))
        if violation.max() > _KKT_TOLERANCE * len(observations):
            raise InsufficientData(
                f"feasible GLS: the REML estimate of the variance components failed ({result.message}; "
                f"gradient {violation.max():.2g})"
            )
    inverse, covariance, _ = _projection(x, _covariance(theta, unknown, known))
    coefficients = covariance @ x.T @ inverse @ observations
    return GlsFit(coefficients, covariance, theta, observations - x @ coefficients)
