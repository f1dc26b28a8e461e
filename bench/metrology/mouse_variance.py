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

from bench.errors import ConfigError
from bench.metrology.uncertainty import resolution_uncertainty

__all__ = ["GlsFit", "feasible_gls", "move_error_structures", "shared_reading_matrix"]

#: Fisher scoring steps of the REML estimate; it converges in well under this on calibration runs.
_REML_STEPS = 200


@dataclass(frozen=True)
class GlsFit:
    """A feasible GLS fit y = X β + e, Cov(e) = Σ θ_j G_j + Q."""

    coefficients: np.ndarray  #: (p,) β̂
    covariance: np.ndarray  #: (p, p) (Xᵀ V̂⁻¹ X)⁻¹
    components: np.ndarray  #: (m,) θ̂, the REML estimates of the unknown variances (>= 0)
    residuals: np.ndarray  #: (K,) y - X β̂


def shared_reading_matrix(starts_at_previous_end: ArrayLike, mask: ArrayLike | None = None) -> np.ndarray:
    """D Dᵀ of the moves' readings: the covariance, in units of one reading's variance, of the difference of a
    move's two readings when each reading carries an independent error.

    Move k reads its start and its end; with D the (K x readings) incidence matrix (+1 at the end, -1 at the
    start), D Dᵀ has 2 on the diagonal and -1 between move k - 1 and move k when move k starts at move k - 1's end
    reading. ``mask`` (K,) keeps only the moves whose readings carry the error (others are zeroed).

    Examples
    --------
    >>> shared_reading_matrix([False, True, False]).astype(int).tolist()
    [[2, -1, 0], [-1, 2, 0], [0, 0, 2]]
    """
    chained = np.asarray(starts_at_previous_end, dtype=bool).reshape(-1)
    matrix = 2.0 * np.eye(len(chained))
    linked = np.flatnonzero(chained[1:]) + 1
    matrix[linked, linked - 1] = matrix[linked - 1, linked] = -1.0
    if mask is not None:
        keep = np.asarray(mask, dtype=float).reshape(-1)
        matrix *= np.outer(keep, keep)
    return matrix


def move_error_structures(
    starts_at_previous_end: ArrayLike, along: ArrayLike
) -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """The covariance structures of one sensor axis's move errors: the unknown ones (tracking noise, every move
    independent: I; the reference's error a reading, on the moves ``along`` this sensor axis: D Dᵀ there) and the
    known one, the quantisation of the readings: Q = D Dᵀ / 12 count² (GUM F.2.2.1, one count's resolution)."""
    along_mask = np.asarray(along, dtype=bool).reshape(-1)
    chain = shared_reading_matrix(starts_at_previous_end)
    if chain.shape[0] != along_mask.size:
        raise ConfigError(
            f"starts_at_previous_end: {chain.shape[0]} moves, along: {along_mask.size}, expected one flag per move"
        )
    unknown = (np.eye(len(along_mask)), shared_reading_matrix(starts_at_previous_end, along_mask))
    return unknown, resolution_uncertainty(1.0) ** 2 * chain


def _projection(design: np.ndarray, covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """V⁻¹, (Xᵀ V⁻¹ X)⁻¹ and the REML projection P = V⁻¹ - V⁻¹ X (Xᵀ V⁻¹ X)⁻¹ Xᵀ V⁻¹."""
    inverse = np.linalg.inv(covariance)
    weighted = inverse @ design
    information = np.linalg.inv(design.T @ weighted)
    return inverse, information, inverse - weighted @ information @ weighted.T


def feasible_gls(y: ArrayLike, design: ArrayLike, unknown: tuple[np.ndarray, ...], known: np.ndarray) -> GlsFit:
    """GLS of y = X β + e with Cov(e) = V(θ) = Σ_j θ_j G_j + Q, θ >= 0 estimated by REML.

    REML by Fisher scoring (Patterson & Thompson 1971; Harville 1977, eqs. 4.7-4.9), each step clipped to θ >= 0:

    .. math::

        P = V^{-1} - V^{-1} X (X^T V^{-1} X)^{-1} X^T V^{-1}, \\quad
        s_j = \\tfrac12 \\left(y^T P G_j P y - \\operatorname{tr}(P G_j)\\right), \\quad
        \\mathcal I_{jl} = \\tfrac12 \\operatorname{tr}(P G_j P G_l), \\quad
        \\theta \\leftarrow \\max(0, \\theta + \\mathcal I^{-1} s)

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
    observations = np.asarray(y, dtype=float).reshape(-1)
    x = np.asarray(design, dtype=float)
    ordinary = np.linalg.lstsq(x, observations, rcond=None)[0]
    residual_variance = float(np.sum((observations - x @ ordinary) ** 2)) / max(len(observations) - x.shape[1], 1)
    theta = np.full(len(unknown), max(residual_variance, 1e-6) / max(len(unknown), 1))
    for _ in range(_REML_STEPS if unknown else 0):
        _, _, projection = _projection(x, known + sum((t * g for t, g in zip(theta, unknown)), np.zeros_like(known)))
        projected = projection @ observations
        weighted = [projection @ g for g in unknown]
        score = np.array([0.5 * (projected @ g @ projected - np.trace(w)) for g, w in zip(unknown, weighted)])
        information = np.array([[0.5 * np.sum(a * b.T) for b in weighted] for a in weighted])
        step = np.linalg.lstsq(information, score, rcond=None)[0]
        updated = np.maximum(theta + step, 0.0)
        converged = np.allclose(updated, theta, rtol=1e-6, atol=1e-8 * max(residual_variance, 1e-12))
        theta = updated
        if converged:
            break
    covariance_e = known + sum((t * g for t, g in zip(theta, unknown)), np.zeros_like(known))
    inverse, covariance, _ = _projection(x, covariance_e)
    coefficients = covariance @ x.T @ inverse @ observations
    return GlsFit(coefficients, covariance, theta, observations - x @ coefficients)
