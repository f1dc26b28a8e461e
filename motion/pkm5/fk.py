"""Forward kinematics of the PKM by batched least squares over all six legs (pkm5.md §4.3).

The robot is redundantly actuated (six lengths, three or four pose unknowns per mode), so the pose is the
least-squares solution of IK(q) = L. Levenberg-Marquardt with the exact Jacobian of the IK, batched over poses;
local minima (large positive beta, pkm5.md §4.3) are escaped by restarting from alternative guesses and keeping
the smallest residual.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from motion import dual
from motion.errors import MotionInputError
from motion.pkm5 import compiled
from motion.pkm5.fk_starts import RESTARTS as _RESTARTS
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry, _as_legs
from motion.pkm5.ik import inverse_kinematics, leg_lengths
from motion.pkm5.workspace import sample_reachable

__all__ = ["FKResult", "NEUTRAL_POSE", "detect_mode", "forward_kinematics", "MODES"]

#: Mode name -> index of the rotation column that is solved for (None: translation only).
MODES = {"translation": None, "alpha": 3, "beta": 4}
_NEUTRAL = np.array([150.0, 0.0, 300.0])  # pkm5.md §4.3 neutral guess
#: The neutral pose (x, y, z mm, alpha, beta rad) of pkm5.md §4.3: a start for one well-conditioned solve (the home
#: pose) that needs no seed table.
NEUTRAL_POSE = (*_NEUTRAL, 0.0, 0.0)


_WORKSPACE_OF_MODE = {"translation": "constant-orientation", "alpha": "alpha", "beta": "beta"}


#: Largest batch whose start poses are found by comparing each target with the whole seed table: a few targets
#: (a driver's pre-flight of one move) cost microseconds that way, while the k-d tree costs importing scipy.spatial
#: (0.3-0.5 s of CPU, a third of every ``bench run`` process on the pkm5); larger batches (n x 4000 distances)
#: query the tree.
_BRUTE_FORCE_MAX_TARGETS = 64


@lru_cache(maxsize=16)
def _seed_table(mode: str, geometry: Geometry, size: int = 4000) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
    """Reachable poses of a mode and their leg lengths, to start each solve near its answer.

    Built once per (mode, geometry) from a fixed-seed sample, so results stay deterministic."""
    try:
        poses = sample_reachable(size, kinds=(_WORKSPACE_OF_MODE[mode],), seed=20241123, geometry=geometry)
    except MotionInputError:  # a geometry with no reachable pose in the box: fall back to the neutral guess
        return None, None
    angle_col = MODES[mode]
    cols = [0, 1, 2] + ([angle_col] if angle_col is not None else [])
    return poses[:, cols], inverse_kinematics(poses, geometry).lengths_mm


@lru_cache(maxsize=16)
def _seed_tree(mode: str, geometry: Geometry) -> Any:
    """A k-d tree over the seed table's leg lengths, for large batches. scipy.spatial is imported here, not at the
    top: an inverse-kinematics caller (``bench kin ik``) and a small batch never pay for it."""
    from scipy.spatial import cKDTree

    return cKDTree(_seed_table(mode, geometry)[1])


def _nearest_seed(target: np.ndarray, mode: str, geometry: Geometry) -> np.ndarray:
    """Index of the seed whose leg lengths are nearest (Euclidean) to each target: the same neighbour whether a
    target is solved alone or in a large batch."""
    if len(target) > _BRUTE_FORCE_MAX_TARGETS:
        return _seed_tree(mode, geometry).query(target, workers=-1)[1]
    lengths = _seed_table(mode, geometry)[1]
    assert lengths is not None  # _initial_guess asks only where the seed table exists
    difference = target[:, None, :] - lengths[None, :, :]
    return np.einsum("ijk,ijk->ij", difference, difference).argmin(axis=1)


def _initial_guess(target: np.ndarray, mode: str, geometry: Geometry) -> np.ndarray:
    starts, lengths = _seed_table(mode, geometry)
    if starts is None or lengths is None:
        return np.tile(np.r_[_NEUTRAL, [0.0] * (1 if MODES[mode] is not None else 0)], (len(target), 1))
    return starts[_nearest_seed(target, mode, geometry)]


@dataclass(frozen=True)
class FKResult:
    """Poses solved from leg lengths.

    Attributes
    ----------
    pose : ndarray (N, 5)
        x, y, z [mm], alpha, beta [rad].
    converged : ndarray (N,) of bool
        The solver reached a stationary point (step < tolerance) with residual RMS below ``residual_tol_mm``.
    iterations : ndarray (N,) of int
        LM iterations of the accepted solution.
    residual_mm : ndarray (N,)
        RMS of IK(pose) - L over the six legs: ~1e-12 for consistent lengths; for measured lengths a health metric.
    mode : ndarray (N,) of str
        The motion mode solved for.
    """

    pose: np.ndarray
    converged: np.ndarray
    iterations: np.ndarray
    residual_mm: np.ndarray
    mode: np.ndarray


def detect_mode(lengths_mm: ArrayLike, tol_mm: float = 1e-3) -> np.ndarray:
    """Motion mode from the length pattern (pkm5.md §4.3): 'alpha' if L5 != L6, else 'beta' if a pair is unequal,
    else 'translation'. ``tol_mm`` should be a few times the length noise for measured data."""
    lengths = _as_legs(lengths_mm, "lengths_mm")
    alpha = np.abs(lengths[:, 4] - lengths[:, 5]) > tol_mm
    beta = (np.abs(lengths[:, 0] - lengths[:, 1]) > tol_mm) | (np.abs(lengths[:, 2] - lengths[:, 3]) > tol_mm)
    return np.where(alpha, "alpha", np.where(beta, "beta", "translation")).astype(object)


def _residual(q: Any, target: np.ndarray, mode: str, geometry: Geometry) -> Any:
    """IK(q) - target (n, 6) and its Jacobian (n, 6, k), from one dual-number pass."""
    n = len(q)
    zeros = np.zeros(n)
    variables = dual.seed(q)
    x, y, z = variables[:3]
    alpha = variables[3] if mode == "alpha" else zeros
    beta = variables[3] if mode == "beta" else zeros
    lengths, _ = leg_lengths(x, y, z, alpha, beta, geometry, with_tilt=False)
    r = np.stack([length.value for length in lengths], -1) - target
    return r, np.stack([length.grad for length in lengths], 1)


def _levenberg_marquardt(
    q: np.ndarray, target: np.ndarray, mode: str, geometry: Geometry, max_iter: int, step_tol: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batched LM; each pose has its own damping. Returns q, cost, iterations, stationary flag.

    The residual and Jacobian at a trial point come from one pass and are kept if the step is accepted, so each
    iteration costs one IK evaluation with derivatives.
    """
    n, k = q.shape
    q = q.copy()
    r, jac = _residual(q, target, mode, geometry)
    cost = np.einsum("ij,ij->i", r, r)
    damping = np.full(n, 1e-3)
    iterations = np.zeros(n, int)
    done = cost < 1e-24
    eye = np.eye(k)
    for _ in range(max_iter):
        active = np.flatnonzero(~done)
        if active.size == 0:
            break
        ja, ra = jac[active], r[active]
        jt = ja.transpose(0, 2, 1)
        normal = jt @ ja
        grad = (jt @ ra[..., None])[..., 0]
        diag = np.diagonal(normal, axis1=1, axis2=2)
        damped = normal + damping[active, None, None] * eye * diag[:, None, :]
        step = np.linalg.solve(damped, grad[..., None])[..., 0]
        q_new = q[active] - step
        r_new, jac_new = _residual(q_new, target[active], mode, geometry)
        cost_new = np.einsum("ij,ij->i", r_new, r_new)
        better = cost_new <= cost[active]
        accepted = active[better]
        q[accepted], r[accepted], jac[accepted] = q_new[better], r_new[better], jac_new[better]
        cost[accepted] = cost_new[better]
        damping[active] = np.where(better, np.maximum(damping[active] * 0.3, 1e-12), damping[active] * 10.0)
        iterations[active] += 1
        small_step = np.abs(step).max(1) < step_tol
        # a step below tolerance means no further progress, whether or not it was accepted
        done[active] = small_step | (cost[active] < 1e-24) | (damping[active] > 1e12)
    return q, cost, iterations, done


