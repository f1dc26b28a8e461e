"""Shared array checks and Monte Carlo helpers for the robot packages of motion/.

``as_rows`` is the one input check of (N, width) arrays; ``hit_or_miss_volume`` the one volume estimator,
V = p V_box with standard error V_box sqrt(p (1 - p) / n) for p the share of n uniform box samples accepted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError

__all__ = ["as_rows", "check_box", "WorkspaceVolume", "hit_or_miss_volume"]


def as_rows(values: ArrayLike, width: int, name: str) -> np.ndarray:
    """Coerce ``values`` to a finite float array of shape (N, width); a single row becomes N = 1."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 1:
        array = array[None, :]
    if array.ndim != 2 or array.shape[1] != width:
        raise MotionInputError(f"{name} has shape {np.shape(values)}, expected (N, {width}) or ({width},)")
    if not np.all(np.isfinite(array)):
        raise MotionInputError(f"{name} contains NaN or infinity, expected finite values")
    return array


def check_box(box_mm: ArrayLike) -> np.ndarray:
    """A sampling box ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)) in mm as a (3, 2) array, lo < hi."""
    box = np.asarray(box_mm, dtype=float)
    if box.shape != (3, 2) or not np.all(box[:, 0] < box[:, 1]):
        raise MotionInputError(f"box_mm = {box_mm!r}, expected ((x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi)), lo < hi")
    return box


@dataclass(frozen=True)
class WorkspaceVolume:
    """Monte Carlo volume estimate: ``volume_mm3`` +- ``standard_error_mm3`` from ``accepted`` of ``count``."""

    volume_mm3: float
    standard_error_mm3: float
    accepted: int
    count: int
    box_mm: tuple[tuple[float, float], ...]


def hit_or_miss_volume(accepted: int, count: int, box_mm: ArrayLike) -> WorkspaceVolume:
    """Hit-or-miss volume of a set from ``accepted`` of ``count`` uniform samples in ``box_mm``."""
    box = check_box(box_mm)
    box_volume = float(np.prod(box[:, 1] - box[:, 0]))
    fraction = accepted / count
    return WorkspaceVolume(
        volume_mm3=fraction * box_volume,
        standard_error_mm3=box_volume * float(np.sqrt(fraction * (1 - fraction) / count)),
        accepted=int(accepted),
        count=count,
        box_mm=tuple(map(tuple, box.tolist())),
    )
