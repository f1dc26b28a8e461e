r"""A calibration campaign on a robot with play: per-pose means weighted by their measured scatter, and the plan of
how many cycles per pose a target gain needs. Pure computation, arrays in and out.

A reading of pose i in cycle c is ``m_ic = p_i + eta_ic + e_ic``: the robot's attained pose, its play (passive
joints; 0.6 mm per axis per move on the documented pkm5) and the instrument's error. The geometry fixes ``p_i``
only, so the fit takes each pose's mean ``m_i = mean_c m_ic`` with the standard uncertainty of that mean
(GUM 4.2.3, type A)

.. math:: u(m_{i,a}) = \max(s_{i,a}, u_{inst}) / \sqrt{n_i}, \quad
          s_{i,a}^2 = \frac{(n_i - 1)\, \hat s_{i,a}^2 + \nu_0\, s_a^2}{n_i - 1 + \nu_0},

``hat s_ia`` pose i's own standard deviation over its ``n_i`` readings and ``s_a`` the within-pose standard deviation
of axis a pooled over the poses (``sum_i sum_c (m_ica - m_ia)^2 / (M - N)``, M readings of N poses). The pooled
value is a prior worth ``nu_0`` = :data:`POOLED_DOF` degrees of freedom (the conjugate scaled-inverse-chi^2 update
of a normal variance, Gelman et al., Bayesian Data Analysis 3rd ed. §2.6): a pose's own scatter from 2-3 cycles is
too uncertain to weight by alone (3 cycles give a standard deviation within a factor 2 of the truth only ~75 % of
the time), yet a pose where the robot really scatters more is weighted down (seen on the simulated pkm5: a beta
pose whose x spread over 22 mm in 10 cycles against 0.7 mm elsewhere; weighted by the pooled scatter it alone
made the fit's reduced chi^2 2.8). ``u_inst`` is the instrument's stated standard uncertainty per reading, a floor:
a scatter measured below what the instrument claims (a deterministic simulator, a quantised reading repeated) is
not trusted below it. With one cycle per pose (no scatter measured) ``u_inst`` stands alone. The robot's scatter
and the instrument's figure are kept apart (:class:`PoseMeans`): the report prints both.

The plan (:func:`plan_campaign`) for a target gain G over the geometric error ``g`` the fit removes: with n cycles
per pose the posterior covariance is ``C(n) = (n J_1^T J_1 + diag(sigma^-2))^{-1}``, ``J_1`` the Jacobian over the
scatter of one reading, and the calibration leaves at pose i the error ``e_i(n) = sqrt(tr(J_i C(n) J_i^T))``
(the propagated covariance, GUM 5.1.2); a validation run of ``n_v`` cycles reads each pose's mean with the play's
``sqrt(sum_a s_a^2 / n_v)``. Splitting the allowed error ``g / G`` equally (in quadrature) between the two, the
calibration needs the least n with ``mean_i e_i(n) <= g / (G sqrt 2)`` and the validation
``n_v = ceil(2 G^2 sum_a s_a^2 / g^2)``. However well calibrated, a validation of ``n_v`` cycles cannot show more
than ``g / sqrt(sum_a s_a^2 / n_v)`` (the gain the play allows). ``g`` is the in-sample error before with the
means' own scatter taken out in quadrature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import InsufficientData

__all__ = [
    "ERRATIC_FALSE_ALARM",
    "MAX_CYCLES",
    "POOLED_DOF",
    "CampaignPlan",
    "PoseMeans",
    "erratic_poses",
    "plan_campaign",
    "pose_means",
]

#: Degrees of freedom the pooled scatter counts for in each pose's own (module docstring): as much as 10 readings.
POOLED_DOF = 10.0
#: A pose is erratic when its own scatter exceeds the other poses' by more than an F-test lets pass with this
#: probability (:func:`erratic_poses`).
ERRATIC_FALSE_ALARM = 1e-6
#: The most cycles per pose a plan proposes; a target that needs more is said to be out of reach.
MAX_CYCLES = 1000


@dataclass(frozen=True)
class PoseMeans:
    """Per-pose means of a campaign and their uncertainties (module docstring)."""

    mean_mm: np.ndarray  # (N, a)
    uncertainty_mm: np.ndarray  # (N, a) standard uncertainty of each mean
    cycles: np.ndarray  # (N,) readings per pose
    scatter_mm: np.ndarray  # (a,) pooled within-pose standard deviation of one reading; NaN: not measured
    scatter_dof: int  # its degrees of freedom, M - N
    instrument_mm: float  # the instrument's stated standard uncertainty per reading
    left_out: tuple[int, ...] = ()  # erratic poses left out (their indices in the protocol's order)

    def as_dict(self) -> dict[str, Any]:
        return {
            "scatter_mm": [None if not np.isfinite(s) else float(s) for s in self.scatter_mm],
            "scatter_dof": self.scatter_dof,
            "instrument_uncertainty_mm": float(self.instrument_mm),
            "cycles_per_pose": [int(n) for n in self.cycles],
            "left_out_poses": list(self.left_out),
            "mean_uncertainty_mm": [float(u) for u in np.sqrt(np.mean(self.uncertainty_mm**2, axis=0))],
        }


def pose_means(readings: ArrayLike, pose_index: ArrayLike, instrument_mm: float) -> PoseMeans:
    """The per-pose means of ``readings`` (M, a) labelled by ``pose_index`` (M,) (0..N-1, each pose at least once)
    and their standard uncertainties (module docstring)."""
    readings = np.asarray(readings, dtype=float)
    index = np.asarray(pose_index, dtype=int)
    if readings.ndim != 2 or len(index) != len(readings) or not len(readings):
        raise InsufficientData(f"readings {readings.shape} with {len(index)} pose labels, expected (M, a) and M labels")
    count = int(index.max()) + 1
    cycles = np.bincount(index, minlength=count)
    if np.any(cycles == 0):
        raise InsufficientData(f"pose {int(np.flatnonzero(cycles == 0)[0])} has no reading, expected every pose read")
    sums = np.zeros((count, readings.shape[1]))
    np.add.at(sums, index, readings)
    mean = sums / cycles[:, None]
    dof = len(readings) - count
    if dof > 0:
        squares = np.zeros_like(mean)
        np.add.at(squares, index, (readings - mean[index]) ** 2)
        scatter = np.sqrt(squares.sum(axis=0) / dof)
        own_dof = (cycles - 1)[:, None]
        per_pose = np.sqrt((squares + POOLED_DOF * scatter**2) / (own_dof + POOLED_DOF))
        per_reading = np.maximum(per_pose, instrument_mm)
    else:
        scatter = np.full(readings.shape[1], np.nan)
        per_reading = np.full(mean.shape, float(instrument_mm))
    return PoseMeans(mean, per_reading / np.sqrt(cycles)[:, None], cycles, scatter, dof, float(instrument_mm))


def erratic_poses(
    readings: ArrayLike, pose_index: ArrayLike, instrument_mm: float = 0.0, false_alarm: float = ERRATIC_FALSE_ALARM
) -> np.ndarray:
    """Which poses (bool (N,)) scatter more than the others beyond chance: per axis, the variance ratio
    ``F = max(hat s_i, u_inst)^2 / max(s_rest, u_inst)^2`` of the pose's own readings against the pooled
    within-pose variance of the other poses, both floored at the instrument's stated ``instrument_mm`` (a scatter
    below it is the instrument's resolution, e.g. one count among repeated identical readings, not the robot), with
    ``(n_i - 1, M - N - (n_i - 1))`` degrees of freedom (the F-test of equal variances, NIST/SEMATECH
    e-Handbook §1.3.5.9), above its upper ``false_alarm`` quantile on any axis. Such a pose does not repeat as the
    robot does elsewhere (seen on the simulated pkm5: a beta pose near an FK fold spread 22 mm in x over 10 cycles
    against 0.7 mm elsewhere, its mean 19 mm off the others' geometry): its mean measures no geometry, so the fit
    leaves it out and says so. Poses read once are never erratic (nothing to test)."""
    from scipy.stats import f as f_distribution

    readings = np.asarray(readings, dtype=float)
    index = np.asarray(pose_index, dtype=int)
    count = int(index.max()) + 1
    cycles = np.bincount(index, minlength=count)
    mean = np.zeros((count, readings.shape[1]))
    np.add.at(mean, index, readings)
    mean /= cycles[:, None]
    squares = np.zeros_like(mean)
    np.add.at(squares, index, (readings - mean[index]) ** 2)
    own_dof = cycles - 1
    rest_dof = (len(readings) - count) - own_dof
    testable = (own_dof > 0) & (rest_dof > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        floor = float(instrument_mm) ** 2
        ratio = np.maximum(squares / own_dof[:, None], floor) / np.maximum(
            (squares.sum(axis=0) - squares) / rest_dof[:, None], floor
        )
    limit = f_distribution.isf(false_alarm, np.maximum(own_dof, 1), np.maximum(rest_dof, 1))
    return testable & np.any(ratio > limit[:, None], axis=1)


@dataclass(frozen=True)
class CampaignPlan:
    """Cycles per pose a target gain needs (module docstring); None where :data:`MAX_CYCLES` do not reach it."""

    target_gain: float
    geometric_error_mm: float  # g: what the calibration can remove
    scatter_mm: float  # sqrt(sum_a s_a^2): one reading's play, all axes
    calibration_cycles: int | None
    validation_cycles: int | None
    informing_cycles: int | None  # the least cycles with which the data inform half the parameters with a prior
    predicted_error_mm: float  # mean_i e_i at the campaign's own cycles

    def ceiling_gain(self, validation_cycles: int) -> float:
        """The most gain a validation of ``validation_cycles`` cycles can show (module docstring)."""
        return self.geometric_error_mm / (self.scatter_mm / np.sqrt(validation_cycles))

    def as_dict(self) -> dict[str, Any]:
        return {
            "target_gain": self.target_gain,
            "geometric_error_mm": self.geometric_error_mm,
            "scatter_mm": self.scatter_mm,
            "calibration_cycles": self.calibration_cycles,
            "validation_cycles": self.validation_cycles,
            "informing_cycles": self.informing_cycles,
            "predicted_error_mm": self.predicted_error_mm,
        }


def _least_cycles(good: Callable[[int], bool]) -> int | None:
    """The least n in 1..MAX_CYCLES with ``good(n)`` (monotone in n), by bisection; None if none."""
    if not good(MAX_CYCLES):
        return None
    low, high = 0, MAX_CYCLES
    while high - low > 1:
        middle = (low + high) // 2
        low, high = (low, middle) if good(middle) else (middle, high)
    return high


def plan_campaign(
    jac: ArrayLike,
    campaign: PoseMeans,
    prior_sigma: ArrayLike,
    before_mm: float,
    target_gain: float,
    informed_share: float = 0.5,
    prior_only_ratio: float = 1 / np.sqrt(2),
) -> CampaignPlan:
    """The plan of :class:`CampaignPlan` (module docstring) from the model Jacobian ``jac`` (N, a, K) at the
    poses' means, the campaign's scatter, the prior's 1-sigma ``prior_sigma`` (K,) (inf: none) and the in-sample
    error before ``before_mm``."""
    jac = np.asarray(jac, dtype=float)
    sigma = np.asarray(prior_sigma, dtype=float)
    scatter = np.where(
        np.isfinite(campaign.scatter_mm),
        np.maximum(campaign.scatter_mm, campaign.instrument_mm),
        campaign.instrument_mm,
    )
    one = (jac / scatter[None, :, None]).reshape(-1, jac.shape[-1])
    normal = one.T @ one
    precision = np.where(np.isfinite(sigma), 1.0 / np.square(sigma), 0.0)

    def covariance(n: float) -> np.ndarray:
        return np.linalg.pinv(n * normal + np.diag(precision))

    def pose_error(n: float) -> float:
        cov = covariance(n)
        return float(np.mean(np.sqrt(np.einsum("nak,kl,nal->n", jac, cov, jac))))

    def informs(n: float) -> bool:
        std = np.sqrt(np.diag(covariance(n)))
        with_prior = np.isfinite(sigma)
        return np.sum(std[with_prior] <= prior_only_ratio * sigma[with_prior]) >= informed_share * with_prior.sum()

    noise = float(np.sqrt(np.mean(np.sum(campaign.uncertainty_mm**2, axis=1))))
    geometric = float(np.sqrt(max(before_mm**2 - noise**2, 0.0)))
    allowed = geometric / (target_gain * np.sqrt(2.0))
    total = float(np.sqrt(np.sum(scatter**2)))
    validation = int(np.ceil(2.0 * target_gain**2 * total**2 / geometric**2)) if geometric > 0 else None
    return CampaignPlan(
        float(target_gain),
        geometric,
        total,
        _least_cycles(lambda n: pose_error(n) <= allowed),
        validation if validation is not None and validation <= MAX_CYCLES else None,
        _least_cycles(informs),
        pose_error(float(np.mean(campaign.cycles))),
    )
