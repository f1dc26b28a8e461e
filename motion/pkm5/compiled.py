"""Compiled (numba) kernels of the PKM inverse and forward kinematics: the same formulas, pose by pose.

The numpy code of :mod:`motion.pkm5.ik` and :mod:`motion.pkm5.fk` is the reference; these kernels repeat its
arithmetic in the same order (000 §5.3 / App. B.1, pkm5.md §3.2-3.3, §4.3): the lengths equal numpy's to the bit
in translation mode and to 1 ulp of the libm sin/cos otherwise, the tilts come from numpy's own ``arctan2``, and
the FK takes the same Levenberg-Marquardt steps and restarts, pose by pose (tests/test_pkm5_compiled.py). numpy
spends its time writing and re-reading ~60 temporary arrays of N values; the kernels keep a pose in registers.
The IK runs on cache-sized blocks laid out one quantity a row, so its arithmetic vectorises across poses (4 poses
an AVX2 instruction); the FK's iterations differ pose by pose, so it loops over them. Blocks of poses run on one
thread per CPU (the kernels release the GIL).

numba is an optional dependency (``pip install 'bench[fast]'``; the test extra includes it). The kernels are
compiled with ``cache=True``: the first call after an install compiles for several seconds (IK ~3 s, FK ~10 s of
CPU), later processes load the machine code from numba's cache (~0.3-1 s with the numba import). Because of that
one-off cost, ``engine='auto'`` dispatches here only from :data:`COMPILED_MIN_POSES` poses on, so importing motion/
or running ``bench kin ik`` never imports numba.

Geometry is an input (packed by :func:`pack_geometry` into one float vector), never baked into the machine code.
"""

from __future__ import annotations

import sys
from functools import lru_cache
from types import ModuleType

import numpy as np

from motion import kernels
from motion.kernels import run_chunks
from motion.pkm5.fk_starts import RESTARTS
from motion.pkm5.geometry import Geometry

__all__ = [
    "use_compiled",
    "COMPILED_MIN_POSES",
    "fk_kernel_loaded",
    "pack_geometry",
    "ik_arrays",
    "fk_arrays",
    "fk_pose",
    "MODE_CODES",
]

#: Smallest batch for which inverse_kinematics / forward_kinematics use the compiled kernels by default. Loading
#: numba and the cached kernels costs ~0.3-0.6 s per process; the numpy IK does ~10^5-10^6 poses in that time and the
#: numpy FK ~10^4 solves, so below this size the compiled path cannot pay for itself in a one-shot process.
COMPILED_MIN_POSES = {"ik": 200_000, "fk": 10_000}

#: FK mode -> kernel code (same order as motion.pkm5.fk.MODES).
MODE_CODES = {"translation": 0, "alpha": 1, "beta": 2}

_IK_TASK_BLOCKS = 4  # IK blocks (_kernels.IK_BLOCK poses each) per thread-pool task: one scratch allocation each
_FK_CHUNK = 2048  # FK rows per thread task: ~10-20 ms of work, small enough to balance uneven solves


def use_compiled(engine: str, n: int, kind: str) -> bool:
    """Whether a batch of ``n`` poses of ``kind`` ('ik' or 'fk') runs compiled (:func:`motion.kernels.use_compiled`
    with the threshold :data:`COMPILED_MIN_POSES`)."""
    return kernels.use_compiled(engine, n, COMPILED_MIN_POSES[kind])


@lru_cache(maxsize=32)
def pack_geometry(geometry: Geometry) -> np.ndarray:
    """The geometry fields the kinematics read, as one read-only float64 vector (limits in radians, as the numpy
    IK compares), in the layout of the offsets in ``_kernels`` (beside the machine code that reads them); cached."""
    g = geometry
    parts = [
        g.oa_12_mm,
        g.oa_34_mm,
        g.oa_56_mm,
        g.pd_12_mm,
        g.pd_34_mm,
        g.pd_5_mm,
        g.pd_6_mm,
        [g.bracket_half_height_mm],
        g.ab_odd_mm,
        g.ab_even_mm,
        g.ab_5_mm,
        g.ab_6_mm,
        g.cd_odd_mm,
        g.cd_even_mm,
        g.cd_5_mm,
        g.cd_6_mm,
        g.leg_min_mm,
        g.leg_max_mm,
        np.radians(g.tilt_min_deg),
        np.radians(g.tilt_max_deg),
        np.radians(g.alpha_range_deg),
        np.radians(g.beta_range_deg),
        [g.alpha_plane_x_mm, g.alpha_plane_tolerance_mm],
    ]
    packed = np.concatenate([np.asarray(part, dtype=float) for part in parts])
    if packed.size != _kernels().PACKED_SIZE:
        raise AssertionError(f"packed geometry holds {packed.size} values, the kernels read {_kernels().PACKED_SIZE}")
    packed.setflags(write=False)
    return packed


@lru_cache(maxsize=1)
def _kernels() -> ModuleType:
    """Compile (or load from numba's cache) the kernels; numba is imported here, on first use only."""
    from motion.pkm5 import _kernels

    return _kernels


