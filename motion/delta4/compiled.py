"""Compiled (numba) Gauss-Newton FK of the delta-4, pose by pose; the batched numpy fit of
:func:`motion.delta4.forward_kinematics` is the reference (tests/test_delta4_compiled.py).

Same residuals and Jacobian (reference §2.6: r_i = |A_i(p) - K_i| - R0, dr_i/dp = (A_i - K_i) / |A_i - K_i|), same
well-posedness test (det(J^T J) > 1e-12 (trace / 3)^3, else no step) and step criterion |dp| < tolerance. The one
difference is by design: each pose stops at its own convergence, where the batched fit keeps stepping every pose
until all have converged (steps below the tolerance, so poses agree to ~1e-10 mm).

numba is imported on the first compiled call only; ``engine='auto'`` compiles from :data:`COMPILED_MIN_POSES` angle
sets on (numba and the cached kernel load in 0.3-1 s a process).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from motion import kernels
from motion.delta4.geometry import LEG_OUTWARD, Geometry

__all__ = ["COMPILED_MIN_POSES", "use_compiled", "gauss_newton"]

#: Smallest batch that ``engine='auto'`` runs compiled (the numpy fit does ~10^5 solves in a numba load).
COMPILED_MIN_POSES = 20_000
_CHUNK = 8192  # poses per thread task


def use_compiled(engine: str, n: int) -> bool:
    """Whether ``n`` angle sets run compiled (:func:`motion.kernels.use_compiled`)."""
    return kernels.use_compiled(engine, n, COMPILED_MIN_POSES)


@lru_cache(maxsize=1)
def _kernel() -> Any:
    import math

    from numba import njit

    @njit(cache=True, nogil=True, error_model="numpy")
    def gauss_newton_rows(  # type: ignore[no-untyped-def]  # numba infers the kernel's types
        start,
        knees,
        outward,
        offset_mm,
        lower_arm_mm,
        iterations,
        tolerance_mm,
        pose,
        converged,
    ):
        for row in range(start.shape[0]):
            px, py, pz = start[row, 0], start[row, 1], start[row, 2]
            ok = False
            for _ in range(iterations):
                n00 = n01 = n02 = n11 = n12 = n22 = g0 = g1 = g2 = 0.0
                for leg in range(4):
                    lx = px + offset_mm * outward[leg, 0] - knees[row, leg, 0]
                    ly = py + offset_mm * outward[leg, 1] - knees[row, leg, 1]
                    lz = pz + offset_mm * outward[leg, 2] - knees[row, leg, 2]
                    length = math.sqrt(lx * lx + ly * ly + lz * lz)
                    r = length - lower_arm_mm
                    jx, jy, jz = lx / length, ly / length, lz / length
                    n00 += jx * jx
                    n01 += jx * jy
                    n02 += jx * jz
                    n11 += jy * jy
                    n12 += jy * jz
                    n22 += jz * jz
                    g0 += jx * r
                    g1 += jy * r
                    g2 += jz * r
                # J^T J is symmetric: cofactors give det and the solve (Cramer's rule)
                c00 = n11 * n22 - n12 * n12
                c01 = n02 * n12 - n01 * n22
                c02 = n01 * n12 - n02 * n11
                det = n00 * c00 + n01 * c01 + n02 * c02
                trace = (n00 + n11 + n22) / 3.0
                well_posed = det > 1e-12 * trace * trace * trace
                sx = sy = sz = 0.0
                if well_posed:
                    c11 = n00 * n22 - n02 * n02
                    c12 = n01 * n02 - n00 * n12
                    c22 = n00 * n11 - n01 * n01
                    sx = -(c00 * g0 + c01 * g1 + c02 * g2) / det
                    sy = -(c01 * g0 + c11 * g1 + c12 * g2) / det
                    sz = -(c02 * g0 + c12 * g1 + c22 * g2) / det
                px, py, pz = px + sx, py + sy, pz + sz
                ok = well_posed and math.sqrt(sx * sx + sy * sy + sz * sz) < tolerance_mm
                if ok:
                    break
            pose[row, 0], pose[row, 1], pose[row, 2] = px, py, pz
            converged[row] = ok

    return gauss_newton_rows


def gauss_newton(
    start: np.ndarray, knees: np.ndarray, geometry: Geometry, iterations: int, tolerance_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares FK of N poses from starts (N, 3) and knees (N, 4, 3) mm: pose (N, 3), converged (N,)."""
    kernel = _kernel()
    start, knees = np.ascontiguousarray(start, dtype=float), np.ascontiguousarray(knees, dtype=float)
    n = len(start)
    pose, converged = np.empty((n, 3)), np.empty(n, bool)
    outward = np.ascontiguousarray(LEG_OUTWARD, dtype=float)

    def some_rows(rows: slice) -> None:
        kernel(
            start[rows],
            knees[rows],
            outward,
            float(geometry.ankle_offset_mm),
            float(geometry.lower_arm_mm),
            iterations,
            tolerance_mm,
            pose[rows],
            converged[rows],
        )

    kernels.run_chunks(some_rows, n, _CHUNK)
    return pose, converged
