"""Constant-orientation workspace of the 3-PRUS: Monte Carlo volume and the exact-in-z quadrature oracle.

A pose is reachable when every leg closes, passes the revolute existence test, and has at least one slider
branch inside the stroke; branches are chosen freely per leg (reference ``prus3.md`` §7.2-§7.4). The paper's
2.86e-2 m^3 cannot be reproduced: Table 2 lost its dimensions and the paper's acceptance tolerance is unstated.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from motion.errors import MotionInputError
from motion.prus3.geometry import STAND_IN, Geometry, corners_mm, rotation_matrix
from motion.prus3.kinematics import _slider_solutions, link_directions
from motion.prus3.revolute import existence_margin
from motion.sampling import WorkspaceVolume, as_rows, check_box, hit_or_miss_volume

__all__ = [
    "DEFAULT_BOX_MM",
    "CRITERIA",
    "WorkspaceVolume",
    "reachable_any_branch",
    "workspace_samples",
    "workspace_volume",
    "workspace_volume_quadrature",
]

#: Box enclosing the stand-in's zero-orientation workspace (x 184-553, |y| <= 324, z extent ~1.97 m), mm.
DEFAULT_BOX_MM = ((150.0, 650.0), (-350.0, 350.0), (-1900.0, 700.0))
#: ``existence``: the +-L test of some x2 (convention-free). ``x3_zero``: x2 = phi, x3 = 0 within +-L.
CRITERIA = ("existence", "x3_zero")


def _direction_ok(u: np.ndarray, geometry: Geometry, criterion: str) -> np.ndarray:
    limit, limit2 = np.radians(geometry.revolute_limit_deg), np.radians(geometry.actuated_limit_deg)
    if criterion == "existence":
        return existence_margin(u, limit, limit2) >= 0
    if criterion == "x3_zero":
        phi = np.arctan2(-u[..., 2], u[..., 0])
        return (np.abs(phi) <= limit2) & (np.abs(u[..., 1]) <= np.sin(limit))
    raise MotionInputError(f"criterion = {criterion!r}, expected one of {', '.join(CRITERIA)}")


def reachable_any_branch(pose: ArrayLike, geometry: Geometry = STAND_IN, *, criterion: str = "existence") -> np.ndarray:
    """(N,) bool: some slider branch per leg reaches the pose within stroke and revolute ranges."""
    poses = as_rows(pose, 6, "pose")
    corners, _, _ = corners_mm(poses, geometry)
    t, r_sq = _slider_solutions(corners, geometry)
    r = np.sqrt(np.clip(r_sq, 0.0, None))
    low, high = geometry.stroke_mm
    ok = r_sq >= 0
    branch_ok = np.zeros_like(ok)
    for sigma in (1.0, -1.0):  # the direction test is branch-independent for +-L ranges, the stroke is not
        sliders = t + sigma * r
        u = link_directions(corners, sliders, geometry)
        branch_ok |= (sliders >= low) & (sliders <= high) & _direction_ok(u, geometry, criterion)
    return np.asarray((ok & branch_ok).all(axis=1))


def workspace_samples(
    count: int,
    geometry: Geometry = STAND_IN,
    *,
    orientation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    box_mm: ArrayLike = DEFAULT_BOX_MM,
    seed: int | np.random.Generator | None = 0,
    criterion: str = "existence",
) -> tuple[np.ndarray, np.ndarray]:
    """Uniform tip positions in the box at a fixed orientation, as poses (count, 6), and reachability (count,)."""
    if count < 1:
        raise MotionInputError(f"count = {count!r}, expected an integer >= 1")
    box = check_box(box_mm)
    points = np.random.default_rng(seed).uniform(box[:, 0], box[:, 1], size=(count, 3))
    poses = np.column_stack([points, np.broadcast_to(np.asarray(orientation_deg, dtype=float), (count, 3))])
    return poses, reachable_any_branch(poses, geometry, criterion=criterion)


def workspace_volume(
    count: int = 400_000,
    geometry: Geometry = STAND_IN,
    *,
    orientation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    box_mm: ArrayLike = DEFAULT_BOX_MM,
    seed: int | None = 0,
    criterion: str = "existence",
    chunk: int = 500_000,
    progress: Callable[[int], object] | None = None,
) -> WorkspaceVolume:
    """Monte Carlo constant-orientation volume: V = p V_box, SE = V_box sqrt(p (1 - p) / N) (reference §7.2).

    ``progress(done)``, if given, is called with the samples tested so far after each chunk (nothing is printed).
    """
    box = check_box(box_mm)
    rng = np.random.default_rng(seed)
    accepted = 0
    for start in range(0, count, chunk):
        size = min(chunk, count - start)
        _, ok = workspace_samples(
            size, geometry, orientation_deg=orientation_deg, box_mm=box, seed=rng, criterion=criterion
        )
        accepted += int(ok.sum())
        if progress is not None:
            progress(start + size)
    return hit_or_miss_volume(accepted, count, box)


def workspace_volume_quadrature(
    geometry: Geometry = STAND_IN,
    *,
    orientation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
    xy_box_mm: tuple[tuple[float, float], tuple[float, float]] = ((150.0, 650.0), (-350.0, 350.0)),
    cells: int = 600,
    criterion: str = "existence",
) -> float:
    """Constant-orientation volume (mm^3) by midpoint quadrature in x-y, exact in z (reference §7.3).

    For a fixed rotation a leg's reach and link direction depend only on the centroid's (x, y), and the
    admissible centroid heights of leg i form [-r_i - l_hi - p'_iz, r_i - l_lo - p'_iz] for rails along -z,
    so V = double integral of max(0, min_i upper_i - max_i lower_i). Valid for the default rail direction
    (0, 0, -1), when 2a <= stroke length (the two branches' intervals overlap), and n = 0.
    """
    if tuple(geometry.rail_dir) != (0.0, 0.0, -1.0) or geometry.tip_offset_mm != 0.0:
        raise MotionInputError("workspace_volume_quadrature needs rail_dir = (0, 0, -1) and tip_offset_mm = 0")
    (x_lo, x_hi), (y_lo, y_hi) = xy_box_mm
    xs = x_lo + (np.arange(cells) + 0.5) * (x_hi - x_lo) / cells
    ys = y_lo + (np.arange(cells) + 0.5) * (y_hi - y_lo) / cells
    x, y = (axis.ravel() for axis in np.meshgrid(xs, ys, indexing="ij"))
    corner_offsets = rotation_matrix(np.asarray(orientation_deg, dtype=float)[None])[0] @ geometry.platform_corners_mm.T
    lateral = np.column_stack([x, y])[:, None, :] + corner_offsets.T[None, :, :2]  # (M, 3, 2) corner x, y
    reach_sq = geometry.link_mm**2 - lateral[..., 0] ** 2 - (lateral[..., 1] - geometry.rail_offsets_mm[:, 1]) ** 2
    r = np.sqrt(np.clip(reach_sq, 0.0, None))
    # Link direction at either branch: (x, dy, -+r)/a; the direction test is the same for both branches.
    u = np.stack([lateral[..., 0], lateral[..., 1] - geometry.rail_offsets_mm[:, 1], r], axis=-1) / geometry.link_mm
    feasible = (reach_sq >= 0).all(axis=1) & _direction_ok(u, geometry, criterion).all(axis=1)
    low, high = geometry.stroke_mm
    upper = (r - low - corner_offsets[2][None, :]).min(axis=1)
    lower = (-r - high - corner_offsets[2][None, :]).max(axis=1)
    height = np.where(feasible, np.clip(upper - lower, 0.0, None), 0.0)
    return float(height.sum() * (x_hi - x_lo) * (y_hi - y_lo) / cells**2)
