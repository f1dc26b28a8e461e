"""Payload error: the project's definition (not an ISO term) of how pose and leg errors change with load.

``shared/reference/iso9283.md`` §12 [P]: leg actuation error e_i(m) per leg and load (the dissertation's Table
A.14), the pose-level payload error PE(m) = x̄(m) - x̄(m₀) between loads at the same command pose, and a payload
compliance estimate k (mm/N) by regression. k sits next to, but is never called, ISO 9283 static compliance
(clause 10), which applies forces in six directions at the mechanical interface.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology._validation import (
    as_points,
    as_series,
    require_count,
    require_same_length,
)

__all__ = [
    "STANDARD_GRAVITY_M_S2",
    "LegErrorSummary",
    "PayloadCompliance",
    "PayloadShift",
    "leg_error_summary",
    "payload_compliance",
    "payload_shift",
]

#: Standard acceleration of gravity (m/s²). The dissertation's 25.23 kg ↔ 247.51 N implies 9.81.
STANDARD_GRAVITY_M_S2 = 9.80665


@dataclass(frozen=True)
class LegErrorSummary:
    """Per-leg summary of leg actuation error against load (dissertation Table 8-5 and more)."""

    max_error_mm: tuple[float, ...]  #: largest error per leg
    load_at_max_kg: tuple[float, ...]  #: load of the first occurrence of that largest error
    mean_error_mm: tuple[float, ...]
    correlation_with_load: tuple[float | None, ...]  #: Pearson r per leg (None when a leg's error is constant)
    overall_mean_mm: float
    overall_sd_mm: float  #: sample SD (n - 1) over every value
    n_loads: int


@dataclass(frozen=True, eq=False)
class PayloadShift:
    """Barycentre shift PE(m) = x̄(m) - x̄(m₀) at one command pose, per load (iso9283.md §12.1 item 2)."""

    load_kg: np.ndarray  #: (k,) loads, ascending
    shift_mm: np.ndarray  #: (k, d) signed PE(m)
    shift_norm_mm: np.ndarray  #: (k,) |PE(m)|
    barycentre_mm: np.ndarray  #: (k, d)
    reference_load_kg: float


@dataclass(frozen=True)
class PayloadCompliance:
    """Least-squares slope of displacement against added weight (mm/N), with its standard uncertainty."""

    compliance_mm_per_n: float
    u_compliance_mm_per_n: float
    intercept_mm: float
    residual_sd_mm: float
    n: int


def leg_error_summary(load_kg: ArrayLike, leg_error_mm: ArrayLike) -> LegErrorSummary:
    """Largest error per leg, the load at which it occurred, and its correlation with load.

    Leg actuation error e_i(m) = |L_i,meas(m) - L_i,cmd| (dissertation §8.7, Table A.14); Pearson

    .. math:: r_i = \\frac{\\sum_k (m_k - \\bar m)(e_{ik} - \\bar e_i)}{\\sqrt{\\sum_k (m_k - \\bar m)^2
              \\sum_k (e_{ik} - \\bar e_i)^2}}

    Parameters
    ----------
    load_kg : array_like, shape (k,)
        Load of each rung (kg).
    leg_error_mm : array_like, shape (k, legs)
        Error of each leg at each load (mm); absolute values as in Table A.14, or signed.

    Examples
    --------
    >>> s = leg_error_summary([1, 2, 3], [[0.1, 0.3], [0.2, 0.2], [0.3, 0.3]])
    >>> s.max_error_mm, s.load_at_max_kg, s.correlation_with_load[0]
    ((0.3, 0.3), (3.0, 1.0), 1.0)

    Leg 1 grows with the load; leg 2 first peaks at 1 kg and shows no trend (r = 0).
    """
    loads = as_series("load_kg", load_kg, min_count=2)
    errors = as_points("leg_error_mm", leg_error_mm, dims=None)
    require_same_length("load_kg", loads, "leg_error_mm", errors)
    peak = np.argmax(errors, axis=0)
    correlations = []
    for column in errors.T:
        constant = np.ptp(column) == 0 or np.ptp(loads) == 0
        correlations.append(None if constant else float(np.corrcoef(loads, column)[0, 1]))
    return LegErrorSummary(
        max_error_mm=tuple(float(v) for v in errors.max(axis=0)),
        load_at_max_kg=tuple(float(loads[i]) for i in peak),
        mean_error_mm=tuple(float(v) for v in errors.mean(axis=0)),
        correlation_with_load=tuple(correlations),
        overall_mean_mm=float(errors.mean()),
        overall_sd_mm=float(errors.std(ddof=1)),
        n_loads=len(loads),
    )


def payload_shift(attained_by_load_mm: Mapping[float, ArrayLike], *, reference_load_kg: float) -> PayloadShift:
    """Pose-level payload error PE(m) = x̄(m) - x̄(m₀) at one command pose.

    iso9283.md §12.1 [P]: x̄(m) is the barycentre of the attained poses with load m, m₀ the declared reference
    load (stated in the report). The z component is the sag under load.

    Parameters
    ----------
    attained_by_load_mm : mapping of float to array_like (n_m, d)
        Attained positions per load (kg -> mm), same command pose, velocity and approach.
    reference_load_kg : float
        m₀; must be one of the keys.
    """
    if reference_load_kg not in attained_by_load_mm:
        raise ConfigError(
            f"reference_load_kg = {reference_load_kg}, expected one of the loads {sorted(attained_by_load_mm)}"
        )
    loads = np.array(sorted(attained_by_load_mm), dtype=float)
    clouds = [as_points(f"load {m:g} kg", attained_by_load_mm[m]) for m in sorted(attained_by_load_mm)]
    if len({c.shape[1] for c in clouds}) != 1:
        raise ConfigError("attained_by_load_mm: clouds of different dimensions")
    for load, cloud in zip(loads, clouds):
        require_count(f"payload samples at {load:g} kg", len(cloud), 1)
    barycentres = np.array([c.mean(axis=0) for c in clouds])
    shift = barycentres - barycentres[int(np.flatnonzero(loads == reference_load_kg)[0])]
    return PayloadShift(
        load_kg=loads,
        shift_mm=shift,
        shift_norm_mm=np.linalg.norm(shift, axis=1),
        barycentre_mm=barycentres,
        reference_load_kg=float(reference_load_kg),
    )


def payload_compliance(
    load_kg: ArrayLike, displacement_mm: ArrayLike, *, reference_load_kg: float, g_m_s2: float = STANDARD_GRAVITY_M_S2
) -> PayloadCompliance:
    """Payload compliance estimate k: least-squares slope of displacement against added weight, with intercept.

    .. math::

        \\delta_k = \\delta_0 + k\\,(m_k - m_0)\\,g + e_k, \\quad
        u(k) = \\sqrt{\\frac{\\sum e_k^2 / (K - 2)}{\\sum (F_k - \\bar F)^2}}

    Parameters
    ----------
    load_kg : array_like, shape (K,)
        Load per measurement (kg); at least 3 measurements at 2 or more distinct loads.
    displacement_mm : array_like, shape (K,)
        Displacement along one direction, e.g. PE_z(m) (mm).
    reference_load_kg : float
        m₀ (kg).
    g_m_s2 : float
        Acceleration of gravity (m/s²), standard gravity by default; state it in the report.
    """
    loads = as_series("load_kg", load_kg, min_count=3)
    displacement = as_series("displacement_mm", displacement_mm)
    require_same_length("load_kg", loads, "displacement_mm", displacement)
    force_n = (loads - reference_load_kg) * g_m_s2
    spread = float(np.sum((force_n - force_n.mean()) ** 2))
    if spread == 0:
        raise InsufficientData("payload compliance: all measurements at one load, at least 2 loads required")
    slope = float(np.sum((force_n - force_n.mean()) * (displacement - displacement.mean())) / spread)
    intercept = float(displacement.mean() - slope * force_n.mean())
    residuals = displacement - (intercept + slope * force_n)
    residual_var = float(residuals @ residuals) / (len(loads) - 2)
    return PayloadCompliance(
        compliance_mm_per_n=slope,
        u_compliance_mm_per_n=float(np.sqrt(residual_var / spread)),
        intercept_mm=intercept,
        residual_sd_mm=float(np.sqrt(residual_var)),
        n=len(loads),
    )
