"""GUM uncertainty for the metrology figures: Type A and B components, expanded uncertainty, bootstrap, RP floor.

JCGM 100:2008 (GUM) and JCGM 101:2008 as summarised in ``shared/reference/iso9283.md`` §8. Every figure a report
prints comes with an expanded uncertainty U = k·u_c (k = 2 unless stated) as a `Measured` value. The robot's
scatter (S, used by RP) and the uncertainty of a barycentre (S/√n) are different quantities and kept apart.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError
from bench.metrology._moments import CycleMoments, cycle_moments, sd_of_squares, series_mean
from bench.metrology._validation import as_points, as_series, require_count
from bench.metrology.uncertainty_model import (
    MODEL_MAX_CYCLES,
    _rp_of_samples,
    checked_repeatability_uncertainty_model,
    mean_sd_uncertainty,
    repeatability_uncertainty_model,
)

__all__ = [
    "ConfidenceInterval",
    "Measured",
    "accuracy_uncertainty",
    "bootstrap_uncertainty",
    "combine",
    "coverage_factor",
    "distance_accuracy_uncertainty",
    "expanded",
    "instrument_budget",
    "speed_instrument_budget",
    "instrument_rp_floor",
    "mean_confidence_interval",
    "mean_sd_uncertainty",
    "rectangular",
    "repeatability_uncertainty",
    "repeatability_uncertainty_delta",
    "repeatability_uncertainty_model",
    "resolution_uncertainty",
    "type_a_of_mean",
    "welch_satterthwaite",
]


@dataclass(frozen=True)
class Measured:
    """A value with its expanded uncertainty: report ``value ± expanded_uncertainty`` (unit), k stated."""

    value: float
    expanded_uncertainty: float  #: U = k · u_c
    coverage_factor: float  #: k
    unit: str

    def __str__(self) -> str:
        """``value ± U unit (k = ...)`` rounded by U (GUM 7.2.6, :func:`bench.metrology.formatting.format_measured`)."""
        from bench.metrology.formatting import format_measured  # formatting imports nothing of bench: no cycle

        return f"{format_measured(self.value, self.expanded_uncertainty)} {self.unit} (k = {self.coverage_factor:g})"


@dataclass(frozen=True)
class ConfidenceInterval:
    """Two-sided confidence interval of a mean, with the t quantile used."""

    mean: float
    low: float
    high: float
    t_quantile: float
    n: int


def type_a_of_mean(samples: ArrayLike) -> float:
    """Type A standard uncertainty of a mean, u(x̄) = s / √n (GUM 4.2.3); n >= 2."""
    values = as_series("samples", samples, min_count=2)
    return float(values.std(ddof=1) / np.sqrt(len(values)))


def rectangular(half_width: float) -> float:
    """Type B standard uncertainty of a rectangular distribution of half-width a: a / √3 (GUM 4.3.7)."""
    if half_width < 0:
        raise ConfigError(f"half_width = {half_width}, expected a number >= 0")
    return float(half_width / np.sqrt(3.0))


def resolution_uncertainty(resolution: float, *, difference: bool = False) -> float:
    """Standard uncertainty of digital quantisation δ: δ/√12 for one reading, δ/√6 for a difference of two.

    Examples
    --------
    >>> round(resolution_uncertainty(25.4 / 800, difference=True), 4)
    0.013

    A displacement read from an 800 CPI mouse carries 0.013 mm of quantisation uncertainty (iso9283.md §8.2a).
    """
    if resolution < 0:
        raise ConfigError(f"resolution = {resolution}, expected a number >= 0")
    return float(resolution / np.sqrt(6.0 if difference else 12.0))


def combine(*components: float) -> float:
    """Combined standard uncertainty of uncorrelated components with unit sensitivity: √Σ u_i² (GUM 5.1.2)."""
    return float(np.sqrt(np.sum(np.square(components))))


def expanded(value: float, standard_uncertainty: float, *, unit: str, k: float = 2.0) -> Measured:
    """Expanded uncertainty U = k · u_c (GUM 6.2.1); k = 2 gives about 95 % for large ν_eff."""
    if standard_uncertainty < 0 or not math.isfinite(standard_uncertainty):
        raise ConfigError(f"standard_uncertainty = {standard_uncertainty}, expected a finite number >= 0")
    return Measured(float(value), float(k * standard_uncertainty), float(k), unit)


def welch_satterthwaite(contributions: ArrayLike, degrees_of_freedom: ArrayLike) -> float:
    """Effective degrees of freedom ν_eff = u_c⁴ / Σ (c_i u_i)⁴ / ν_i (GUM G.2b); ν_i = inf for Type B."""
    u = np.asarray(contributions, dtype=float)
    nu = np.asarray(degrees_of_freedom, dtype=float)
    if u.shape != nu.shape:
        raise ConfigError(f"contributions {u.shape} and degrees_of_freedom {nu.shape}, expected the same shape")
    return _welch_satterthwaite(u, nu)


def _welch_satterthwaite(u: np.ndarray, nu: np.ndarray) -> float:
    """:func:`welch_satterthwaite` of float arrays of the same shape."""
    denominator = np.add.reduce(u**4 / nu, axis=None)
    return float("inf") if denominator == 0 else float(np.add.reduce(u**2, axis=None) ** 2 / denominator)


def mean_confidence_interval(values: ArrayLike, *, level: float = 0.95) -> ConfidenceInterval:
    """Confidence interval of a mean over k runs with Student's t_{(1+level)/2, k-1}, never 1.96.

    Examples
    --------
    >>> round(mean_confidence_interval([1.0, 2.0, 3.0]).t_quantile, 3)
    4.303

    With three runs the 95 % interval is 4.3 standard errors wide on each side, not 1.96.
    """
    data = as_series("values", values, min_count=2)
    if not 0 < level < 1:
        raise ConfigError(f"level = {level}, expected a number between 0 and 1")
    from scipy import stats  # here, not at import: scipy.stats alone costs the desktop app ~1 s of start-up

    t = float(stats.t.ppf((1 + level) / 2, len(data) - 1))
    half = t * data.std(ddof=1) / np.sqrt(len(data))
    mean = float(data.mean())
    return ConfidenceInterval(mean, mean - half, mean + half, t, len(data))


def accuracy_uncertainty(
    attained_mm: ArrayLike, commanded_mm: ArrayLike, *, instrument_u_mm: float = 0.0, k: float = 2.0
) -> tuple[Measured, tuple[Measured, ...]]:
    """Expanded uncertainty of AP_P and of each signed AP axis (iso9283.md §8.3).

    .. math::

        u^2(AP_x) = \\frac{s_x^2}{n} + u_{inst}^2, \\qquad
        u^2(AP_P) = \\sum_x \\Big(\\frac{AP_x}{AP_P}\\Big)^2 u^2(AP_x)

    (first-order propagation; at AP_P = 0 the largest axis uncertainty is used). ``instrument_u_mm`` holds the
    instrument's systematic and registration terms per axis (standard uncertainty, mm). The stated coverage factor
    is Student's for the Welch-Satterthwaite ν_eff (:func:`coverage_factor`): with s²/n from 10 cycles, k = 2 alone
    would cover about 92 %.

    Returns
    -------
    tuple of (Measured, tuple of Measured)
        AP_P and the per-axis AP values with U = k · u.
    """
    attained = as_points("attained_mm", attained_mm)
    require_count("accuracy uncertainty cycles", len(attained), 2)
    moments, command = cycle_moments(attained), np.asarray(commanded_mm, dtype=float)
    n = moments.n
    deviation, type_a, u_axes = _axis_terms(moments, command, instrument_u_mm)
    axes = tuple(
        expanded(
            d,
            u,
            unit="mm",
            k=coverage_factor(k, welch_satterthwaite([math.sqrt(a), instrument_u_mm], [n - 1, math.inf])),
        )
        for d, u, a in zip(deviation, u_axes, type_a)
    )
    return moments_ap_uncertainty(moments, command, instrument_u_mm=instrument_u_mm, k=k), axes


def _axis_terms(
    moments: CycleMoments, command: np.ndarray, instrument_u_mm: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per axis: AP_x = x̄ - x_c, the Type A variance s_x²/n of x̄, and u(AP_x) = √(s_x²/n + u_inst²)."""
    type_a = moments.variance / moments.n
    return moments.barycentre - command, type_a, np.sqrt(type_a + instrument_u_mm**2)


