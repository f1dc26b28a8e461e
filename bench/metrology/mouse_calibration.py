"""Optical-mouse resolution calibration: the dissertation's per-distance method and least-squares fits.

Counts are raw sensor counts or, in the dissertation's route, OS cursor pixels; displacements are in mm. Methods
from ``shared/reference/sensors.md`` §5.1 (dissertation App. A.7) and §5.2 (project recommendation: the forward
model c = B r fitted by ordinary least squares, inverted to A = B⁻¹ in mm/count).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData
from bench.metrology._validation import (
    as_points,
    as_series,
    require_count,
    require_same_length,
)
from bench.metrology.mouse_variance import feasible_gls, move_error_structures
from bench.metrology.uncertainty import coverage_factor

__all__ = [
    "MM_PER_INCH",
    "AxisCalibration",
    "CalibrationMoves",
    "IncrementResolution",
    "MatrixCalibration",
    "counts_per_inch",
    "student_k95",
    "direction_labels",
    "fit_axis_scale",
    "fit_matrix",
    "increment_resolution",
    "increments_from_positions",
    "mouse_calibration_moves",
]

#: Millimetres per inch; one count is ``MM_PER_INCH / CPI`` mm (``sensors.md`` §1.1).
MM_PER_INCH = 25.4
#: The normal coverage factor of 95 % (Student's factor replaces it at finite degrees of freedom).
_K95 = 1.959963984540054


@dataclass(frozen=True)
class IncrementResolution:
    """Dissertation-parity resolution of one axis at one increment length (App. A.7)."""

    resolution_mm_per_count: float  #: distance / mean Δ
    mean_delta_counts: float  #: mean Δ
    three_sigma_counts: float  #: 3 S(Δ), n - 1
    tolerance_mm: float  #: 3 S(Δ) x resolution (the dissertation's "tolerance")
    n: int  #: number of increments


@dataclass(frozen=True)
class AxisCalibration:
    """Per-axis linear fit counts = slope · reference + offset, inverted to a scale in mm/count."""

    scale_mm_per_count: float  #: 1 / slope
    u_scale_mm_per_count: float  #: standard uncertainty of the scale (first order)
    slope_counts_per_mm: float
    offset_counts: float  #: intercept; significantly non-zero means lost counts or backlash
    u_offset_counts: float
    residual_rms_counts: float
    residuals_counts: tuple[float, ...]
    n: int


@dataclass(frozen=True, eq=False)
class MatrixCalibration:
    """2x2 calibration absorbing sensor rotation and cross-talk: d = A · c (sensors.md §5.2).

    ``offsets_counts`` are the fitted intercepts, one row (sensor x, sensor y) per entry of ``offset_labels``:
    ``("all",)`` for one common intercept, a move direction each (``"+x"``, ``"-y"``...) when fitted per direction,
    none without. A significant one (:attr:`offsets_significant`) is a start/stop offset, lost counts or backlash
    that a fit without it would have put into A.
    """

    a_mm_per_count: np.ndarray  #: (2, 2) A = B⁻¹
    u_a_mm_per_count: np.ndarray  #: (2, 2) standard uncertainty of each element of A
    b_counts_per_mm: np.ndarray  #: (2, 2) forward matrix B
    offset_counts: np.ndarray  #: (2,) the common intercept (zeros when fitted without one or per direction)
    residuals_counts: np.ndarray  #: (K, 2)
    sigma_counts: np.ndarray  #: (2,) residual standard deviation per sensor axis
    rotation_deg: float  #: θ of the polar decomposition A = Rot(θ) S
    scale_mm_per_count: np.ndarray  #: (2,) |A e_x|, |A e_y|: mm per count along each sensor axis
    n: int
    dof: int = 0  #: residual degrees of freedom K - p per sensor axis
    offset_labels: tuple[str, ...] = ()  #: what each row of ``offsets_counts`` belongs to
    #: (len(offset_labels), 2) fitted intercepts, counts, and their standard uncertainties
    offsets_counts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    u_offsets_counts: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def coverage_factor(self) -> float:
        """k for 95 % coverage: Student's t at ``dof`` (the residual SD is estimated from few moves)."""
        return student_k95(self.dof)

    @property
    def expanded_a_mm_per_count(self) -> np.ndarray:
        """U(A) = k · u(A), the 95 % expanded uncertainty of each element of A."""
        return self.coverage_factor * self.u_a_mm_per_count

    @property
    def offsets_significant(self) -> np.ndarray:
        """(len(offset_labels), 2) bool: |intercept| > k · u(intercept), non-zero at 95 %."""
        return np.abs(self.offsets_counts) > self.coverage_factor * self.u_offsets_counts

    def u_scale_mm_per_count(self, reference_u_rel: float = 0.0) -> np.ndarray:
        """(2,) standard uncertainty of :attr:`scale_mm_per_count`: the fit's, to first order,
        u(|a|)² = Σ_i (a_i / |a|)² u(a_i)² over the column a = A e_axis, combined with the reference's relative
        scale u (``reference_u_rel`` · scale; GUM 5.1.2, uncorrelated)."""
        a, u = self.a_mm_per_count, self.u_a_mm_per_count
        u_fit = np.sqrt(np.sum((a / self.scale_mm_per_count * u) ** 2, axis=0))
        return np.hypot(u_fit, reference_u_rel * self.scale_mm_per_count)


