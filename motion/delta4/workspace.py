"""Workspace of the delta-4: Monte Carlo volume and the largest centred square reachable at each height.

Reachability is the IK's per-pose verdict (legs close, end effector below the knees, knee angles and servo
angles within the geometry's limits). Reference: ``delta4-lasergrid.md`` §1.7.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from motion.delta4.geometry import NOMINAL, Geometry
from motion.delta4.kinematics import inverse_kinematics
from motion.errors import MotionInputError
from motion.sampling import WorkspaceVolume, check_box, hit_or_miss_volume

__all__ = [
    "DEFAULT_BOX_MM",
    "WorkspaceVolume",
    "workspace_samples",
    "workspace_volume",
    "reachable_square_half_width_mm",
]

#: Sampling box (x, y, z) bounds in mm; it encloses the whole IK-reachable set of the Table 3 geometry
#: (axis reach z = -272.5 ... -57.5 mm, lateral reach below +-230 mm).
DEFAULT_BOX_MM = ((-250.0, 250.0), (-250.0, 250.0), (-300.0, 0.0))


def workspace_samples(
    count: int, geometry: Geometry = NOMINAL, *, box_mm: ArrayLike = DEFAULT_BOX_MM, seed: int | None = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Uniform random points in the box, (count, 3) mm, and their reachability, (count,) bool."""
    if count < 1:
        raise MotionInputError(f"count = {count!r}, expected an integer >= 1")
    box = check_box(box_mm)
    points = np.random.default_rng(seed).uniform(box[:, 0], box[:, 1], size=(count, 3))
    return points, inverse_kinematics(points, geometry).reachable


def workspace_volume(
    count: int = 200_000, geometry: Geometry = NOMINAL, *, box_mm: ArrayLike = DEFAULT_BOX_MM, seed: int | None = 0
) -> WorkspaceVolume:
    """Monte Carlo volume of the reachable set: V = p V_box, SE = V_box sqrt(p (1 - p) / count)."""
    box = check_box(box_mm)
    _, reachable = workspace_samples(count, geometry, box_mm=box, seed=seed)
    return hit_or_miss_volume(int(reachable.sum()), count, box)


def reachable_square_half_width_mm(
    z_mm: ArrayLike, geometry: Geometry = NOMINAL, *, step_mm: float = 2.5, grid: int = 13, max_mm: float = 250.0
) -> np.ndarray:
    """Largest half-width h (mm, a multiple of ``step_mm``) such that every centred square of half-width
    <= h at height z is reachable, checked on a ``grid`` x ``grid`` lattice of each square. (Z,) array.

    A height whose centre (0, 0, z) is unreachable gets 0, like one where only the centre is reachable; check
    the centre with the IK when the difference matters.

    Notes
    -----
    The reference (§1.7, [computed], 13 x 13 grid, 0.25 cm steps) tabulates e.g. 9.5 cm at z = -20 cm and
    11.75 cm at z = -15 cm for the thesis geometry with servo limits 30-170 deg and no knee-angle margin.
    """
    heights = np.atleast_1d(np.asarray(z_mm, dtype=float))
    widths = np.arange(0.0, max_mm + step_mm / 2, step_mm)
    lattice = np.linspace(-1.0, 1.0, grid)
    unit = np.stack(np.meshgrid(lattice, lattice, indexing="ij"), axis=-1).reshape(-1, 2)  # (G, 2)
    xy = widths[:, None, None] * unit[None]  # (W, G, 2)
    points = np.concatenate(
        [
            np.broadcast_to(xy, (len(heights),) + xy.shape),
            np.broadcast_to(heights[:, None, None, None], (len(heights),) + xy.shape[:2] + (1,)),
        ],
        axis=-1,
    )
    reachable = np.asarray(inverse_kinematics(points.reshape(-1, 3), geometry).reachable)
    square_ok = np.all(reachable.reshape(len(heights), len(widths), -1), axis=2)  # (Z, W)
    first_failure = np.where(square_ok.all(axis=1), len(widths), np.argmin(square_ok, axis=1))
    return np.where(first_failure > 0, widths[np.maximum(first_failure - 1, 0)], 0.0)
