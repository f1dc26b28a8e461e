"""Forward-mode automatic differentiation for batched numpy kinematics.

A ``Dual`` carries a value of shape (N,) and its gradient of shape (N, k) with respect to k seed variables. The
kinematics are written once against the small set of operations below (+, -, *, /, sin, cos, sqrt, hypot, atan2);
called with plain arrays they compute values at full numpy speed, called with duals they also produce the exact
Jacobian, so the Jacobian can never drift from the function it differentiates.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeAlias

import numpy as np

#: What the kinematics compute with: a float array, a scalar, or a :class:`Dual` carrying its gradient.
Number: TypeAlias = "Dual | np.ndarray | float"


class Dual:
    """Value (N,) with gradient (N, k)."""

    __slots__ = ("value", "grad")
    __array_priority__ = 1000  # make ndarray <op> Dual defer to Dual's reflected operators

    def __init__(self, value: np.ndarray, grad: np.ndarray) -> None:
        self.value = value
        self.grad = grad

    # arithmetic -----------------------------------------------------------------------------------------------
    def __add__(self, other: Number) -> Dual:
        if isinstance(other, Dual):
            return Dual(self.value + other.value, self.grad + other.grad)
        return Dual(self.value + other, self.grad)

    __radd__ = __add__

    def __neg__(self) -> Dual:
        return Dual(-self.value, -self.grad)

    def __sub__(self, other: Number) -> Dual:
        return self + (-other)

    def __rsub__(self, other: Number) -> Dual:
        return (-self) + other

    def __mul__(self, other: Number) -> Dual:
        if isinstance(other, Dual):
            return Dual(self.value * other.value, self.grad * other.value[:, None] + other.grad * self.value[:, None])
        other = np.asarray(other, dtype=float)
        return Dual(self.value * other, self.grad * (other[:, None] if other.ndim else other))

    __rmul__ = __mul__

    def __truediv__(self, other: Number) -> Dual:
        if isinstance(other, Dual):
            return self * other.reciprocal()
        return self * (1.0 / np.asarray(other, dtype=float))

    def __rtruediv__(self, other: Number) -> Dual:
        return self.reciprocal() * other

    def reciprocal(self) -> Dual:
        inv = 1.0 / self.value
        return Dual(inv, -self.grad * (inv * inv)[:, None])


def seed(values: np.ndarray) -> list[Dual]:
    """Independent variables: column j of ``values`` (N, k) becomes a dual with unit gradient along j."""
    values = np.asarray(values, dtype=float)
    n, k = values.shape
    eye = np.eye(k)
    return [Dual(values[:, j].copy(), np.broadcast_to(eye[j], (n, k)).copy()) for j in range(k)]


def value(x: Any) -> Any:
    """The value of a dual, or the array itself."""
    return x.value if isinstance(x, Dual) else x


def gradient(x: Any, n: int, k: int) -> np.ndarray:
    """The gradient (N, k) of a dual; zeros for a constant."""
    return x.grad if isinstance(x, Dual) else np.zeros((n, k))


def _unary(x: Any, f: Callable[[Any], Any], df: Callable[[Any], Any]) -> Any:
    if isinstance(x, Dual):
        return Dual(f(x.value), x.grad * df(x.value)[:, None])
    return f(x)


def sin(x: Any) -> Any:
    return _unary(x, np.sin, np.cos)


def cos(x: Any) -> Any:
    return _unary(x, np.cos, lambda v: -np.sin(v))


def sqrt(x: Any) -> Any:
    if isinstance(x, Dual):
        root = np.sqrt(x.value)
        return Dual(root, x.grad * (0.5 / root)[:, None])
    return np.sqrt(x)


def _norm(a: Any, b: Any) -> Any:
    # sqrt(a*a + b*b) is 3-5x faster than np.hypot; lengths in mm never approach overflow or underflow
    return np.sqrt(a * a + b * b)


def hypot(a: Any, b: Any) -> Any:
    """sqrt(a^2 + b^2); d/da = a / r."""
    if not isinstance(a, Dual) and not isinstance(b, Dual):
        return _norm(a, b)
    r = _norm(value(a), value(b))
    inv = 1.0 / r
    grad: Any = 0.0  # a Dual operand adds its gradient term
    if isinstance(a, Dual):
        grad = a.grad * (value(a) * inv)[:, None]
    if isinstance(b, Dual):
        grad = grad + b.grad * (value(b) * inv)[:, None]
    return Dual(r, grad)


def atan2(y: Any, x: Any) -> Any:
    """Angle of (x, y); d = (x dy - y dx) / (x^2 + y^2)."""
    if not isinstance(y, Dual) and not isinstance(x, Dual):
        return np.arctan2(y, x)
    yv, xv = value(y), value(x)
    inv = 1.0 / (xv * xv + yv * yv)
    grad: Any = 0.0  # a Dual operand adds its gradient term
    if isinstance(y, Dual):
        grad = y.grad * (xv * inv)[:, None]
    if isinstance(x, Dual):
        grad = grad - x.grad * (yv * inv)[:, None]
    return Dual(np.arctan2(yv, xv), grad)