def counts_per_inch(scale_mm_per_count: float, u_scale_mm_per_count: float) -> tuple[float, float]:
    """A scale in mm/count as counts per inch with its uncertainty: cpi = 25.4 / s, u(cpi) = cpi · u(s) / s
    (first order, GUM 5.1.3), so a printed cpi carries no more digits than the scale's U supports."""
    cpi = MM_PER_INCH / scale_mm_per_count
    return cpi, cpi * u_scale_mm_per_count / scale_mm_per_count


def student_k95(dof: int) -> float:
    """Coverage factor k = t_{0.975, ν} for 95 % of a quantity whose standard uncertainty has ν degrees of freedom
    (GUM, JCGM 100:2008, G.3 and G.4): k = 2.36 at ν = 7, 2.05 at ν = 27. One home for Student's factor:
    :func:`bench.metrology.uncertainty.coverage_factor` at the normal k of 95 % (1.96)."""
    if dof < 1:
        raise InsufficientData(f"coverage factor: {dof} degrees of freedom, expected >= 1")
    return coverage_factor(_K95, dof)


def direction_labels(reference_mm: ArrayLike) -> tuple[str, ...]:
    """The direction of each move: its dominant stage axis and sign (``"+x"``, ``"-x"``, ``"+y"``, ``"-y"``).

    >>> direction_labels([[5.0, 0.1], [-10.0, 0.0], [0.0, 20.0]])
    ('+x', '-x', '+y')
    """
    reference = np.asarray(reference_mm, dtype=float).reshape(-1, 2)
    axis = np.argmax(np.abs(reference), axis=1)
    sign = np.sign(reference[np.arange(len(reference)), axis])
    return tuple(f"{'+' if s >= 0 else '-'}{'xy'[a]}" for a, s in zip(axis, sign))


def increments_from_positions(positions: ArrayLike) -> np.ndarray:
    """Absolute count increments |Δ| between successive positions; NaN marks a restart (segment break).

    The dissertation's raw tables print "N/A" where the cursor was re-positioned near the screen edge: no
    increment is formed across such a break (it is never read as zero).

    Examples
    --------
    >>> increments_from_positions([951, 926, 902, float("nan"), 10, 35]).tolist()
    [25.0, 24.0, 25.0]

    The jump from 902 to 10 after the restart marker is not an increment.
    """
    values = np.asarray(positions, dtype=float)
    if values.ndim != 1:
        raise ConfigError(f"positions: shape {values.shape}, expected a 1-D array")
    delta = np.abs(np.diff(values))
    return delta[np.isfinite(delta)]


