"""The dissertation's Newton-Raphson forward kinematics, kept for parity with its Tables A.15-A.17.

000 §5.4 and App. B.3 (pkm5.md §4.1) solve a square system per mode with one leg per pair (legs 1, 3 and 5, or
the virtual leg 5-6) and the leg elevation angles theta_1, theta_3, theta_5 as extra unknowns. In the alpha and
beta scripts the rotated bracket components and ``gradient = tan(angle)`` are constants taken from the KNOWN pose,
so those scripts check the equations rather than solve the FK; use :func:`motion.pkm5.forward_kinematics` for
real work. Stopping rule as printed: ``while max|V - NewV| > 1e-6`` (mixed mm and rad), every update counted;
the documents have no iteration cap, here ``max_iter`` (default 100) flags divergence.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion import dual
from motion.errors import MotionInputError
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry
from motion.pkm5.ik import _rotate

__all__ = ["NRResult", "forward_kinematics_nr"]


@dataclass(frozen=True)
class NRResult:
    """Result of the parity Newton-Raphson solve for one pose.

    ``solution`` holds x, y, z [mm], then the mode angle [deg] (alpha/beta modes only), then theta_1, theta_3,
    theta_5 [deg], as in the columns of 000 Tables A.15-A.17.
    """

    solution: np.ndarray
    iterations: int
    converged: bool


def _squared(vector: Sequence[Any]) -> Any:
    return vector[0] * vector[0] + vector[1] * vector[1] + vector[2] * vector[2]


def _system(
    v: Sequence[Any], mode: str, lengths: Sequence[np.ndarray], brackets: Mapping[str, Any], gradient: Any, g: Geometry
) -> list[Any]:
    """Residuals F1..F6 (translation) or F1..F7 (alpha, beta) of 000 Eqs. 5.28-5.38."""
    l1, l3, l5 = lengths
    x, y, z = v[:3]
    zero = np.zeros(1)
    angle: Any = v[3] if mode != "translation" else zero
    th1, th3, th5 = v[-3:]
    alpha = angle if mode == "alpha" else zero
    beta = angle if mode == "beta" else zero
    ca, sa, cb, sb = dual.cos(alpha), dual.sin(alpha), dual.cos(beta), dual.sin(beta)
    residuals = []
    pair_legs = ((l1, th1, g.pd_12_mm, g.oa_12_mm, brackets["cd1"]), (l3, th3, g.pd_34_mm, g.oa_34_mm, brackets["cd3"]))
    heights = []
    for length, theta, pd, oa, cd in pair_legs:
        dx, dy, dz = _rotate(pd, ca, sa, cb, sb)
        ad = (x + dx - oa[0], y + dy - oa[1], z + dz - oa[2])
        in_u = length * dual.cos(theta) + g.ab_odd_mm[0] + cd[0]
        in_w = length * dual.sin(theta) + g.ab_odd_mm[1] + cd[1]
        residuals.append(_squared(ad) - (in_u * in_u + in_w * in_w))
        heights.append(in_w - ad[2])
    if mode == "alpha":  # real leg 5 with the rotated bracket (App. B.3.2)
        pd5: Sequence[float] = g.pd_5_mm
        ab_v, cd5 = g.ab_5_mm[0], brackets["cd5"]
    else:  # virtual leg 5-6 midway between D5 and D6 (App. B.3.1, B.3.3)
        pd5 = (0.5 * (g.pd_5_mm[0] + g.pd_6_mm[0]), 0.0, 0.0)
        ab_v, cd5 = g.ab_5_mm[0] + g.cd_5_mm[0] - g.pd_5_mm[1], (0.0, g.cd_5_mm[1])
    dx, dy, dz = _rotate(pd5, ca, sa, cb, sb)
    ad5 = (x + dx - g.oa_56_mm[0], y + dy - g.oa_56_mm[1], z + dz - g.oa_56_mm[2])
    in_v = l5 * dual.cos(th5) + ab_v + cd5[0]
    in_w = l5 * dual.sin(th5) + g.ab_5_mm[1] + cd5[1]
    residuals.append(_squared(ad5) - (in_v * in_v + in_w * in_w))
    residuals.extend(heights)
    residuals.append(in_v - ad5[1])
    if mode != "translation":
        residuals.append(gradient - dual.sin(angle) / dual.cos(angle))
    return residuals


def forward_kinematics_nr(
    lengths_135_mm: ArrayLike,
    guess: ArrayLike,
    *,
    mode: str = "translation",
    brackets: Mapping[str, ArrayLike] | None = None,
    gradient: Any = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    tol: float = 1e-6,
    max_iter: int = 100,
) -> NRResult:
    """Newton-Raphson FK exactly as in 000 App. B.3 (one pose).

    Parameters
    ----------
    lengths_135_mm : sequence of 3 floats
        L1, L3, L5 [mm].
    guess : sequence
        Initial guess as typed in the documents' tables: x, y, z [mm], (mode angle), theta_1, theta_3, theta_5
        [deg] (the documents typed radians; their tables show degrees).
    mode : {'translation', 'alpha', 'beta'}
    brackets : dict, optional
        Rotated bracket vectors ``cd1``, ``cd3`` (and ``cd5`` in alpha mode), (2,) mm each, taken from the true
        pose (App. B.3.2-B.3.3 constants DC1x, DC1z, ...); see :func:`motion.pkm5.bracket_vectors`. Design values
        in translation mode.
    gradient : float, optional
        tan of the true alpha or beta (the F7 constant of Eqs. 5.37-5.38).
    """
    if mode not in ("translation", "alpha", "beta"):
        raise MotionInputError(f"mode = {mode!r}, expected 'translation', 'alpha' or 'beta'")
    size = 6 if mode == "translation" else 7
    v = np.asarray(guess, dtype=float).copy()
    if v.shape != (size,):
        raise MotionInputError(f"guess has shape {v.shape}, expected ({size},) for mode {mode!r}")
    if mode != "translation" and (brackets is None or gradient is None):
        raise MotionInputError(f"mode {mode!r} needs the bracket constants and gradient taken from the known pose")
    g = geometry
    brackets = brackets or {"cd1": g.cd_odd_mm, "cd3": g.cd_odd_mm, "cd5": g.cd_5_mm}
    v[3:] = np.radians(v[3:])
    lengths = [np.array([float(length)]) for length in np.asarray(lengths_135_mm, dtype=float)]
    iterations = 0
    delta = 100.0
    while delta > tol and iterations < max_iter:
        residuals = _system(dual.seed(v[None, :]), mode, lengths, brackets, gradient, g)
        f = np.array([r.value[0] for r in residuals])
        jac = np.stack([r.grad[0] for r in residuals])
        try:
            new_v = v - np.linalg.solve(jac, f)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(new_v)):
            break
        delta = float(np.max(np.abs(v - new_v)))
        v = new_v
        iterations += 1
    solution = v.copy()
    solution[3:] = np.degrees(solution[3:])
    return NRResult(solution, iterations, bool(delta <= tol))