def moments_ap_uncertainty(moments: CycleMoments, command: np.ndarray, *, instrument_u_mm: float, k: float) -> Measured:
    """AP_P with its expanded uncertainty, as :func:`accuracy_uncertainty` gives it, of checked cycles (their
    moments, n >= 2) and a float command array (the per-axis figures left out: a pose table reports AP_P's)."""
    n = moments.n
    deviation, type_a, u_axes = _axis_terms(moments, command, instrument_u_mm)
    norm = math.sqrt(deviation.dot(deviation))  # np.linalg.norm(deviation)'s arithmetic, without its wrapper
    weights = np.zeros_like(deviation) if norm == 0 else (deviation / norm) ** 2
    if norm == 0:
        weights[np.argmax(u_axes)] = 1.0
    u_norm = math.sqrt(np.add.reduce(weights * u_axes**2))
    nu_norm = _welch_satterthwaite(
        np.array([*np.sqrt(weights * type_a), instrument_u_mm]), np.array([*[n - 1] * len(type_a), math.inf])
    )
    return expanded(norm, u_norm, unit="mm", k=coverage_factor(k, nu_norm))


def distance_accuracy_uncertainty(
    ad_mm: float, u_ad_mm: float, n: int, *, instrument_u_mm: float = 0.0, k: float = 2.0
) -> Measured:
    """Expanded uncertainty of AD (ISO 9283 7.3): the scatter of the D_j and twice the instrument (a distance is
    the difference of two uncorrelated readings), at Student's factor for the Welch-Satterthwaite ν_eff.

    .. math:: u^2(AD) = S_D^2 / n + 2 u_{inst}^2, \\qquad U = k_p(\\nu_{eff}) \\, u(AD)
    """
    instrument = math.sqrt(2.0) * instrument_u_mm
    nu = welch_satterthwaite([u_ad_mm, instrument], [n - 1, math.inf])
    return expanded(ad_mm, combine(u_ad_mm, instrument), unit="mm", k=coverage_factor(k, nu))


