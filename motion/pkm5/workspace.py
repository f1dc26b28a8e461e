"""Workspace of the PKM by Monte Carlo with the vectorised IK as membership test (000 §6.3, App. B.4).

Two numbers per workspace type, always labelled:

* ``volume`` -- hit-or-miss estimate of the TRUE (non-convex) workspace: the share of uniform samples in the
  sampling box that some orientation in the type's range reaches, times the box volume, with its standard error
  V_box * sqrt(p (1 - p) / n). This is the physically meaningful figure.
* ``hull_volume`` -- the convex hull of a cloud of feasible samples, the dissertation's method (MATLAB
  ``convexHull`` of 12,000 points), for parity with its printed numbers. A hull overstates a non-convex set: for
  constant orientation 1.21e6 mm^3 (hull) against about 0.82e6 mm^3 (hit-or-miss), pkm5.md §5.5.

The alpha workspace lies on the plane x = 111.31 mm, so its "volume" is an area in (y, z) [mm^2].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError
from motion.pkm5.geometry import DEFAULT_GEOMETRY, Geometry
from motion.pkm5.ik import inverse_kinematics

__all__ = [
    "WORKSPACE_KINDS",
    "WorkspaceKind",
    "WorkspaceEstimate",
    "estimate_workspace",
    "feasible",
    "sample_reachable",
]


@dataclass(frozen=True)
class WorkspaceKind:
    """A sampling box (000 Tables 6-1 to 6-3; the printed y signs are swapped, the code uses -/+ 136.12) and the
    orientation that varies: ``angle`` is None (constant orientation), 'alpha' or 'beta'."""

    x_mm: tuple[float, float]
    y_mm: tuple[float, float]
    z_mm: tuple[float, float]
    angle: str | None = None
    angle_deg: tuple[float, float] = (0.0, 0.0)

    @property
    def planar(self) -> bool:
        return self.x_mm[0] == self.x_mm[1]


WORKSPACE_KINDS = {
    "constant-orientation": WorkspaceKind((46.50, 235.14), (-136.12, 136.12), (262.08, 356.68)),
    "alpha": WorkspaceKind((111.31, 111.31), (-136.12, 136.12), (262.08, 356.68), "alpha", (-35.73, 35.73)),
    "beta": WorkspaceKind((46.50, 239.50), (-136.12, 136.12), (252.07, 356.68), "beta", (-36.8, 27.17)),
}


@dataclass(frozen=True)
class WorkspaceEstimate:
    """Monte Carlo workspace estimate; units mm^3, or mm^2 for the planar alpha workspace (see ``unit``)."""

    kind: str
    unit: str
    volume: float
    stderr: float
    hull_volume: float
    samples: int
    hits: int
    box_volume: float
    hull_points: np.ndarray


def feasible(poses: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> np.ndarray:
    """The membership test of 000 App. B.4: leg-length and tilt windows (strict), every leg including phi_6."""
    return inverse_kinematics(poses, geometry).reachable


def _uniform(rng: np.random.Generator, bounds: Sequence[tuple[float, float]], n: int) -> np.ndarray:
    low = np.array([b[0] for b in bounds])
    high = np.array([b[1] for b in bounds])
    return low + (high - low) * rng.random((n, len(bounds)))


def _poses(kind: WorkspaceKind, positions: np.ndarray, angles_rad: np.ndarray) -> np.ndarray:
    """Pose array for positions (n, 3) and angles (n,) of the kind's rotation."""
    poses = np.zeros((len(positions), 5))
    poses[:, :3] = positions
    if kind.angle is not None:
        poses[:, 3 if kind.angle == "alpha" else 4] = angles_rad
    return poses


def _draw(kind: WorkspaceKind, rng: np.random.Generator, n: int) -> np.ndarray:
    """n uniform poses from the kind's box and angle range."""
    positions = _uniform(rng, (kind.x_mm, kind.y_mm, kind.z_mm), n)
    angles = np.radians(_uniform(rng, (kind.angle_deg,), n)[:, 0])
    return _poses(kind, positions, angles)


def sample_reachable(
    n: int,
    *,
    kinds: Sequence[str] = ("constant-orientation",),
    seed: int | None = 0,
    geometry: Geometry = DEFAULT_GEOMETRY,
) -> np.ndarray:
    """n reachable poses (N, 5), drawn uniformly from the sampling boxes of the given workspace kinds.

    Each draw picks one of ``kinds`` with equal probability; draws the IK refuses are discarded (rejection
    sampling), so the result is uniform over the reachable part of each box. Deterministic for a given seed.
    """
    unknown = set(kinds) - set(WORKSPACE_KINDS)
    if unknown:
        raise MotionInputError(f"kinds = {sorted(unknown)}, expected names from {sorted(WORKSPACE_KINDS)}")
    rng = np.random.default_rng(seed)
    chunks, count = [], 0
    for _ in range(10000):
        batch = max(8 * (n - count), 1000)
        choice = rng.integers(0, len(kinds), batch)
        poses = np.concatenate([_draw(WORKSPACE_KINDS[k], rng, int((choice == i).sum())) for i, k in enumerate(kinds)])
        poses = poses[rng.permutation(len(poses))]
        poses = poses[feasible(poses, geometry)]
        chunks.append(poses)
        count += len(poses)
        if count >= n:
            return np.concatenate(chunks)[:n]
    raise MotionInputError(f"kinds {list(kinds)}: fewer than {n} reachable poses found for this geometry")