def _with_restarts(
    q0: np.ndarray,
    target: np.ndarray,
    mode: str,
    geometry: Geometry,
    max_iter: int,
    step_tol: float,
    retry_above_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """LM from q0, then from each restart guess of ``mode`` for the rows still above ``retry_above_mm``."""
    q, cost, its, done = _levenberg_marquardt(q0, target, mode, geometry, max_iter, step_tol)
    for restart in _RESTARTS[mode]:
        retry = np.flatnonzero(np.sqrt(cost / 6) > retry_above_mm)
        if retry.size == 0:
            break
        q_r, cost_r, its_r, done_r = _levenberg_marquardt(
            np.tile(restart, (retry.size, 1)), target[retry], mode, geometry, max_iter, step_tol
        )
        better = cost_r < cost[retry]
        idx = retry[better]
        q[idx], cost[idx], its[idx], done[idx] = q_r[better], cost_r[better], its_r[better], done_r[better]
    return q, cost, its, done


def forward_kinematics(
    lengths_mm: ArrayLike,
    geometry: Geometry = DEFAULT_GEOMETRY,
    *,
    initial_pose: ArrayLike | None = None,
    mode: str = "auto",
    max_iter: int = 50,
    step_tol: float = 1e-9,
    residual_tol_mm: float = 0.01,
    retry_above_mm: float = 1e-9,
    mode_tol_mm: float = 1e-6,
    engine: str = "auto",
) -> FKResult:
    """Poses from six leg lengths, batched least squares.

    Parameters
    ----------
    lengths_mm : array_like, shape (N, 6)
        Leg lengths |BC| [mm].
    initial_pose : array_like (N, 5) or (5,), optional
        Starting poses (e.g. the previous pose when tracking). Default: the reachable pose whose leg lengths are
        nearest (k-d tree over a fixed table of 4,000 poses per mode), which halves the iterations and avoids most
        local minima; the neutral pose (150, 0, 300) mm of pkm5.md §4.3 is among the restarts.
    mode : {'auto', 'translation', 'alpha', 'beta'}
        Which pose variables to solve for; 'auto' uses :func:`detect_mode` with ``mode_tol_mm`` (default 1e-6 mm,
        right for computed lengths; for measured lengths give the commanded mode, or a tolerance of a few times the
        length noise, since a four-parameter mode always fits noise better than translation).
    max_iter, step_tol : int, float
        LM iteration cap and the step criterion max|dq| (mm, rad) of pkm5.md §4.3.
    residual_tol_mm : float
        Largest residual RMS of a converged solution. Measured lengths are never exactly consistent: lengths
        rounded to 0.01 mm (the CAD precision of 000) leave up to 0.0032 mm RMS; the beta local minima of
        pkm5.md §4.3 leave 0.015-0.28 mm.
    retry_above_mm : float
        A solution whose residual RMS exceeds this is retried from the restart guesses of pkm5.md §4.3 and the
        best is kept. Near the beta singularity a wrong local minimum can have a residual of only 1e-4 mm while
        the pose is 4 mm off, so the default retries anything that is not an exact fit.
    engine : {'auto', 'numpy', 'compiled'}
        'numpy' is the batched reference below; 'compiled' runs the same LM, pose by pose, in the numba kernel of
        :mod:`motion.pkm5.compiled` (same steps, poses equal to ~1e-12 mm); 'auto' compiles batches of at least
        ``compiled.COMPILED_MIN_POSES['fk']`` when numba is installed.

    Returns
    -------
    FKResult

    Examples
    --------
    The lengths of 001 Table I at full retraction give the pose printed in 001 §IV.A (87.82, 0, 295.83):

    >>> r = forward_kinematics([184, 184, 184, 184, 192, 192])
    >>> np.round(r.pose[0, :3], 3), bool(r.converged[0])
    (array([ 87.816,   0.   , 295.833]), True)
    """
    target = _as_legs(lengths_mm, "lengths_mm")
    n = len(target)
    run_compiled = compiled.use_compiled(engine, n, "fk")
    modes = detect_mode(target, mode_tol_mm) if mode == "auto" else np.full(n, mode, dtype=object)
    unknown = set(modes) - set(MODES)
    if unknown:
        raise MotionInputError(f"mode = {sorted(unknown)[0]!r}, expected 'auto' or one of {sorted(MODES)}")
    start = None
    if initial_pose is not None:
        start = np.broadcast_to(np.asarray(initial_pose, dtype=float), (n, 5))
    pose = np.zeros((n, 5))
    converged = np.zeros(n, bool)
    iterations = np.zeros(n, int)
    residual = np.zeros(n)
    for name in MODES:
        rows = np.flatnonzero(modes == name)
        if rows.size == 0:
            continue
        angle_col = MODES[name]
        cols = [0, 1, 2] + ([angle_col] if angle_col is not None else [])
        q0 = start[rows][:, cols] if start is not None else _initial_guess(target[rows], name, geometry)
        solve = compiled.fk_arrays if run_compiled else _with_restarts
        q, cost, its, done = solve(q0, target[rows], name, geometry, max_iter, step_tol, retry_above_mm)
        pose[np.ix_(rows, np.asarray(cols))] = q
        rms = np.sqrt(cost / 6)
        residual[rows] = rms
        iterations[rows] = its
        converged[rows] = done & (rms <= residual_tol_mm)
    return FKResult(pose, converged, iterations, residual, modes)