def coverage_factor(k: float, degrees_of_freedom: float) -> float:
    """Student's t factor for the coverage a normal k promises, at ν_eff degrees of freedom (GUM G.3, G.4).

    .. math:: k_p = t_{(1+p)/2,\\,\\nu_{eff}}, \\qquad p = \\mathrm{erf}(k/\\sqrt2)

    so k = 2 asks for 95.45 %: 2.32 at ν = 9 (n = 10 cycles), 2.09 at ν = 29, 2 for ν = inf (Type B only).

    Examples
    --------
    >>> round(coverage_factor(2.0, 9), 2)
    2.32
    """
    if not math.isfinite(degrees_of_freedom):
        return float(k)
    return _student_factor(float(k), float(degrees_of_freedom))


@lru_cache(maxsize=4096)
def _student_factor(k: float, degrees_of_freedom: float) -> float:
    """:func:`coverage_factor` at finite ν, cached: the poses of one table mostly share ν = n - 1."""
    from scipy.special import stdtrit  # here, not at import; scipy.special loads in a third of scipy.stats' time

    level = math.erf(k / math.sqrt(2.0))
    return float(stdtrit(degrees_of_freedom, (1.0 + level) / 2.0))


def bootstrap_uncertainty(
    statistic: Callable[[np.ndarray], float], attained: ArrayLike, *, resamples: int = 1000, seed: int = 0
) -> float:
    """Standard uncertainty of a non-linear statistic (e.g. RP) from a bootstrap over cycles (JCGM 101 spirit).

    Parameters
    ----------
    statistic : callable
        Maps an (n, d) array to a float, e.g. ``lambda p: pose_repeatability(p).rp_mm``.
    attained : array_like, shape (n, d)
        Samples, one row per cycle; n >= 3.
    resamples : int
        Number of bootstrap resamples (with replacement, whole cycles).
    seed : int
        Seed of the random generator: the result is reproducible.
    """
    points = as_points("attained", attained, dims=None)
    require_count("bootstrap cycles", len(points), 3)
    rng = np.random.default_rng(seed)
    index = rng.integers(0, len(points), size=(resamples, len(points)))
    values = np.array([statistic(points[rows]) for rows in index])
    return float(values.std(ddof=1))


#: Resampled cycles held in memory at once (resamples are drawn and evaluated in chunks of about this many cycles).
_BOOTSTRAP_CHUNK_CYCLES = 1_000_000