def fk_kernel_loaded() -> bool:
    """Whether the FK kernel's machine code is already in this process (compiled or loaded from the cache here, or
    by a parent before it forked this process): then a compiled solve costs no load at all."""
    module = sys.modules.get("motion.pkm5._kernels")
    return module is not None and bool(module.fk_batch.signatures)


def ik_arrays(
    poses: np.ndarray, geometry: Geometry, check_limits: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lengths (N, 6), tilts (N, 6), failure flags (N,), length_ok and tilt_ok (N, 6) of validated poses (N, 5).

    Per block of ``_kernels.IK_BLOCK`` poses (in cache): a kernel writes the lengths and the tilt components, one row
    per quantity, numpy's ``arctan2`` turns the components into angles in place, a second kernel applies the
    windows and writes the block's rows of the results. Tasks of a few blocks run on one thread per CPU (the
    kernels and arctan2 release the GIL); the results do not depend on the thread count.
    """
    kernels = _kernels()
    block_size = kernels.IK_BLOCK
    poses = np.ascontiguousarray(poses)
    packed = pack_geometry(geometry)
    n = len(poses)
    lengths, tilts = np.empty((n, 6)), np.empty((n, 6))
    failure = np.empty(n, np.int64)
    length_ok, tilt_ok = np.empty((n, 6), bool), np.empty((n, 6), bool)

    def some_blocks(rows: slice) -> None:
        inputs, outputs = np.empty(kernels.IN_ROWS * block_size), np.empty(kernels.OUT_ROWS * block_size)
        by_row = outputs.reshape(kernels.OUT_ROWS, block_size)
        for start in range(rows.start, rows.stop, block_size):
            block = slice(start, min(start + block_size, rows.stop))
            size = block.stop - block.start
            kernels.ik_values(poses[block], packed, inputs, outputs)
            tilt = by_row[kernels.OUT_BW : kernels.OUT_BW + 6, :size]
            np.arctan2(tilt, by_row[kernels.OUT_BU : kernels.OUT_BU + 6, :size], out=tilt)
            kernels.ik_limits(
                inputs,
                outputs,
                packed,
                check_limits,
                lengths[block].reshape(-1),
                tilts[block].reshape(-1),
                failure[block],
                length_ok[block].reshape(-1),
                tilt_ok[block].reshape(-1),
            )

    run_chunks(some_blocks, n, block_size * _IK_TASK_BLOCKS)
    return lengths, tilts, failure, length_ok, tilt_ok


def restart_table(mode: str) -> np.ndarray:
    """The restart guesses of motion.pkm5.fk for ``mode`` as rows of four (x, y, z, angle; angle 0 in translation)."""
    table = np.zeros((len(RESTARTS[mode]), 4))
    for i, start in enumerate(RESTARTS[mode]):
        table[i, : len(start)] = start
    return table


def fk_arrays(
    q0: np.ndarray,
    target: np.ndarray,
    mode: str,
    geometry: Geometry,
    max_iter: int,
    step_tol: float,
    retry_above_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """LM with restarts for one mode's rows, as fk._with_restarts: q (n, k), cost, iterations, stationary flag.

    Each pose is solved on its own, so chunks of rows run on the thread pool with the same results."""
    n, k = q0.shape
    q = np.zeros((n, 4))
    q[:, :k] = q0
    restarts = restart_table(mode)
    cost, iterations, done = np.empty(n), np.empty(n, np.int64), np.empty(n, bool)
    kernel, target, packed, code = (
        _kernels().fk_batch,
        np.ascontiguousarray(target),
        pack_geometry(geometry),
        MODE_CODES[mode],
    )

    def some_rows(rows: slice) -> None:
        kernel(
            target[rows],
            q[rows],
            code,
            restarts,
            len(restarts),
            packed,
            max_iter,
            step_tol,
            retry_above_mm,
            cost[rows],
            iterations[rows],
            done[rows],
        )

    run_chunks(some_rows, n, _FK_CHUNK)
    return q[:, :k], cost, iterations, done


def fk_pose(
    target: np.ndarray,
    q0: np.ndarray,
    mode: int,
    restarts: np.ndarray,
    packed: np.ndarray,
    max_iter: int = 50,
    step_tol: float = 1e-9,
    retry_above_mm: float = 1e-9,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One pose, one compiled call (the per-pose peer of the batched FK): cost, iterations, stationary (1,) arrays.

    ``target`` (1, 6); ``q0`` (1, 4) holds x, y, z and the mode angle (ignored in translation mode) and receives
    the solution; ``mode`` a :data:`MODE_CODES` value; ``restarts`` from :func:`restart_table`; ``packed`` from
    :func:`pack_geometry`. No validation: the caller (a tracking loop, the benchmark's peer) prepares the arrays.
    """
    cost, iterations, done = np.empty(1), np.empty(1, np.int64), np.empty(1, bool)
    _kernels().fk_batch(
        target, q0, mode, restarts, len(restarts), packed, max_iter, step_tol, retry_above_mm, cost, iterations, done
    )
    return cost, iterations, done
