"""Input checks shared by the metrology functions: array shapes, finiteness and minimum sample counts.

Every public metrology function validates its arguments here first, so that a malformed array raises
``ConfigError`` naming the argument, the value and the expectation, and too few samples raise
``InsufficientData`` naming the count and the requirement. A metrology result is never a silent NaN.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError, InsufficientData


def as_points(name: str, values: ArrayLike, *, dims: tuple[int, ...] | None = (1, 2, 3)) -> np.ndarray:
    """Return ``values`` as a finite float array of shape (n, d) with d in ``dims`` (any d when None).

    A 1-D array is read as n one-dimensional samples, shape (n, 1).
    """
    array = np.asarray(values, dtype=float)
    if array.ndim == 1:
        array = array[:, np.newaxis]
    if array.ndim != 2 or (dims is not None and array.shape[1] not in dims):
        expected = "(n, m)" if dims is None else f"(n, d) with d in {dims}"
        raise ConfigError(f"{name}: shape {np.shape(values)}, expected {expected}")
    _require_finite(name, array)
    return array


def as_vector(name: str, values: ArrayLike, *, length: int) -> np.ndarray:
    """Return ``values`` as a finite float vector of shape (length,)."""
    array = np.atleast_1d(np.asarray(values, dtype=float))
    if array.shape != (length,):
        raise ConfigError(f"{name}: shape {np.shape(values)}, expected ({length},)")
    _require_finite(name, array)
    return array


def as_series(name: str, values: ArrayLike, *, min_count: int = 1) -> np.ndarray:
    """Return ``values`` as a finite 1-D float array with at least ``min_count`` entries."""
    array = np.asarray(values, dtype=float)
    if array.ndim != 1:
        raise ConfigError(f"{name}: shape {array.shape}, expected a 1-D array")
    _require_finite(name, array)
    require_count(name, len(array), min_count)
    return array


def require_count(what: str, count: int, minimum: int) -> None:
    """Raise ``InsufficientData`` when ``count`` < ``minimum``."""
    if count < minimum:
        raise InsufficientData(f"{what}: {count} sample(s), at least {minimum} required")


def require_same_length(name_a: str, a: np.ndarray, name_b: str, b: np.ndarray) -> None:
    """Raise ``ConfigError`` unless ``a`` and ``b`` have the same number of rows."""
    if len(a) != len(b):
        raise ConfigError(f"{name_a} has {len(a)} rows and {name_b} has {len(b)}, expected the same number")


def _require_finite(name: str, array: np.ndarray) -> None:
    if not array.size or np.isfinite(array).all():  # the usual case in one pass: no row search (per pose, per call)
        return
    bad = np.flatnonzero(~np.isfinite(array).reshape(len(array), -1).all(axis=1))
    if len(bad):
        row = int(bad[0])
        raise ConfigError(f"{name}: row {row} = {array[row].tolist()}, expected finite numbers")