def repeatability_uncertainty(
    attained_mm: ArrayLike, *, resamples: int = 1000, seed: int = 0, method: str = "auto"
) -> float:
    """Standard uncertainty of RP_l: the measurement-model Monte Carlo at small n, the delta method above.

    ``method = "bootstrap"``: the same estimate as ``bootstrap_uncertainty(lambda p: pose_repeatability(p).rp_mm,
    ...)`` with the same seed: resample whole cycles with replacement, recompute RP_l = l̄ + 3 S_l for each
    resample, and take the sample standard deviation of those values. Vectorised over chunks of resamples, so the
    memory stays bounded (about ``_BOOTSTRAP_CHUNK_CYCLES`` x d floats) whatever n; the draws are those of one
    ``rng.integers(0, n, (resamples, n))`` call. ``"delta"``: :func:`repeatability_uncertainty_delta`.
    ``"model"``: :func:`repeatability_uncertainty_model`. ``"auto"`` (default): the model up to
    ``MODEL_MAX_CYCLES`` cycles, the delta method above (where RP's small-sample bias is under a tenth of its
    spread). The bootstrap is kept for comparison only: at n = 10 its k = 2 interval covers the truth 75 % of the
    time (it understates the spread and ignores the bias; docs/metrology.md).

    Parameters
    ----------
    attained_mm : array_like, shape (n, d)
        Attained positions of one pose, n >= 3.
    """
    points = as_points("attained_mm", attained_mm)
    require_count("bootstrap cycles", len(points), 3)
    if method not in ("auto", "bootstrap", "delta", "model"):
        raise ConfigError(f"method = {method!r}, expected 'auto', 'bootstrap', 'delta' or 'model'")
    if method == "model":
        return repeatability_uncertainty_model(points)
    if method == "delta":
        return repeatability_uncertainty_delta(points)
    if method == "auto":
        return moments_repeatability_uncertainty(cycle_moments(points))
    n = len(points)
    rng = np.random.default_rng(seed)
    chunk = max(1, _BOOTSTRAP_CHUNK_CYCLES // n)
    rp = np.empty(resamples)
    for first in range(0, resamples, chunk):
        count = min(chunk, resamples - first)
        samples = points[rng.integers(0, n, size=(count, n))]
        distances = np.sqrt(np.sum((samples - samples.mean(axis=1, keepdims=True)) ** 2, axis=2))
        rp[first : first + count] = distances.mean(axis=1) + 3.0 * distances.std(axis=1, ddof=1)
    return float(rp.std(ddof=1))


def moments_repeatability_uncertainty(moments: CycleMoments, rp_mm: float | None = None) -> float:
    """:func:`repeatability_uncertainty` (``method="auto"``) of checked cycles (their moments), n >= 3; ``rp_mm``:
    their RP_l when known (:func:`bench.metrology.iso9283.pose_repeatability`), else computed here."""
    if moments.n > MODEL_MAX_CYCLES:
        return moments_repeatability_uncertainty_delta(moments)
    rp = float(_rp_of_samples(moments.points)) if rp_mm is None else rp_mm
    return checked_repeatability_uncertainty_model(moments.points, rp)


def repeatability_uncertainty_delta(attained_mm: ArrayLike) -> float:
    """Standard uncertainty of RP_l = l̄ + 3 S_l by the nonparametric delta method (infinitesimal jackknife).

    With the barycentre p̄, l_j = ‖p_j - p̄‖ and unit vectors u_j = (p_j - p̄)/l_j, the empirical influence of
    cycle j on RP_l (the barycentre's own influence included) is

    .. math::

        IF_j = (l_j - \\bar l) - \\bar u \\cdot (p_j - \\bar p)
               + \\frac{3}{2 S_l}\\left[(l_j - \\bar l)^2 - S_l^2 - 2\\,\\bar w \\cdot (p_j - \\bar p)\\right],
        \\quad \\bar u = \\frac1n\\sum_j u_j, \\quad \\bar w = \\frac1n\\sum_j (l_j - \\bar l)\\,u_j

    and u(RP_l) = √(Σ_j IF_j²) / n (Efron & Tibshirani, *An Introduction to the Bootstrap*, 1993, ch. 21: the
    infinitesimal jackknife, the large-n limit of the bootstrap standard error). O(n) time and memory.

    Parameters
    ----------
    attained_mm : array_like, shape (n, d)
        Attained positions of one pose, n >= 3.
    """
    points = as_points("attained_mm", attained_mm)
    require_count("cycles", len(points), 3)
    return moments_repeatability_uncertainty_delta(cycle_moments(points))


def moments_repeatability_uncertainty_delta(moments: CycleMoments) -> float:
    """:func:`repeatability_uncertainty_delta` of checked cycles (their moments), n >= 3."""
    n, offsets = moments.n, moments.offsets
    distances = np.sqrt(np.einsum("ij,ij->i", offsets, offsets))
    # numpy scalars, as distances.mean() and .std() gave them: spread**2 below is numpy's power, bit for bit
    mean_l = np.float64(series_mean(distances))
    deviation = distances - mean_l
    squared_deviation = deviation**2
    spread = np.float64(sd_of_squares(squared_deviation))
    if spread == 0.0:
        return 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        units = np.where(distances[:, None] > 0, offsets / distances[:, None], 0.0)
    mean_u = np.add.reduce(units, axis=0) / n  # units.mean(axis=0), without its wrapper
    mean_w = np.add.reduce(deviation[:, None] * units, axis=0) / n
    influence = (
        deviation - offsets @ mean_u + 3.0 / (2.0 * spread) * (squared_deviation - spread**2 - 2.0 * (offsets @ mean_w))
    )
    return float(np.sqrt(np.add.reduce(influence**2)) / n)


def instrument_rp_floor(sigma_mm: float, *, dims: int) -> float:
    """Expected RP of a perfectly repeatable robot seen through Gaussian instrument noise σ per axis (large n).

    iso9283.md §8.4 [R]: l follows a chi distribution with d degrees of freedom scaled by σ, so

    .. math::

        E[l] = \\sigma \\sqrt2\\, \\frac{\\Gamma((d+1)/2)}{\\Gamma(d/2)}, \\quad
        SD[l] = \\sqrt{d\\sigma^2 - E[l]^2}, \\quad RP_{floor} = E[l] + 3 SD[l]

    giving 3.616 σ (3-D), 3.219 σ (2-D) and 2.606 σ (1-D). With finite n the barycentre estimate shrinks l by
    about √((n - 1)/n). Report it next to every RP; never subtract it silently.

    Examples
    --------
    >>> round(instrument_rp_floor(0.355, dims=2), 2)
    1.14

    The dissertation's worst mouse scatter alone would produce an RP of about 1.14 mm in 2-D.
    """
    if dims not in (1, 2, 3):
        raise ConfigError(f"dims = {dims}, expected 1, 2 or 3")
    if sigma_mm < 0:
        raise ConfigError(f"sigma_mm = {sigma_mm}, expected a number >= 0")
    mean = math.sqrt(2.0) * math.exp(math.lgamma((dims + 1) / 2) - math.lgamma(dims / 2))
    return float(sigma_mm * (mean + 3.0 * np.sqrt(dims - mean**2)))


def _budget(u: float | None, source: str, *, figure: str, unit: str, name: str) -> str:
    """``figure`` excludes the instrument (none declared) or includes it with ``u`` in ``unit``, from ``source``."""
    if u is None:
        return f"{figure} excludes the instrument: none declared ({source})"
    if u < 0 or not math.isfinite(u):
        raise ConfigError(f"{name} = {u}, expected a finite number >= 0")
    return f"{figure} includes the instrument: u = {u:g} {unit} ({source})"


def instrument_budget(instrument_u_mm: float | None, source: str) -> str:
    """The instrument's place in a U budget, in words: its standard uncertainty and where it came from, or a plain
    statement that U excludes it. Never a silent 0: a bias the instrument adds to every reading cannot be seen in
    the readings' scatter, so a U without it covers only the robot's scatter (46 % coverage with an undeclared
    offset of the instrument's size, issue 32).

    Examples
    --------
    >>> instrument_budget(None, "--instrument-u-mm")
    'U excludes the instrument: none declared (--instrument-u-mm)'
    >>> instrument_budget(0.05, "station file")
    'U includes the instrument: u = 0.05 mm per axis (station file)'
    """
    return _budget(instrument_u_mm, source, figure="U", unit="mm per axis", name="instrument_u_mm")


def speed_instrument_budget(instrument_u_pct: float | None, source: str) -> str:
    """The speed instrument's place in U(AV) (its relative standard uncertainty, its scale), in words, as
    :func:`instrument_budget` says it for a position instrument: never a silent 0.

    Examples
    --------
    >>> speed_instrument_budget(None, "--instrument-u-pct")
    'U(AV) excludes the instrument: none declared (--instrument-u-pct)'
    >>> speed_instrument_budget(0.5, "--instrument-u-pct")
    'U(AV) includes the instrument: u = 0.5 % (--instrument-u-pct)'
    """
    return _budget(instrument_u_pct, source, figure="U(AV)", unit="%", name="instrument_u_pct")
