"""The moments of one pose's cycles, computed once and shared by its figures (AP, RP, U(AP), U(RP)).

numpy's ``mean`` and ``var`` are Python wrappers around ``np.add.reduce``; per call they cost microseconds of
argument handling, which a table of many poses paid about a dozen times per pose (issue 34: a fixed ~0.5 ms per
pose). These functions run the same ufunc reductions in the same order, so every figure is bit for bit the one
``points.mean(axis=0)``, ``points.var(axis=0, ddof=1)`` and ``values.std(ddof=1)`` give
(tests/test_metrology_frozen_results.py). They take arrays already checked (:mod:`bench.metrology._validation`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class CycleMoments:
    """The barycentre, squared offsets and variances of n attained points (n, d), as the pose figures use them."""

    points: np.ndarray  #: (n, d), finite
    barycentre: np.ndarray  #: (d,) p̄ = Σ p_j / n, as ``points.mean(axis=0)``
    offsets: np.ndarray  #: (n, d) p_j - p̄
    squares: np.ndarray  #: (n, d) (p_j - p̄)²
    #: (d,) s² = Σ (p_j - p̄)² / (n - 1), as ``points.var(axis=0, ddof=1)``; n = 1: the sums (0), never used
    variance: np.ndarray

    @property
    def n(self) -> int:
        """The number of cycles."""
        return len(self.points)


def cycle_moments(points: np.ndarray) -> CycleMoments:
    """The :class:`CycleMoments` of a checked (n, d) array, n >= 1."""
    n = len(points)
    barycentre = np.add.reduce(points, axis=0) / n
    offsets = points - barycentre
    squares = offsets**2
    return CycleMoments(points, barycentre, offsets, squares, np.add.reduce(squares, axis=0) / max(n - 1, 1))


def series_mean(values: np.ndarray) -> float:
    """x̄ = Σ x_j / n of a 1-D array, as ``float(values.mean())``."""
    return float(np.add.reduce(values) / len(values))


def series_sd(values: np.ndarray, mean: float) -> float:
    """s = √(Σ (x_j - x̄)² / (n - 1)) of a 1-D array with its mean ``mean`` (:func:`series_mean`), as
    ``float(values.std(ddof=1))`` (n >= 2)."""
    return sd_of_squares((values - mean) ** 2)


def sd_of_squares(squared_deviations: np.ndarray) -> float:
    """s = √(Σ (x_j - x̄)² / (n - 1)) from the squared deviations (x_j - x̄)² of a 1-D array (:func:`series_sd`)."""
    return math.sqrt(np.add.reduce(squared_deviations) / (len(squared_deviations) - 1))
