"""Expanded uncertainties of the spread figures (RD, RV) and the path figures (AT_p, RT_p, AV) of ISO 9283.

Each U here is the half-width of ``value ± U`` that holds the figure's population value (the measurand) with the
probability a normal k promises (95.45 % for k = 2), measured by ``benchmarks/bench_uncertainty_coverage.py``:

- **A spread, 3 S (RD, RV):** the chi pivot. For n Gaussian values S/σ = √(χ²_{n-1}/(n-1)), so W = |S - σ|/S has a
  distribution that depends on n alone and U = w_p · 3S is exact (no simulation; :func:`spread_half_width`).
- **A mean (AV):** Student's factor for the Welch-Satterthwaite ν_eff, as U(AP) and U(AD).
- **A maximum over the stations of a path (AT_p, RT_p):** a parametric bootstrap-t, the Monte Carlo of the
  measurement model of JCGM 101 (GUM Supplement 1) with the model fitted to the run: the n cycles' crossing
  deviations, stations jointly (the correlation along the path kept), are Gaussian with the run's sample covariance;
  ``draws`` campaigns of n cycles are simulated from it (and an instrument offset drawn from N(0, u_inst²) per axis
  when one is declared), and the figure's error over the model's truth, studentised, gives the quantile that U
  scales. The max over stations reads high (noise lifts the largest barycentre deviation) and RT reads low (as RP
  does at small n); the simulation carries both.

Pure functions, arrays in and `Measured` out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError
from bench.metrology._validation import as_series, require_count
from bench.metrology.uncertainty import Measured, coverage_factor, expanded, welch_satterthwaite

__all__ = [
    "PATH_MODEL_DRAWS",
    "PATH_U_MIN_CYCLES",
    "PathUncertainty",
    "mean_speed_uncertainty",
    "path_uncertainty",
    "spread_half_width",
    "spread_uncertainty",
]

#: Simulated campaigns of the path model per call (the 95.45 % quantile rests on about 45 of them in its tail).
PATH_MODEL_DRAWS = 1000
#: Cycles the path model needs: a scatter about the barycentres, and a spread of that scatter.
PATH_U_MIN_CYCLES = 3
#: Standard normal draws that fix each station's population RT (its Monte Carlo error is about 0.3 %).
_POPULATION_DRAWS = 20_000
#: Simulated crossing coordinates held in memory at once (campaigns are simulated in chunks of about this size).
_SIMULATED_VALUES = 2_000_000


@lru_cache(maxsize=1024)
def spread_half_width(n: int, level: float) -> float:
    """Relative half-width w_p with P(|S - σ| <= w_p S) = p for the sample SD S of n Gaussian values.

    .. math::

        P(w) = F_{\\chi^2_{n-1}}\\Big(\\frac{n-1}{(1-w)^2}\\Big) - F_{\\chi^2_{n-1}}\\Big(\\frac{n-1}{(1+w)^2}\\Big)
        = p

    (the first term is 1 for w >= 1), solved for w. S/σ = √(χ²_{n-1}/(n-1)) makes W = |S - σ|/S a pivot
    (Cochran's theorem), so ``3 S ± w_p 3 S`` covers 3σ with probability p exactly for Gaussian values.

    Examples
    --------
    >>> round(spread_half_width(10, 0.9545), 3), round(spread_half_width(30, 0.9545), 3)
    (0.669, 0.291)
    """
    require_count("spread cycles", n, 2)
    if not 0 < level < 1:
        raise ConfigError(f"level = {level}, expected a number between 0 and 1")
    # here, not at import; chdtr is scipy.stats.chi2.cdf's own function, without the 0.5 s of importing scipy.stats
    from scipy import optimize, special

    dof = n - 1

    def shortfall(w: float) -> float:
        upper = 1.0 if w >= 1.0 else float(special.chdtr(dof, dof / (1.0 - w) ** 2))
        return upper - float(special.chdtr(dof, dof / (1.0 + w) ** 2)) - level

    return float(optimize.brentq(shortfall, 0.0, 1e3, xtol=1e-10))


def spread_uncertainty(value: float, n: int, *, unit: str, k: float = 2.0) -> Measured:
    """Expanded uncertainty of a spread figure 3 S (RD, RV, RP_a) from n cycles: U = w_p · 3S (chi pivot).

    .. math:: U = w_p \\cdot 3S, \\qquad p = \\mathrm{erf}(k/\\sqrt2)

    with w_p from :func:`spread_half_width`. The instrument's offset cancels in a spread; its noise is part of the
    measured spread (report the instrument's floor beside it, as for RP).

    Examples
    --------
    >>> print(spread_uncertainty(0.3, 10, unit="mm"))
    0.30 ± 0.20 mm (k = 2)
    """
    if value < 0 or not math.isfinite(value):
        raise ConfigError(f"spread = {value}, expected a finite number >= 0")
    return expanded(value, value * spread_half_width(n, math.erf(k / math.sqrt(2.0))) / k, unit=unit, k=k)


def mean_speed_uncertainty(
    av_pct: float,
    speeds_per_cycle_mm_s: ArrayLike,
    commanded_mm_s: float,
    *,
    instrument_u_pct: float = 0.0,
    k: float = 2.0,
) -> Measured:
    """Expanded uncertainty of path velocity accuracy AV (ISO 9283 8.6), in % of the commanded velocity.

    .. math::

        u^2(AV) = \\Big(\\frac{100\\, S_v}{v_c \\sqrt n}\\Big)^2 + u_{inst}^2, \\qquad U = k_p(\\nu_{eff})\\, u(AV)

    with S_v the SD of the n per-cycle mean speeds and ``instrument_u_pct`` the instrument's relative standard
    uncertainty of speed (its scale), Student's factor for the Welch-Satterthwaite ν_eff (:func:`coverage_factor`).
    """
    means = as_series("speeds_per_cycle_mm_s", speeds_per_cycle_mm_s, min_count=2)
    if not commanded_mm_s > 0:
        raise ConfigError(f"commanded_mm_s = {commanded_mm_s}, expected a velocity > 0 mm/s")
    type_a = 100.0 * float(means.std(ddof=1)) / commanded_mm_s / math.sqrt(len(means))
    nu = welch_satterthwaite([type_a, instrument_u_pct], [len(means) - 1, math.inf])
    return expanded(av_pct, math.hypot(type_a, instrument_u_pct), unit="%", k=coverage_factor(k, nu))


@dataclass(frozen=True)
class PathUncertainty:
    """AT_p and RT_p of one path with their expanded uncertainties (:func:`path_uncertainty`)."""

    at: Measured  #: AT_p = max_i |p̄_i - p_ci| with U
    rt: Measured  #: RT_p = max_i (l̄_i + 3 S_li) with U


def _lengths(vectors: np.ndarray) -> np.ndarray:
    """Euclidean length over the last axis, √(x_1² + x_2² + ...) summed axis after axis: ``np.linalg.norm(vectors,
    axis=-1)`` bit for bit (its reduce over a short last axis took ~8x as long: most of the path model's time)."""
    total = vectors[..., 0] * vectors[..., 0]
    for axis in range(1, vectors.shape[-1]):
        total += vectors[..., axis] * vectors[..., axis]
    return np.sqrt(total, out=total)


def _rt_per_station(points: np.ndarray) -> np.ndarray:
    """l̄_i + 3 S_li per station of a stack (..., m, n, d) of crossings: shape (..., m)."""
    distances = _lengths(points - points.mean(axis=-2, keepdims=True))
    return distances.mean(axis=-1) + 3.0 * distances.std(axis=-1, ddof=1)


def _rt_population(covariance: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """E[l] + 3 SD[l] per station for Gaussian crossings of covariances ``covariance`` (m, d, d)."""
    sigmas = np.sqrt(np.clip(np.linalg.eigvalsh(covariance), 0.0, None))  # (m, d)
    normals = rng.standard_normal((_POPULATION_DRAWS, covariance.shape[-1]))
    squares = normals**2  # summed axis after axis, as .sum(axis=-1) does, without its reduce over a 3-long axis
    total = squares[None, :, 0] * sigmas[:, None, 0] ** 2
    for axis in range(1, squares.shape[1]):
        total += squares[None, :, axis] * sigmas[:, None, axis] ** 2
    distances = np.sqrt(total, out=total)
    return distances.mean(axis=1) + 3.0 * distances.std(axis=1)


def _covariances(deviations: np.ndarray) -> np.ndarray:
    """Sample covariance (ddof 1) per station of crossing deviations (..., m, n, d) about their means: (..., m, d, d)."""
    centred = deviations - deviations.mean(axis=-2, keepdims=True)
    return np.einsum("...nd,...ne->...de", centred, centred) / (deviations.shape[-2] - 1)


def _pooled_toward(deviations: np.ndarray, share: float | None = None) -> np.ndarray:
    """The model's crossing deviations (m, n, d): each station's axis variances (the eigenvalues λ_i of its sample
    covariance, largest first) shrunk toward their mean over the stations, λ_i' = (1 - w) λ_i + w λ̄, along the
    station's own axes (so stations whose planes face different ways, the sides of a rectangle, are pooled by
    shape, not by direction). The cycles are scaled along those axes by √(λ_i'/λ_i), which keeps the correlation
    between stations. w = min(1, mean_i v_i / mean_i ‖λ_i - λ̄‖²), v_i the jackknife variance over cycles of
    λ_i - λ̄ (so correlated stations are judged fairly): the share of the stations' differences that sampling
    alone explains. A path whose stations scatter alike keeps its near ties, which raw n = 10 covariances would
    break up; stations that truly differ keep their differences. ``share`` = 1: fully pooled (every station the
    stations' mean shape: the tie hypothesis)."""
    n = deviations.shape[1]
    values, vectors = np.linalg.eigh(_covariances(deviations))  # ascending, per station
    if share is None:  # the jackknife (n leave-one-out covariances) only where the share is to be estimated
        keep = ~np.eye(n, dtype=bool)
        leave_one_out = np.linalg.eigvalsh(_covariances(np.stack([deviations[:, keep[j]] for j in range(n)])))
        differences = leave_one_out - leave_one_out.mean(axis=1, keepdims=True)  # (n, m, d)
        jackknife = (n - 1) / n * np.sum((differences - differences.mean(axis=0)) ** 2, axis=(0, 2))
        heterogeneity = float(np.mean(np.sum((values - values.mean(axis=0)) ** 2, axis=1)))
        share = 1.0 if heterogeneity == 0.0 else min(1.0, float(jackknife.mean()) / heterogeneity)
    target = (1.0 - share) * values + share * values.mean(axis=0)
    floor = 1e-12 * np.max(values, axis=-1, keepdims=True)
    scale = np.where(values > floor, np.sqrt(np.clip(target / np.where(values > floor, values, 1.0), 0.0, None)), 0.0)
    transform = np.einsum("mij,mj,mkj->mik", vectors, scale, vectors)
    return np.einsum("mnd,mde->mne", deviations, transform)


def _mixed(mixing: np.ndarray, deviations: np.ndarray) -> np.ndarray:
    """Simulated cycles (c, m, n, d): each campaign's n cycles are the ``mixing`` (c, n, n) combinations of the
    model's n cycles ``deviations`` (m, n, d), as one matrix product (BLAS: ~15x an einsum of the same sum)."""
    count, n, _ = mixing.shape
    m, _, d = deviations.shape
    flat = deviations.transpose(1, 0, 2).reshape(n, m * d)
    return (mixing.reshape(count * n, n) @ flat).reshape(count, n, m, d).transpose(0, 2, 1, 3)


def _at_and_scale(
    barycentres: np.ndarray, deviations: np.ndarray, stations: np.ndarray, instrument_u_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """AT = max_i |p̄_i - p_ci| of stacks (..., m, d) and its standard error at the arg-max station along the
    deviation there: √(e·S_i·e / n + u_inst²); ``deviations`` (..., m, n, d) are the cycles about p̄_i."""
    offsets = barycentres - stations
    norms = _lengths(offsets)
    worst = np.argmax(norms, axis=-1)
    at = np.take_along_axis(norms, worst[..., None], axis=-1)[..., 0]
    direction = np.take_along_axis(offsets, worst[..., None, None], axis=-2)[..., 0, :]
    direction = direction / np.where(at > 0, at, 1.0)[..., None]
    cycles = np.take_along_axis(deviations, worst[..., None, None, None], axis=-3)[..., 0, :, :]
    n = deviations.shape[-2]
    along = np.einsum("...nd,...d->...n", cycles, direction)
    scale = np.sqrt((along**2).sum(axis=-1) / (n - 1) / n + instrument_u_mm**2)
    return at, scale


def path_uncertainty(
    crossings_mm: ArrayLike,
    stations_mm: ArrayLike,
    *,
    instrument_u_mm: float = 0.0,
    k: float = 2.0,
    draws: int = PATH_MODEL_DRAWS,
    seed: int = 0,
) -> PathUncertainty:
    """AT_p and RT_p (ISO 9283 8.2, 8.3) with expanded uncertainties from a parametric bootstrap-t (JCGM 101).

    With the crossings p_ij of cycle j in the plane of station i (``station_crossings``), e_ij = p_ij - p̄_i and
    the measurement model "the n cycle vectors (e_1j .. e_mj) are Gaussian with the run's sample covariance":

    .. math::

        e^*_{ij} = \\sum_{j'} z_{jj'} \\frac{e_{ij'}}{\\sqrt{n-1}}, \\quad z \\sim N(0, 1), \\qquad
        p^*_{ij} = \\bar p_i + e^*_{ij} + b^*, \\quad b^* \\sim N(0, u_{inst}^2 I)

    simulates ``draws`` campaigns. AT: t* = (AT* - AT_model)/s*, with AT_model = max_i |p̄_i - p_ci| and s* the
    standard error of the barycentre at the arg-max station along its deviation (instrument included);
    U(AT) = q_p(|t*|) · ŝ. RT: W* = |RT* - RT_model| / RT*, with RT_model = max_i (E[l_i] + 3 SD[l_i]) of the
    model; U(RT) = q_p(W*) · RT̂. p = erf(k/√2). Both quantiles carry the small-sample spread of the studentiser
    (Student-like) and the bias of a maximum over stations.

    RT's quantile is the larger of two models' (the same draws): the stations' axis variances pooled by the share
    sampling explains (:func:`_pooled_toward`) and fully pooled (every station alike: the stations tie). At n =
    10-30 the data cannot tell a near tie from an exact one, and a bootstrap of a maximum is inconsistent at ties
    (Fang & Santos, Rev. Econ. Stud. 86 (2019) 377-412; Hirano & Porter, Econometrica 80 (2012) 1769-1790): the
    first model alone covered 89.5 % on a 16-station circle (an exact tie) at n = 30, the larger of the two covers
    it and reads wide (98-100 %) on a near tie [choice: a stated U may be conservative, never short; coverage in
    docs/metrology.md].

    Parameters
    ----------
    crossings_mm : array_like, shape (m, n, d)
        Crossing points per station and cycle, n >= 3 cycles.
    stations_mm : array_like, shape (m, d)
        The commanded stations.
    instrument_u_mm : float
        The instrument's standard uncertainty per axis (an offset common to every reading of the run), mm.
    draws : int
        Simulated campaigns; seed : int, of the simulation (the result is reproducible).
    """
    points = np.asarray(crossings_mm, dtype=float)
    stations = np.asarray(stations_mm, dtype=float)
    if points.ndim != 3 or stations.shape != (points.shape[0], points.shape[2]):
        raise ConfigError(
            f"crossings_mm {points.shape} and stations_mm {stations.shape}, expected (m, n, d) and (m, d)"
        )
    if not np.isfinite(points).all():
        raise ConfigError("crossings_mm: not all finite, expected finite numbers")
    if instrument_u_mm < 0 or not math.isfinite(instrument_u_mm):
        raise ConfigError(f"instrument_u_mm = {instrument_u_mm}, expected a finite number >= 0")
    m, n, d = points.shape
    require_count("path cycles", n, PATH_U_MIN_CYCLES)
    level = math.erf(k / math.sqrt(2.0))
    barycentres = points.mean(axis=1)
    deviations = points - barycentres[:, None, :]
    at_array, scale = _at_and_scale(barycentres, deviations, stations, instrument_u_mm)
    at = float(at_array)
    rt = float(_rt_per_station(points).max())
    rng = np.random.default_rng(seed)
    model = _pooled_toward(deviations)
    tied = _pooled_toward(deviations, share=1.0)
    rt_model = float(_rt_population(_covariances(model), rng).max())
    # a generator of its own, so the AT/RT draws below are those of the pooled model alone (AT unchanged by it)
    rt_tied = float(_rt_population(_covariances(tied), np.random.default_rng([seed, 1])).max())
    t = np.empty(draws)
    w = np.empty(draws)
    w_tied = np.empty(draws)
    chunk = max(1, _SIMULATED_VALUES // (m * n * d))
    for first in range(0, draws, chunk):
        count = min(chunk, draws - first)
        mixing = rng.standard_normal((count, n, n)) / math.sqrt(n - 1)
        simulated = _mixed(mixing, model)  # (count, m, n, d) cycles about the mean
        bias = rng.standard_normal((count, 1, d)) * instrument_u_mm
        sim_mean = simulated.mean(axis=2)
        sim_at, sim_scale = _at_and_scale(
            barycentres + sim_mean + bias, simulated - sim_mean[:, :, None, :], stations, instrument_u_mm
        )
        sim_rt = _rt_per_station(simulated).max(axis=-1)
        sim_tied = _rt_per_station(_mixed(mixing, tied)).max(axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            t[first : first + count] = np.where(sim_scale > 0, np.abs(sim_at - at) / sim_scale, 0.0)
            w[first : first + count] = np.where(sim_rt > 0, np.abs(sim_rt - rt_model) / sim_rt, 0.0)
            w_tied[first : first + count] = np.where(sim_tied > 0, np.abs(sim_tied - rt_tied) / sim_tied, 0.0)
    at_half = float(np.quantile(t, level)) * float(scale)
    rt_half = max(float(np.quantile(w, level)), float(np.quantile(w_tied, level))) * rt
    return PathUncertainty(at=expanded(at, at_half / k, unit="mm", k=k), rt=expanded(rt, rt_half / k, unit="mm", k=k))
