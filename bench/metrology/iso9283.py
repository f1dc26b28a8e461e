"""ISO 9283:1998 pose characteristics from attained samples: AP, RP, vAP, AD/RD, exchangeability.

Pure functions over numpy arrays in the scipy.stats style: samples of one command pose are an array of shape
(n cycles, d) with d = 3 for spatial instruments, 2 for planar sensors and 1 for single-axis gauges. Results
are frozen dataclasses. Positions are in mm, angles in degrees. Formulas and clause numbers follow
``shared/reference/iso9283.md`` §6; the confidence tag of each formula ([N] checked against the national
adoption GOST R 60.3.3.1-2016, [C] corroborated, [U] unverified) is repeated in each docstring, and a formula
tagged [C] or [U] still has to be checked against a licensed copy of the standard.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError
from bench.metrology._moments import CycleMoments, cycle_moments, series_mean, series_sd
from bench.metrology._validation import (
    as_points,
    as_vector,
    require_count,
    require_same_length,
)

__all__ = [
    "DistanceCharacteristics",
    "MultidirectionalVariation",
    "OrientationAccuracy",
    "OrientationDistanceCharacteristics",
    "OrientationRepeatability",
    "OrientationVariation",
    "PoseAccuracy",
    "PoseRepeatability",
    "circular_mean_deg",
    "distance_characteristics",
    "exchangeability",
    "multidirectional_variation",
    "orientation_accuracy",
    "orientation_distance_characteristics",
    "orientation_multidirectional_variation",
    "orientation_repeatability",
    "pose_accuracy",
    "pose_repeatability",
    "wrap_deg",
]


@dataclass(frozen=True)
class PoseAccuracy:
    """Position accuracy at one command pose (ISO 9283 7.2.1)."""

    ap_mm: float  #: AP_P >= 0, distance from the command position to the barycentre
    ap_axes_mm: tuple[float, ...]  #: signed (AP_x, AP_y[, AP_z]) = barycentre - command
    barycentre_mm: tuple[float, ...]  #: (x̄, ȳ[, z̄])
    n: int  #: number of cycles


@dataclass(frozen=True)
class PoseRepeatability:
    """Position repeatability at one command pose (ISO 9283 7.2.2)."""

    rp_mm: float  #: RP_l = l̄ + 3 S_l >= 0
    l_mean_mm: float  #: l̄, mean distance of the attained points to their barycentre
    s_l_mm: float  #: S_l, sample standard deviation (n - 1) of those distances
    spread_3s_axes_mm: tuple[float, ...]  #: 3 S_x, 3 S_y[, 3 S_z]: per-axis spread, NOT an ISO RP
    n: int


@dataclass(frozen=True)
class OrientationAccuracy:
    """Orientation accuracy AP_a, AP_b, AP_c at one command pose (ISO 9283 7.2.1)."""

    ap_deg: tuple[float, ...]  #: signed mean angle - command angle, wrapped to [-180, 180)
    mean_deg: tuple[float, ...]  #: circular means ā, b̄, c̄
    n: int


@dataclass(frozen=True)
class OrientationRepeatability:
    """Orientation repeatability RP_a, RP_b, RP_c = 3 S (ISO 9283 7.2.2), reported as ± values."""

    rp_deg: tuple[float, ...]
    n: int


@dataclass(frozen=True)
class MultidirectionalVariation:
    """Largest distance between the barycentres of clouds approached from different directions (7.2.3)."""

    vap_mm: float  #: vAP_p >= 0
    barycentres_mm: tuple[tuple[float, ...], ...]  #: one barycentre per approach direction (or per robot)
    farthest_pair: tuple[int, int]  #: indices (h, k) of the two barycentres that are farthest apart


@dataclass(frozen=True)
class OrientationVariation:
    """Multi-directional orientation accuracy variation vAP_a, vAP_b, vAP_c at one command pose (7.2.3)."""

    vap_deg: tuple[float, ...]  #: per angle, max_{h,k} |ā_h - ā_k| >= 0
    mean_deg: tuple[tuple[float, ...], ...]  #: circular means per approach direction


@dataclass(frozen=True)
class DistanceCharacteristics:
    """Distance accuracy AD and repeatability RD between two command poses (ISO 9283 7.3)."""

    ad_mm: float  #: AD_p = D̄ - D_c, signed: negative when the robot falls short
    rd_mm: float  #: RD = 3 S_D >= 0, reported as ±
    ad_axes_mm: tuple[float, ...]  #: AD_x, AD_y[, AD_z], signed
    rd_axes_mm: tuple[float, ...]  #: RD_x, RD_y[, RD_z]
    mean_distance_mm: float  #: D̄
    commanded_distance_mm: float  #: D_c
    u_ad_mm: float  #: Type A standard uncertainty of AD from the scatter of D_j: S_D / √n
    n: int


@dataclass(frozen=True)
class OrientationDistanceCharacteristics:
    """Per-angle distance accuracy AD_a/b/c and repeatability RD_a/b/c (ISO 9283 7.3)."""

    ad_deg: tuple[float, ...]  #: signed D̄_a - D_ca (likewise b, c)
    rd_deg: tuple[float, ...]  #: 3 S(D_a), reported as ±
    n: int


def wrap_deg(angle_deg: ArrayLike) -> np.ndarray:
    """Wrap angles to [-180, 180) degrees."""
    return (np.asarray(angle_deg, dtype=float) + 180.0) % 360.0 - 180.0


def circular_mean_deg(angles_deg: ArrayLike, axis: int = 0) -> np.ndarray:
    """Circular mean of angles in degrees, in [-180, 180).

    .. math:: \\bar a = \\operatorname{atan2}\\Big(\\sum_j \\sin a_j, \\sum_j \\cos a_j\\Big)

    For a spread of a few degrees this equals the arithmetic mean ISO 9283 uses, and unlike it does not break
    at ±180° (``iso9283.md`` §6.18, invariant 11): the mean of {179°, -179°} is -180°, never 0°.
    """
    radians = np.deg2rad(np.asarray(angles_deg, dtype=float))
    mean = np.arctan2(np.sin(radians).sum(axis=axis), np.cos(radians).sum(axis=axis))
    return wrap_deg(np.rad2deg(mean))


def pose_accuracy(attained_mm: ArrayLike, commanded_mm: ArrayLike) -> PoseAccuracy:
    """Position accuracy AP of one command pose, against the COMMANDED position.

    ISO 9283:1998 clause 7.2.1, Eqs. for AP_P and AP_x/y/z [N]; dissertation Eqs. 8.4-8.7:

    .. math::

        \\bar x = \\frac1n\\sum_{j=1}^n x_j, \\quad AP_x = \\bar x - x_c, \\quad
        AP_P = \\sqrt{AP_x^2 + AP_y^2 + AP_z^2}

    Parameters
    ----------
    attained_mm : array_like, shape (n, d)
        Attained positions, one row per cycle, d = 1, 2 or 3 (mm).
    commanded_mm : array_like, shape (d,)
        Command position (mm). Never the first attained sample.

    Returns
    -------
    PoseAccuracy
        ``ap_mm`` >= 0 and the signed per-axis ``ap_axes_mm`` (the dissertation prints them as absolute values,
        which hides the sign of the systematic error).

    Examples
    --------
    >>> r = pose_accuracy([[10.1, 0.0, 5.0], [10.3, 0.0, 5.0]], [10.0, 0.0, 5.4])
    >>> round(r.ap_mm, 3), tuple(round(v, 3) for v in r.ap_axes_mm)
    (0.447, (0.2, 0.0, -0.4))

    The barycentre lies 0.2 mm beyond the command in x and 0.4 mm below it in z.
    """
    attained = as_points("attained_mm", attained_mm)
    command = as_vector("commanded_mm", commanded_mm, length=attained.shape[1])
    require_count("pose accuracy cycles", len(attained), 1)
    return moments_accuracy(cycle_moments(attained), command)


def moments_accuracy(moments: CycleMoments, command: np.ndarray) -> PoseAccuracy:
    """:func:`pose_accuracy` of checked cycles (their moments) and a checked command of the same length."""
    barycentre = moments.barycentre
    deviation = barycentre - command
    return PoseAccuracy(
        ap_mm=math.sqrt(np.add.reduce(deviation**2)),
        ap_axes_mm=tuple(deviation.tolist()),
        barycentre_mm=tuple(barycentre.tolist()),
        n=moments.n,
    )


def pose_repeatability(attained_mm: ArrayLike) -> PoseRepeatability:
    """Position repeatability RP_l of one command pose.

    ISO 9283:1998 clause 7.2.2 [C: same form in three public codebases and the dissertation, Eqs. 8.11-8.14;
    verify the wording against a licensed copy]:

    .. math::

        l_j = \\lVert p_j - \\bar p \\rVert, \\quad \\bar l = \\frac1n \\sum_j l_j, \\quad
        S_l = \\sqrt{\\frac{\\sum_j (l_j - \\bar l)^2}{n-1}}, \\quad RP_l = \\bar l + 3 S_l

    Parameters
    ----------
    attained_mm : array_like, shape (n, d)
        Attained positions, one row per cycle; n >= 2 (S needs n - 1 >= 1).

    Returns
    -------
    PoseRepeatability
        ``rp_mm`` >= 0. RP_l is not the root-sum-square of the per-axis spreads (Table 8-4, point 1-1: 2.71 mm
        against an RSS of 3.37 mm); ``spread_3s_axes_mm`` gives 3 S per axis, labelled as such.

    Raises
    ------
    InsufficientData
        With fewer than 2 cycles.

    Examples
    --------
    >>> round(pose_repeatability([[0, 0, 0], [2, 0, 0]]).rp_mm, 3)
    1.0

    Both points lie 1 mm from their barycentre, so the scatter S_l is zero and RP equals l̄.
    """
    attained = as_points("attained_mm", attained_mm)
    require_count("pose repeatability cycles", len(attained), 2)
    return moments_repeatability(cycle_moments(attained))


def moments_repeatability(moments: CycleMoments) -> PoseRepeatability:
    """:func:`pose_repeatability` of checked cycles (their moments), n >= 2."""
    distances = np.sqrt(np.add.reduce(moments.squares, axis=1))
    l_mean = series_mean(distances)
    s_l = series_sd(distances, l_mean)
    return PoseRepeatability(
        rp_mm=l_mean + 3.0 * s_l,
        l_mean_mm=l_mean,
        s_l_mm=s_l,
        spread_3s_axes_mm=tuple((3.0 * np.sqrt(moments.variance)).tolist()),
        n=moments.n,
    )


def orientation_accuracy(attained_deg: ArrayLike, commanded_deg: ArrayLike) -> OrientationAccuracy:
    """Orientation accuracy AP_a, AP_b, AP_c (ISO 9283 7.2.1 [N]).

    .. math:: AP_a = \\bar a - a_c \\quad (\\text{likewise } b, c)

    ``ā`` is the circular mean (see `circular_mean_deg`), a documented method choice that equals ISO's arithmetic
    mean for small spreads and stays correct across ±180°; the difference is wrapped to [-180, 180).

    Parameters
    ----------
    attained_deg : array_like, shape (n, k)
        Attained angles a, b, c about the base x, y, z axes (deg), k = 1..3.
    commanded_deg : array_like, shape (k,)
        Command angles (deg).
    """
    attained = as_points("attained_deg", attained_deg)
    command = as_vector("commanded_deg", commanded_deg, length=attained.shape[1])
    require_count("orientation accuracy cycles", len(attained), 1)
    mean = circular_mean_deg(attained)
    return OrientationAccuracy(
        ap_deg=tuple(float(v) for v in wrap_deg(mean - command)),
        mean_deg=tuple(float(v) for v in mean),
        n=len(attained),
    )


def orientation_repeatability(attained_deg: ArrayLike) -> OrientationRepeatability:
    """Orientation repeatability RP_a, RP_b, RP_c (ISO 9283 7.2.2 [U]).

    .. math:: RP_a = \\pm 3 S_a = \\pm 3 \\sqrt{\\frac{\\sum_j (a_j - \\bar a)^2}{n-1}}

    Deviations a_j - ā are taken from the circular mean and wrapped to [-180, 180).

    Raises
    ------
    InsufficientData
        With fewer than 2 cycles.
    """
    attained = as_points("attained_deg", attained_deg)
    require_count("orientation repeatability cycles", len(attained), 2)
    deviation = wrap_deg(attained - circular_mean_deg(attained))
    s = np.sqrt(np.sum(deviation**2, axis=0) / (len(attained) - 1))
    return OrientationRepeatability(rp_deg=tuple(float(v) for v in 3.0 * s), n=len(attained))


def _approach_clouds(name: str, clouds: Sequence[ArrayLike]) -> list[np.ndarray]:
    """Two or more point clouds of one dimension, each of at least one cycle (ConfigError naming ``name``)."""
    if len(clouds) < 2:
        raise ConfigError(f"{name}: {len(clouds)} cloud(s) given, expected at least 2 to compare")
    points = [as_points(f"{name}[{i}]", cloud) for i, cloud in enumerate(clouds)]
    if len({p.shape[1] for p in points}) != 1:
        raise ConfigError(f"{name}: clouds of different dimensions {[p.shape[1] for p in points]}")
    for i, cloud in enumerate(points):
        require_count(f"{name}[{i}] cycles", len(cloud), 1)
    return points


def _barycentre_spread(name: str, clouds: Sequence[ArrayLike]) -> MultidirectionalVariation:
    points = _approach_clouds(name, clouds)
    barycentres = np.array([p.mean(axis=0) for p in points])
    pairs = list(combinations(range(len(points)), 2))
    distances = [float(np.linalg.norm(barycentres[h] - barycentres[k])) for h, k in pairs]
    best = int(np.argmax(distances))
    return MultidirectionalVariation(
        vap_mm=distances[best],
        barycentres_mm=tuple(tuple(float(v) for v in b) for b in barycentres),
        farthest_pair=pairs[best],
    )


def multidirectional_variation(approaches_mm: Sequence[ArrayLike]) -> MultidirectionalVariation:
    """Multi-directional pose accuracy variation vAP_p (ISO 9283 7.2.3 [U]; definition ISO 8373 [N]).

    .. math:: vAP_p = \\max_{h,k} \\lVert \\bar p_h - \\bar p_k \\rVert, \\quad h, k = 1..3

    Parameters
    ----------
    approaches_mm : sequence of array_like, each shape (n_h, d)
        Attained positions at ONE command pose, one array per approach direction (ISO: three perpendicular
        directions, 30 cycles each). Cycle counts may differ between directions.
    """
    return _barycentre_spread("approaches_mm", approaches_mm)


def orientation_multidirectional_variation(approaches_deg: Sequence[ArrayLike]) -> OrientationVariation:
    """Multi-directional orientation accuracy variation vAP_a, vAP_b, vAP_c (ISO 9283 7.2.3 [U]).

    .. math:: vAP_a = \\max_{h,k} |\\bar a_h - \\bar a_k| \\quad (\\text{likewise } b, c), \\quad h, k = 1..3

    ``ā_h`` is the circular mean of the angles attained from direction h (see `circular_mean_deg`); the
    difference is wrapped to [-180, 180) before the absolute value, so clouds at 179° and -179° are 2° apart.

    Parameters
    ----------
    approaches_deg : sequence of array_like, each shape (n_h, k)
        Attained angles at ONE command pose, one array per approach direction, k = 1..3 angles.

    Examples
    --------
    >>> r = orientation_multidirectional_variation([[[179.0], [179.0]], [[-179.0]], [[178.5]]])
    >>> [round(v, 6) for v in r.vap_deg]
    [2.5]
    """
    clouds = _approach_clouds("approaches_deg", approaches_deg)
    means = np.array([circular_mean_deg(c) for c in clouds])
    spread = np.max([np.abs(wrap_deg(means[h] - means[k])) for h, k in combinations(range(len(means)), 2)], axis=0)
    return OrientationVariation(
        vap_deg=tuple(float(v) for v in spread), mean_deg=tuple(tuple(float(v) for v in m) for m in means)
    )


def exchangeability(clouds_mm: Sequence[ArrayLike]) -> MultidirectionalVariation:
    """Exchangeability E: largest distance between the barycentres of exchanged robots (ISO 9283 7.7 [U]).

    .. math:: E = \\max_{h,k} \\lVert \\bar p_h - \\bar p_k \\rVert

    ``clouds_mm`` holds one (n_h, d) array per robot or per mounting, at the same command pose. The exact
    formula and pose set of clause 7.7 must be checked against a licensed copy; ``vap_mm`` holds E.
    """
    return _barycentre_spread("clouds_mm", clouds_mm)


def distance_characteristics(
    first_mm: ArrayLike, second_mm: ArrayLike, commanded_first_mm: ArrayLike, commanded_second_mm: ArrayLike
) -> DistanceCharacteristics:
    """Distance accuracy AD and repeatability RD between two command poses, paired by cycle.

    ISO 9283:1998 clause 7.3 [N]; P_c1 = P2 and P_c2 = P4 in the standard test:

    .. math::

        D_j = \\lVert A_j - B_j \\rVert, \\quad D_c = \\lVert A_c - B_c \\rVert, \\quad
        AD_p = \\bar D - D_c, \\quad RD = \\pm 3 \\sqrt{\\frac{\\sum_j (D_j - \\bar D)^2}{n-1}}

    and per axis D_xj = |x_Aj - x_Bj|, D_cx = |x_Ac - x_Bc|, AD_x = D̄_x - D_cx, RD_x = 3 S(D_x).

    Parameters
    ----------
    first_mm, second_mm : array_like, shape (n, d)
        Attained positions at the first and second command pose; row j of both is cycle j (the pairing matters:
        shuffling only one side changes RD).
    commanded_first_mm, commanded_second_mm : array_like, shape (d,)
        The two command positions (mm).

    Raises
    ------
    InsufficientData
        With fewer than 2 cycles.
    """
    first = as_points("first_mm", first_mm)
    second = as_points("second_mm", second_mm, dims=(first.shape[1],))
    require_same_length("first_mm", first, "second_mm", second)
    require_count("distance cycles", len(first), 2)
    cmd_first = as_vector("commanded_first_mm", commanded_first_mm, length=first.shape[1])
    cmd_second = as_vector("commanded_second_mm", commanded_second_mm, length=first.shape[1])
    per_axis = np.abs(first - second)
    distance = np.sqrt(np.sum(per_axis**2, axis=1))
    commanded_axes = np.abs(cmd_first - cmd_second)
    commanded = float(np.sqrt(np.sum(commanded_axes**2)))
    return DistanceCharacteristics(
        ad_mm=float(distance.mean()) - commanded,
        rd_mm=3.0 * float(distance.std(ddof=1)),
        ad_axes_mm=tuple(float(v) for v in per_axis.mean(axis=0) - commanded_axes),
        rd_axes_mm=tuple(float(v) for v in 3.0 * per_axis.std(axis=0, ddof=1)),
        mean_distance_mm=float(distance.mean()),
        commanded_distance_mm=commanded,
        u_ad_mm=float(distance.std(ddof=1) / np.sqrt(len(first))),
        n=len(first),
    )


def orientation_distance_characteristics(
    first_deg: ArrayLike, second_deg: ArrayLike, commanded_first_deg: ArrayLike, commanded_second_deg: ArrayLike
) -> OrientationDistanceCharacteristics:
    """Per-angle distance accuracy and repeatability between two command poses, paired by cycle.

    ISO 9283:1998 clause 7.3 [N]:

    .. math::

        D_{aj} = |a_{1j} - a_{2j}|, \\quad D_{ca} = |a_{c1} - a_{c2}|, \\quad AD_a = \\bar D_a - D_{ca}, \\quad
        RD_a = \\pm 3 S(D_a)

    (likewise b, c). Angle differences are wrapped to [-180, 180) before the absolute value.

    Parameters
    ----------
    first_deg, second_deg : array_like, shape (n, k)
        Attained angles at the first and second command pose; row j of both is cycle j; n >= 2.
    commanded_first_deg, commanded_second_deg : array_like, shape (k,)
        Command angles (deg).
    """
    first = as_points("first_deg", first_deg)
    second = as_points("second_deg", second_deg, dims=(first.shape[1],))
    require_same_length("first_deg", first, "second_deg", second)
    require_count("orientation distance cycles", len(first), 2)
    cmd_first = as_vector("commanded_first_deg", commanded_first_deg, length=first.shape[1])
    cmd_second = as_vector("commanded_second_deg", commanded_second_deg, length=first.shape[1])
    distance = np.abs(wrap_deg(first - second))
    commanded = np.abs(wrap_deg(cmd_first - cmd_second))
    return OrientationDistanceCharacteristics(
        ad_deg=tuple(float(v) for v in distance.mean(axis=0) - commanded),
        rd_deg=tuple(float(v) for v in 3.0 * distance.std(axis=0, ddof=1)),
        n=len(first),
    )