def increment_resolution(distance_mm: float, increments_counts: ArrayLike) -> IncrementResolution:
    """Resolution and "tolerance" of one axis from repeated equal increments (dissertation App. A.7).

    .. math::

        r = d / \\bar\\Delta, \\qquad \\text{tolerance} = 3 S_\\Delta \\cdot r, \\quad
        S_\\Delta = \\sqrt{\\textstyle\\sum (\\Delta_k - \\bar\\Delta)^2 / (n - 1)}

    The "tolerance" is a 3σ scatter at one distance and one speed, not a bound.

    Parameters
    ----------
    distance_mm : float
        Length of each increment (mm), > 0.
    increments_counts : array_like, shape (n,)
        Count (or pixel) increments, n >= 2 (see `increments_from_positions`).

    Examples
    --------
    Table A.28 (Y axis, mouse speed 4, 5 mm increments):

    >>> deltas = [25, 24, 25, 24, 24, 24, 25, 24, 25, 25, 24, 25, 24, 25, 24, 24, 23, 24]
    >>> r = increment_resolution(5.0, deltas)
    >>> round(r.mean_delta_counts, 2), round(r.resolution_mm_per_count, 4), round(r.three_sigma_counts, 2)
    (24.33, 0.2055, 1.78)

    The printed average 24.33 px, resolution 0.21 mm/px and Table A.25's 3σ of 1.78 px are reproduced.
    """
    if not distance_mm > 0:
        raise ConfigError(f"distance_mm = {distance_mm}, expected a number > 0")
    increments = as_series("increments_counts", increments_counts, min_count=2)
    mean = float(increments.mean())
    if mean == 0:
        raise ConfigError("increments_counts: mean increment is 0 counts, expected a moving sensor")
    resolution = distance_mm / mean
    three_sigma = 3.0 * float(increments.std(ddof=1))
    return IncrementResolution(
        resolution_mm_per_count=resolution,
        mean_delta_counts=mean,
        three_sigma_counts=three_sigma,
        tolerance_mm=three_sigma * resolution,
        n=len(increments),
    )


def fit_axis_scale(reference_mm: ArrayLike, counts: ArrayLike) -> AxisCalibration:
    """Least-squares scale and offset of one sensor axis against reference displacements.

    The sensor is the noisy side, so the forward model is fitted and inverted (sensors.md §5.2):

    .. math::

        c_k = \\beta r_k + c_0 + e_k, \\quad s = 1/\\beta, \\quad u(s) = u(\\beta) / \\beta^2

    with u(β), u(c_0) from the OLS covariance σ̂² (XᵀX)⁻¹, σ̂² = Σ e_k² / (K - 2).

    Parameters
    ----------
    reference_mm : array_like, shape (K,)
        Reference displacements (mm), K >= 3, not all equal.
    counts : array_like, shape (K,)
        Count increments measured for each move.
    """
    reference = as_series("reference_mm", reference_mm, min_count=3)
    measured = as_series("counts", counts)
    require_same_length("reference_mm", reference, "counts", measured)
    if np.ptp(reference) == 0:
        raise ConfigError("reference_mm: all moves have the same length, expected at least two lengths")
    design = np.column_stack([reference, np.ones_like(reference)])
    coefficients, *_ = np.linalg.lstsq(design, measured, rcond=None)
    residuals = measured - design @ coefficients
    sigma2 = float(residuals @ residuals) / (len(reference) - 2)
    covariance = sigma2 * np.linalg.inv(design.T @ design)
    slope, offset = (float(v) for v in coefficients)
    if slope == 0:
        raise InsufficientData("fit_axis_scale: the counts do not change with the reference (slope 0)")
    return AxisCalibration(
        scale_mm_per_count=1.0 / slope,
        u_scale_mm_per_count=float(np.sqrt(covariance[0, 0])) / slope**2,
        slope_counts_per_mm=slope,
        offset_counts=offset,
        u_offset_counts=float(np.sqrt(covariance[1, 1])),
        residual_rms_counts=float(np.sqrt(np.mean(residuals**2))),
        residuals_counts=tuple(float(v) for v in residuals),
        n=len(reference),
    )


