"""Uncertainty of RP and of Groover's 3 σ̄ from a Monte Carlo of their measurement model (JCGM 101:2008, GUM S1).

Both figures are non-linear in the readings and biased low at small n, so neither s/√n nor a bootstrap covers their
population value as often as a k = 2 interval promises (75-89 % at n = 10-30, issue 32). Under a Gaussian model of
the cycles, |estimate - measurand| / estimate is a pivot that depends only on n and the scatter's shape; its
quantile, simulated once per (n, shape) and cached, scales the estimate into U. Coverage:
benchmarks/bench_uncertainty_coverage.py.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from bench.metrology._validation import as_points, require_count

__all__ = ["MODEL_MAX_CYCLES", "mean_sd_uncertainty", "repeatability_uncertainty_model"]

#: Up to this many cycles per pose U(RP) is the measurement model's (:func:`repeatability_uncertainty_model`); above,
#: the delta method's: RP's small-sample bias (about -0.6 % of RP at n = 100) is then small against its spread.
MODEL_MAX_CYCLES = 100
#: Monte Carlo draws of the measurement model per (n, shape) (cached: a campaign of many poses pays for it once).
MODEL_DRAWS = 2000
#: Grid of the scatter's shape (axis sigmas over the largest) on which the model's factor is computed and cached.
MODEL_SHAPE_STEP = 0.1
#: Population draws that fix the measurand l_mean + 3 sigma_l of a shape (its Monte Carlo error is under 0.1 %).
MODEL_TARGET_DRAWS = 400_000
#: Share of the eigenvalue dispersion that sampling alone gives an isotropic scatter which the shape estimate gives
#: back (see :func:`_scatter_shape`) [choice: measured over five shapes (axis sigmas 1:1:1, 1:0.3:0.1, 1:1:0.4, 1:1
#: and 1:0.5) at n = 10 and 30, 1000 campaigns each: 0 (the raw sample shape) covers 93.4-97.5 %, isotropic scatter
#: over-covered at n = 10; 0.25: 93.4-96.4 %; 0.4: 93.4-95.9 %; 0.5: 93.2-95.8 %; 1 (full): 92.2-95.4 %].
SHAPE_SHRINKAGE = 0.4


def _rp_of_samples(samples: np.ndarray) -> np.ndarray:
    """RP_l = l̄ + 3 S_l of every sample of a stack (..., n, d) of cycles."""
    distances = np.sqrt(np.sum((samples - samples.mean(axis=-2, keepdims=True)) ** 2, axis=-1))
    return distances.mean(axis=-1) + 3.0 * distances.std(axis=-1, ddof=1)


@lru_cache(maxsize=8)
def _squared_offsets(seed: int, size: tuple[int, ...]) -> np.ndarray:
    """Squared offsets from their sample mean (over axis -2; none for a 2-D ``size``) of the standard normal draws
    ``default_rng(seed).standard_normal(size)``, drawn once.

    A scatter of axis sigmas s is these draws scaled by s, so its squared distances are these squares weighted by
    s²: every shape is a matrix-vector product over the same draws (a table of many poses pays for the draws and the
    centring once per n, then about 3 ms per shape)."""
    draws = np.random.default_rng(seed).standard_normal(size)
    if len(size) == 3:
        draws -= draws.mean(axis=-2, keepdims=True)
    squares = np.square(draws, out=draws)  # in place: the draws are not needed again
    squares.flags.writeable = False
    return squares


def _distances(squares: np.ndarray, shape: tuple[float, ...]) -> np.ndarray:
    """Distances ‖s ∘ z‖ of the draws whose squared components are ``squares``, for axis sigmas s = ``shape``."""
    return np.sqrt(squares @ np.square(np.array(shape)))


@lru_cache(maxsize=4096)
def _rp_population(shape: tuple[float, ...]) -> float:
    """The measurand l_mean + 3 sigma_l of a Gaussian scatter with axis sigmas ``shape`` (distances to the mean)."""
    distances = _distances(_squared_offsets(20_260_001, (MODEL_TARGET_DRAWS, len(shape))), shape)
    return float(distances.mean() + 3.0 * distances.std())


@lru_cache(maxsize=4096)
def _rp_relative_half_width(n: int, shape: tuple[float, ...], level: float) -> float:
    """Quantile ``level`` of |RP̂ - RP| / RP̂ for n cycles of a Gaussian scatter of axis sigmas ``shape``."""
    distances = _distances(_squared_offsets(20_260_002 + n, (MODEL_DRAWS, n, len(shape))), shape)
    estimates = distances.mean(axis=-1) + 3.0 * distances.std(axis=-1, ddof=1)
    return float(np.quantile(np.abs(estimates - _rp_population(shape)) / estimates, level))


@lru_cache(maxsize=64)
def _isotropic_dispersion(n: int, d: int) -> float:
    """E[Σ (λ̂_i - λ̂̄)² / λ̂̄²] of the sample covariance's eigenvalues λ̂ of n cycles of an isotropic Gaussian scatter
    in d axes (Monte Carlo of ``MODEL_DRAWS`` campaigns): the spread that sampling alone puts between the axes."""
    draws = np.random.default_rng(20_260_004 + n).standard_normal((MODEL_DRAWS, n, d))
    draws -= draws.mean(axis=1, keepdims=True)
    eigenvalues = np.linalg.eigvalsh(np.einsum("knd,kne->kde", draws, draws) / (n - 1))
    mean = eigenvalues.mean(axis=1, keepdims=True)
    return float(np.mean(np.sum((eigenvalues - mean) ** 2, axis=1) / mean[:, 0] ** 2))


def _scatter_shape(points: np.ndarray) -> tuple[float, ...]:
    """The scatter's axis sigmas over the largest, rounded to ``MODEL_SHAPE_STEP``: the sample covariance's
    eigenvalues λ̂, shrunk toward their mean.

    Sample eigenvalues spread more than the population's (the largest reads high, the smallest low: Ledoit & Wolf,
    J. Multivariate Anal. 88 (2004) 365-411), so at n = 10 an isotropic scatter looks anisotropic, and the model's
    factor for that shape over-covers (97-98 %). The estimate keeps the mean and shrinks the deviations,

    .. math::

        λ_i = \\bar λ + (λ̂_i - \\bar λ)(1 - b), \\qquad
        b = \\min\\Big(1, c \\, \\frac{E_{iso}[D]}{D}\\Big), \\quad
        D = \\frac{\\sum_i (λ̂_i - \\bar λ)^2}{\\bar λ^2}

    with E_iso[D] the dispersion sampling alone gives (:func:`_isotropic_dispersion`) and c = ``SHAPE_SHRINKAGE``.
    """
    n, d = points.shape
    eigenvalues = np.clip(np.linalg.eigvalsh(np.atleast_2d(np.cov(points, rowvar=False))), 0.0, None)[::-1]
    mean = float(eigenvalues.mean())
    dispersion = float(np.sum((eigenvalues - mean) ** 2)) / mean**2
    if d > 1 and dispersion > 0.0:
        shrink = min(1.0, SHAPE_SHRINKAGE * _isotropic_dispersion(n, d) / dispersion)
        eigenvalues = mean + (eigenvalues - mean) * (1.0 - shrink)
    sigmas = np.sqrt(eigenvalues)
    return tuple(float(v) for v in np.round(sigmas / sigmas[0] / MODEL_SHAPE_STEP) * MODEL_SHAPE_STEP)


@lru_cache(maxsize=8)
def _standard_sds(seed: int, size: tuple[int, ...]) -> np.ndarray:
    """Sample SDs over axis 1 of the standard normal draws ``default_rng(seed).standard_normal(size)``, drawn once
    (readings of SD s are these draws scaled by s, and so are their SDs)."""
    sds = np.random.default_rng(seed).standard_normal(size).std(axis=1, ddof=1)
    sds.flags.writeable = False
    return sds


def repeatability_uncertainty_model(attained_mm: ArrayLike, *, k: float = 2.0) -> float:
    """Uncertainty of RP_l from a Monte Carlo of its measurement model (JCGM 101:2008, GUM Supplement 1).

    The measurand is the population value RP = E[l] + 3 SD[l], l the distance of an attained position from the
    true mean position (what RP_l = l̄ + 3 S_l estimates; at n = 10 the estimator reads about 6-8 % low). The model:
    the n cycles are Gaussian about their mean, with the pose's axis sigmas (eigenvalues of the sample covariance,
    shrunk toward their mean by :func:`_scatter_shape`).
    W = |RP̂ - RP| / RP̂ is then a pivot: its distribution depends only on n and the scatter's *shape*, not on its
    size, so the half-width

    .. math::

        U = w_p \\cdot RP_l, \\qquad P(W \\le w_p) = p = \\mathrm{erf}(k/\\sqrt2) \\; (95.45 \\% \\text{ for } k = 2)

    covers the measurand with probability p, small-sample bias included. w_p comes from ``MODEL_DRAWS``
    simulated campaigns of n cycles for the shape rounded to ``MODEL_SHAPE_STEP`` (cached, so a table of many
    poses pays for it once per (n, shape)); O(n d²) per pose otherwise. Coverage measured by
    ``benchmarks/bench_uncertainty_coverage.py`` (docs/metrology.md).

    Returns
    -------
    float
        The standard-uncertainty equivalent U / k, so that ``expanded(rp, u, k=k)`` states this U.
    """
    points = as_points("attained_mm", attained_mm, dims=None)
    require_count("cycles", len(points), 3)
    return checked_repeatability_uncertainty_model(points, float(_rp_of_samples(points)), k=k)


def checked_repeatability_uncertainty_model(points: np.ndarray, rp: float, *, k: float = 2.0) -> float:
    """:func:`repeatability_uncertainty_model` of checked cycles (n >= 3) whose RP_l = l̄ + 3 S_l is ``rp``."""
    if rp == 0.0:
        return 0.0
    level = math.erf(k / math.sqrt(2.0))
    return rp * _rp_relative_half_width(len(points), _scatter_shape(points), level) / k


@lru_cache(maxsize=4096)
def _mean_sd_relative_half_width(n: int, shape: tuple[float, ...], level: float) -> float:
    """Quantile ``level`` of |σ̄̂ - σ̄| / σ̄̂ for n Gaussian readings at targets of standard deviations ``shape``."""
    sigmas = np.array(shape)
    estimates = (_standard_sds(20_260_003 + n, (MODEL_DRAWS, n, len(shape))) * sigmas).mean(axis=1)
    return float(np.quantile(np.abs(estimates - sigmas.mean()) / estimates, level))


def mean_sd_uncertainty(readings: ArrayLike, *, k: float = 2.0) -> float:
    """Uncertainty of σ̄, the mean over targets of the per-target sample SDs (Groover's repeatability 3 σ̄), from
    a Monte Carlo of its measurement model (JCGM 101), as :func:`repeatability_uncertainty_model` does for RP.

    The measurand is the mean of the targets' true standard deviations; σ̄ reads low at small n (E[s] = c_4 σ, 0.973 σ
    at n = 10). Model: Gaussian readings per target with the observed SDs' shape (over the largest, rounded to
    ``MODEL_SHAPE_STEP``); U = w_p σ̄ with w_p the quantile p = erf(k/√2) of |σ̄̂ - σ̄| / σ̄̂. Cached per (n, shape).

    Parameters
    ----------
    readings : array_like, shape (n, m)
        n repeats (rows) at m targets (columns), n >= 3.

    Returns
    -------
    float
        The standard-uncertainty equivalent U / k of σ̄ (multiply by 3 for Groover's 3 σ̄).
    """
    values = as_points("readings", readings, dims=None)
    require_count("repeats", len(values), 3)
    sds = values.std(axis=0, ddof=1)
    if sds.max() == 0.0:
        return 0.0
    shape = tuple(float(v) for v in np.round(sds / sds.max() / MODEL_SHAPE_STEP) * MODEL_SHAPE_STEP)
    level = math.erf(k / math.sqrt(2.0))
    return float(sds.mean()) * _mean_sd_relative_half_width(len(values), shape, level) / k
