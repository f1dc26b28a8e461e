"""Commanded test paths of ISO 9283 clause 8 in the test plane of the cube, and their joint-space segmentation.

Pure computation (no I/O). The test plane is the diagonal plane of the cube that holds P2-P5 (``cube_poses``); in it
the paths are [U: ISO 9283 6.8 and Table A.4 were not retrieved, ``shared/reference/iso9283.md`` §6.10]:

- ``line``: the straight line P2 -> P4 (the diagonal of the rectangle P2-P3-P4-P5, length 1.386 L for edge L);
- ``rectangle``: P2 -> P3 -> P4 -> P5 -> P2, sharp corners (the cornering test, 8.5);
- ``circle``: centred on P1, radius 0.4 L (inscribed in the rectangle), from P1 - R u, first towards +v, with u
  along P2 -> P5 and v along P2 -> P3.

The pkm5 firmware moves its legs linearly in joint space (constant-speed MultiStepper), so a straight Cartesian
move bends. A Cartesian path is therefore cut into segments short enough that the joint-space chord error, the
distance of the joint-space midpoint of a segment (forward kinematics of the mean leg lengths) from the commanded
path, stays below a stated bound; for the pkm5 test cube it grows as about 0.0005 mm per mm² of segment length, so
0.01 mm needs segments of about 4 mm or less.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import ConfigError

__all__ = ["PATH_SHAPES", "CommandedPath", "Segmentation", "commanded_path", "segment_path"]

PATH_SHAPES = ("line", "rectangle", "circle")


@dataclass(frozen=True, eq=False)
class CommandedPath:
    """A commanded path: straight edges through ``vertices`` (line, rectangle) or a circle (centre, radius, u, v)."""

    shape: str
    vertices_mm: np.ndarray  #: (k, 3): the line's ends, the rectangle's corners (closed: last == first)
    centre_mm: np.ndarray
    radius_mm: float
    u: np.ndarray  #: unit vectors spanning the test plane
    v: np.ndarray

    @property
    def closed(self) -> bool:
        return self.shape != "line"

    @property
    def corners_mm(self) -> np.ndarray:
        """The sharp corners (rectangle: P3, P4, P5, P2; the start P2 is the last corner of each cycle)."""
        return self.vertices_mm[1:] if self.shape == "rectangle" else np.empty((0, 3))

    @property
    def length_mm(self) -> float:
        if self.shape == "circle":
            return float(2 * np.pi * self.radius_mm)
        return float(np.linalg.norm(np.diff(self.vertices_mm, axis=0), axis=1).sum())

    def point(self, s_mm: ArrayLike) -> np.ndarray:
        """Points (N, 3) at arc length ``s_mm`` (N,) from the start, 0 <= s <= length."""
        s = np.atleast_1d(np.asarray(s_mm, dtype=float))
        if self.shape == "circle":
            angle = s / self.radius_mm
            return self.centre_mm - self.radius_mm * (np.cos(angle)[:, None] * self.u - np.sin(angle)[:, None] * self.v)
        edges = np.diff(self.vertices_mm, axis=0)
        ends = np.concatenate([[0.0], np.cumsum(np.linalg.norm(edges, axis=1))])
        index = np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(edges) - 1)
        fraction = (s - ends[index]) / (ends[index + 1] - ends[index])
        return self.vertices_mm[index] + fraction[:, None] * edges[index]

    def stations(self, spacing_mm: float) -> np.ndarray:
        """Stations (m, 3) every ``spacing_mm`` or less along the path, ends included (closed: the start once)."""
        count = max(2, int(np.ceil(self.length_mm / spacing_mm)))
        s = np.linspace(0.0, self.length_mm, count + 1)
        return self.point(s[:-1] if self.closed else s)

    def distance_mm(self, points: ArrayLike) -> np.ndarray:
        """Least distance (N,) of ``points`` (N, 3) from the path."""
        p = np.asarray(points, dtype=float)
        if self.shape == "circle":
            relative = p - self.centre_mm
            in_plane = np.hypot(relative @ self.u, relative @ self.v)
            normal = np.cross(self.u, self.v)
            return np.hypot(in_plane - self.radius_mm, relative @ normal)
        best = np.full(len(p), np.inf)
        for a, b in zip(self.vertices_mm[:-1], self.vertices_mm[1:]):
            edge = b - a
            f = np.clip((p - a) @ edge / (edge @ edge), 0.0, 1.0)
            best = np.minimum(best, np.linalg.norm(p - (a + f[:, None] * edge), axis=1))
        return best


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


def commanded_path(shape: str, poses: dict[str, tuple[float, ...]]) -> CommandedPath:
    """The commanded ``shape`` in the plane of the cube poses P1-P5 (module docstring)."""
    p = {label: np.asarray(poses[label][:3], dtype=float) for label in ("P1", "P2", "P3", "P4", "P5")}
    u, v = _unit(p["P5"] - p["P2"]), _unit(p["P3"] - p["P2"])
    radius = 0.5 * min(np.linalg.norm(p["P5"] - p["P2"]), np.linalg.norm(p["P3"] - p["P2"]))
    if shape == "line":
        vertices = np.array([p["P2"], p["P4"]])
    elif shape == "rectangle":
        vertices = np.array([p["P2"], p["P3"], p["P4"], p["P5"], p["P2"]])
    elif shape == "circle":
        vertices = np.empty((0, 3))
    else:
        raise ConfigError(f"shape = {shape!r}, expected one of {', '.join(PATH_SHAPES)}")
    return CommandedPath(shape, vertices, p["P1"], float(radius), u, v)


@dataclass(frozen=True, eq=False)
class Segmentation:
    """A path cut into joint-space segments: their end points and the worst joint-space chord error."""

    targets_mm: np.ndarray  #: (n + 1, 3): the start, then every segment's end, in order of travel
    chord_error_mm: float  #: max over segments of the distance of the joint-space midpoint from the path
    joints: np.ndarray  #: (n + 1, J) leg lengths of the targets


def _pieces(path: CommandedPath, count: int) -> np.ndarray:
    """Arc lengths of ``count`` equal segments per straight edge (corners always kept) or on the circle."""
    if path.shape == "circle":
        return np.linspace(0.0, path.length_mm, count + 1)
    lengths = np.linalg.norm(np.diff(path.vertices_mm, axis=0), axis=1)
    ends = np.concatenate([[0.0], np.cumsum(lengths)])
    per_edge = [
        np.linspace(a, b, max(1, int(np.ceil(count * (b - a) / path.length_mm))) + 1)[:-1]
        for a, b in zip(ends[:-1], ends[1:])
    ]
    return np.concatenate(per_edge + [[path.length_mm]])


def segment_path(
    path: CommandedPath, kinematics: Any, *, max_segment_mm: float, chord_error_mm: float, max_segments: int = 4096
) -> Segmentation:
    """Cut ``path`` into segments no longer than ``max_segment_mm`` and halve them until the joint-space chord error
    (module docstring) is at most ``chord_error_mm``. ``kinematics`` is a :class:`motion.model.RobotModel`.

    Raises
    ------
    ConfigError
        When a segment end is not reachable (the caller pre-flights them too), or the bound needs more than
        ``max_segments`` segments.
    """
    width = len(kinematics.pose_fields)
    count = max(1, int(np.ceil(path.length_mm / max_segment_mm)))
    while True:
        points = path.point(_pieces(path, count))
        targets = np.hstack([points, np.zeros((len(points), width - 3))])
        ik = kinematics.ik(targets)
        if not np.all(ik.reachable):
            bad = int(np.flatnonzero(~np.asarray(ik.reachable))[0])
            raise ConfigError(
                f"{path.shape} path: point ({', '.join(f'{v:.2f}' for v in points[bad])}) mm is not "
                f"reachable ({ik.reason[bad]}), expected a path inside the workspace"
            )
        joints = np.asarray(ik.joints, dtype=float)
        middle = kinematics.fk((joints[:-1] + joints[1:]) / 2)
        error = float(path.distance_mm(np.asarray(middle.pose, dtype=float)[:, :3]).max())
        if error <= chord_error_mm:
            return Segmentation(points, error, joints)
        count *= 2
        if count > max_segments:
            raise ConfigError(
                f"{path.shape} path: chord_error_mm = {chord_error_mm:g} needs more than "
                f"{max_segments} segments, expected a looser bound"
            )