def _hit_or_miss(
    kind: WorkspaceKind,
    geometry: Geometry,
    rng: np.random.Generator,
    samples: int,
    angle_step_deg: float,
    chunk: int = 20000,
    progress: Callable[[int], object] | None = None,
) -> int:
    """Count box samples reachable with at least one angle of the grid; ``progress(done)`` after each chunk."""
    lo, hi = kind.angle_deg
    grid = (
        np.radians(np.linspace(lo, hi, max(2, int(round((hi - lo) / angle_step_deg)) + 1)))
        if kind.angle is not None
        else np.zeros(1)
    )
    hits = 0
    for start in range(0, samples, chunk):
        n = min(chunk, samples - start)
        positions = _uniform(rng, (kind.x_mm, kind.y_mm, kind.z_mm), n)
        poses = _poses(kind, np.repeat(positions, len(grid), 0), np.tile(grid, n))
        hits += int(feasible(poses, geometry).reshape(n, len(grid)).any(1).sum())
        if progress is not None:
            progress(start + n)
    return hits


def _feasible_cloud(
    kind: WorkspaceKind, geometry: Geometry, rng: np.random.Generator, points: int, batch: int = 50000
) -> np.ndarray:
    """The dissertation's cloud: uniform (position, angle) samples kept while the IK accepts them."""
    cloud = []
    count = 0
    for _ in range(10000):
        poses = _draw(kind, rng, batch)
        ok = feasible(poses, geometry)
        cloud.append(poses[ok, :3])
        count += int(ok.sum())
        if count >= points:
            return np.concatenate(cloud)[:points]
    raise MotionInputError(f"workspace kind {kind!r}: fewer than {points} feasible samples found")


def estimate_workspace(
    kind: str = "constant-orientation",
    *,
    samples: int = 200_000,
    hull_points: int = 12_000,
    seed: int | None = 0,
    angle_step_deg: float = 1.0,
    geometry: Geometry = DEFAULT_GEOMETRY,
    progress: Callable[[int], object] | None = None,
) -> WorkspaceEstimate:
    """Workspace volume by hit-or-miss Monte Carlo, and the convex hull of a feasible cloud.

    Parameters
    ----------
    kind : {'constant-orientation', 'alpha', 'beta'}
        Workspace type of 000 §6.3.2-6.3.4 (sampling boxes of Tables 6-1 to 6-3).
    samples : int
        Uniform box samples for the hit-or-miss estimate.
    hull_points : int
        Feasible samples whose convex hull is reported (000 uses 12,000).
    seed : int or None
        Seed of ``numpy.random.default_rng``; a fixed seed gives a reproducible estimate.
    angle_step_deg : float
        Grid step of the orientation search in the hit-or-miss test (alpha/beta kinds).
    progress : callable, optional
        ``progress(done)`` with the box samples tested so far, after each chunk (for a caller's progress display;
        nothing is printed here).

    Returns
    -------
    WorkspaceEstimate
    """
    if kind not in WORKSPACE_KINDS:
        raise MotionInputError(f"kind = {kind!r}, expected one of {sorted(WORKSPACE_KINDS)}")
    if samples < 1 or hull_points < 4:
        raise MotionInputError(f"samples = {samples}, hull_points = {hull_points}, expected >= 1 and >= 4")
    spec = WORKSPACE_KINDS[kind]
    rng = np.random.default_rng(seed)
    spans = [b[1] - b[0] for b in (spec.x_mm, spec.y_mm, spec.z_mm)]
    box = float(np.prod([s for s in spans if s > 0]))
    hits = _hit_or_miss(spec, geometry, rng, samples, angle_step_deg, progress=progress)
    share = hits / samples
    cloud = _feasible_cloud(spec, geometry, rng, hull_points)
    from scipy.spatial import ConvexHull  # here, not at the top: importing motion.pkm5 stays cheap

    hull = ConvexHull(cloud[:, 1:] if spec.planar else cloud)
    return WorkspaceEstimate(
        kind=kind,
        unit="mm^2" if spec.planar else "mm^3",
        volume=box * share,
        stderr=box * float(np.sqrt(share * (1 - share) / samples)),
        hull_volume=float(hull.volume),  # in 2-D scipy's "volume" is the area
        samples=samples,
        hits=hits,
        box_volume=box,
        hull_points=cloud,
    )