def _weighted_rows(
    reference: np.ndarray, measured: np.ndarray, design: np.ndarray, readings: ArrayLike
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Coefficients (p, 2), residuals (K, 2) and each sensor axis's coefficient covariance (p, p) of the feasible
    GLS (:func:`bench.metrology.mouse_variance.feasible_gls`): the reference's error shows on the sensor axis
    along each move's step axis."""
    numbers = np.asarray(readings)
    if numbers.shape != (len(reference), 2):
        raise ConfigError(f"readings: shape {numbers.shape}, expected ({len(reference)}, 2): a start and an end a move")
    step_axis = np.array(["xy".index(label[1]) for label in direction_labels(reference)])
    fits = [feasible_gls(measured[:, i], design, *move_error_structures(numbers, step_axis == i)) for i in range(2)]
    coefficients = np.column_stack([fit.coefficients for fit in fits])
    return coefficients, np.column_stack([fit.residuals for fit in fits]), [fit.covariance for fit in fits]


def _rotation_deg(matrix: np.ndarray) -> float:
    """θ of the polar decomposition matrix = Rot(θ) · S (S symmetric positive-definite)."""
    u, _, vt = np.linalg.svd(matrix)
    rotation = u @ vt
    return float(np.degrees(np.arctan2(rotation[1, 0], rotation[0, 0])))


def fit_matrix(
    reference_mm: ArrayLike,
    counts: ArrayLike,
    *,
    intercept: bool = False,
    per_direction: bool = False,
    readings: ArrayLike | None = None,
) -> MatrixCalibration:
    """Least-squares 2x2 calibration c = B r (+ c_0 or + c_0,d per move direction d) and A = B⁻¹ with uncertainties.

    sensors.md §5.2 [P], rows k stacked into R (K x 2), the intercept columns D (K x q) and C (K x 2), X = [R D]:

    .. math::

        [B\\;C_0]^T = (X^T X)^{-1} X^T C, \\quad E = C - X [B\\;C_0]^T, \\quad
        \\hat\\sigma_i^2 = \\frac{\\sum_k E_{ki}^2}{K - p}, \\quad
        \\operatorname{Cov}(B_{i\\cdot}) = \\hat\\sigma_i^2 [(X^T X)^{-1}]_{RR}

    and u(A) by first-order propagation of dA = -A dB A (sensor axes independent); p = 2 + q. The 95 % expanded
    uncertainty uses Student's t at K - p degrees of freedom (:attr:`MatrixCalibration.expanded_a_mm_per_count`).
    A start/stop offset (a fraction of a count every move, in the move's direction) biases a fit without
    intercept; ``per_direction`` fits one intercept per move direction (:func:`direction_labels`), which models it
    whether the moves go one way or both, and is the production fit (``intercept`` fits one common intercept).

    With ``readings`` the fit weighs what scatters each move (:mod:`bench.metrology.mouse_variance`):
    per sensor axis i, Cov(E_i) = θ_1 I + θ_2 (D Dᵀ)_along i + D Dᵀ / 12, the sensor's tracking noise a move, the
    reference's error a reading along the step axis, and the readings' quantisation, a known Type B component of
    1/12 count² a reading (GUM F.2.2.1), shared by the two moves that share a reading. θ is estimated by REML and
    the fit is the GLS with it, Cov(B_i·) = [(Xᵀ V̂_i⁻¹ X)⁻¹]_RR; U keeps Student's t at K - p. Without it each
    sensor axis's residual variance is pooled over all moves (ordinary least squares, as above), which a chain of
    moves sharing readings, or a reference error on the moves along one axis only, leaves under-covered.

    Parameters
    ----------
    reference_mm : array_like, shape (K, 2)
        Reference displacements in the stage frame (mm); at least two non-parallel directions.
    counts : array_like, shape (K, 2)
        Count increments of the two sensor axes for each move.
    readings : array_like of int, shape (K, 2), optional
        The number of each move's start and end reading: moves that name one number share that reading (the
        protocol's out-and-back chain, :func:`mouse_calibration_moves`). Given, the fit is the feasible GLS above.

    Raises
    ------
    InsufficientData
        K <= p (no residual degrees of freedom), moves along one direction only (cross terms unidentifiable), or,
        per direction, a direction whose moves all have one length (its intercept and the scale confound).
    """
    reference = as_points("reference_mm", reference_mm, dims=(2,))
    measured = as_points("counts", counts, dims=(2,))
    require_same_length("reference_mm", reference, "counts", measured)
    if per_direction:
        per_move = direction_labels(reference)
        labels = tuple(sorted(set(per_move)))
        columns = np.array([[label == d for d in labels] for label in per_move], dtype=float)
    elif intercept:
        labels, columns = ("all",), np.ones((len(reference), 1))
    else:
        labels, columns = (), np.zeros((len(reference), 0))
    parameters = 2 + len(labels)
    require_count("matrix calibration moves", len(reference), parameters + 1)
    design = np.column_stack([reference, columns])
    normal = design.T @ design
    if np.linalg.matrix_rank(reference.T @ reference) < 2:
        raise InsufficientData("fit_matrix: moves along fewer than two non-parallel directions, cannot fit 2x2")
    if np.linalg.matrix_rank(normal) < parameters:
        raise InsufficientData(
            f"fit_matrix: the moves of some direction ({', '.join(labels)}) all have one length, "
            "so its intercept and the scale cannot be told apart; use at least two lengths each"
        )
    dof = len(reference) - parameters
    if readings is None:
        inverse = np.linalg.inv(normal)
        coefficients = inverse @ design.T @ measured
        residuals = measured - design @ coefficients
        row_covariances = [s2 * inverse for s2 in np.sum(residuals**2, axis=0) / dof]
    else:
        coefficients, residuals, row_covariances = _weighted_rows(reference, measured, design, readings)
    sigma2 = np.sum(residuals**2, axis=0) / dof
    b = coefficients[:2].T
    a = np.linalg.inv(b)
    # Jacobian of vec(A) w.r.t. vec(B): ∂A_kl/∂B_ij = -A_ki A_jl; rows of B (sensor axes) are independent.
    jacobian = -np.einsum("ki,jl->klij", a, a).reshape(4, 4)
    cov_b = np.zeros((4, 4))
    for i in range(2):
        cov_b[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = row_covariances[i][:2, :2]
    cov_a = jacobian @ cov_b @ jacobian.T
    offsets = coefficients[2:]
    u_offsets = np.sqrt(np.column_stack([np.diag(c)[2:] for c in row_covariances]))
    return MatrixCalibration(
        a_mm_per_count=a,
        u_a_mm_per_count=np.sqrt(np.diag(cov_a)).reshape(2, 2),
        b_counts_per_mm=b,
        offset_counts=offsets[0] if labels == ("all",) else np.zeros(2),
        residuals_counts=residuals,
        sigma_counts=np.sqrt(sigma2),
        rotation_deg=_rotation_deg(a),
        scale_mm_per_count=np.linalg.norm(a, axis=0),
        n=len(reference),
        dof=dof,
        offset_labels=labels,
        offsets_counts=offsets,
        u_offsets_counts=u_offsets,
    )


class CalibrationMoves(NamedTuple):
    """A calibration run's moves, as :func:`fit_matrix` takes them."""

    reference_mm: np.ndarray  #: (K, 2) reference displacements
    counts: np.ndarray  #: (K, 2) the x-y mouse's count increments
    readings: np.ndarray  #: (K, 2) the number of each move's start and end reading (its sample's place in step order)


def mouse_calibration_moves(samples: Any, references: Any = None) -> CalibrationMoves:
    """The moves between consecutive readings of one step axis: reference displacements (K, 2) mm, the x-y
    mouse's count increments (K, 2) and the numbers of each move's start and end reading (K, 2).

    ``samples`` are the ``mouse`` samples in step order (pose ``<axis><mm>/<start|end>``); the reference position of
    each is its calliper reading along the axis (``references``, ``mouse_reference`` samples matched by pose and
    cycle) when given, else its commanded position. The moves back to a step's start count too (moves in both
    directions: a start/stop offset is told from the scale); a move and the next share the reading between them,
    and its quantisation and reference error (:func:`fit_matrix`).
    """
    readings = {(r.pose, r.cycle): r.values["reference_mm"] for r in references or ()}
    reference, counts, numbers = [], [], []
    for index, (before, after) in enumerate(itertools.pairwise(samples)):
        axis = (after.pose or "?")[0]
        if axis not in "xy" or (before.pose or "?")[0] != axis:
            continue
        column = "xy".index(axis)
        if references is not None:
            if (before.pose, before.cycle) not in readings or (after.pose, after.cycle) not in readings:
                continue
            travel = [0.0, 0.0]
            travel[column] = readings[(after.pose, after.cycle)] - readings[(before.pose, before.cycle)]
        else:
            travel = [after.values[f"cmd_{a}_mm"] - before.values[f"cmd_{a}_mm"] for a in "xy"]
        if abs(travel[column]) < 1e-9:
            continue
        reference.append(travel)
        counts.append([after.values[f"mouse_xy_{a}_counts"] - before.values[f"mouse_xy_{a}_counts"] for a in "xy"])
        numbers.append((index, index + 1))
    return CalibrationMoves(
        np.array(reference, dtype=float).reshape(-1, 2),
        np.array(counts, dtype=float).reshape(-1, 2),
        np.array(numbers, dtype=int).reshape(-1, 2),
    )
