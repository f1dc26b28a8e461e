"""Laser-grid simulator: true end-effector positions (mm) -> the sensor numbers each screen would report.

Spec: ``delta4-lasergrid.md`` §4.10. Per laser the spot lands at ``BE + o_l``; every sensor whose square detection
window of half-width r contains the spot is lit; each hit is lost with probability ``p_miss`` and a stray sensor
lights with probability ``p_false``. ``p_miss_by_distance`` draws ``p_miss`` per frame from the end effector's
height instead, interpolating the Appendix D2 values (:func:`p_miss_at_distance`). Also formats frames in the
default report grammar of §5.7 item 5.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bench.errors import ConfigError
from bench.sensors.lasergrid import GridFrame, GridGeometry, Screen

__all__ = ["P_MISS_AT_DISTANCE", "GridFrame", "LaserGridSimulator", "format_report", "p_miss_at_distance"]

#: Miss probabilities reproducing the hit repeatability of Appendix D2 at 140 / 170 / 200 mm (§4.10 defaults).
P_MISS_AT_DISTANCE = {140.0: 0.0075, 170.0: 0.0125, 200.0: 0.02}


def p_miss_at_distance(distance_mm: np.ndarray) -> np.ndarray:
    """Miss probability at a laser-to-screen distance (mm): linear between the three Appendix D2 distances, held
    at the end values outside them (the document measured nothing else).

    >>> p_miss_at_distance(np.array([100.0, 155.0, 200.0, 260.0])).round(5).tolist()
    [0.0075, 0.01, 0.02, 0.02]
    """
    distances = np.array(sorted(P_MISS_AT_DISTANCE))
    return np.interp(np.asarray(distance_mm, float), distances, [P_MISS_AT_DISTANCE[d] for d in distances])


@dataclass(frozen=True)
class LaserGridSimulator:
    """Both screens observing a true end-effector position.

    Parameters
    ----------
    geometry : GridGeometry
        Screens, laser pattern, index maps.
    spot_half_width_mm : float
        Detection window half-width r (default 1.0 mm, §4.10).
    p_miss, p_false : float
        Probability of losing each hit, and of one stray lit sensor per screen and frame.
    p_miss_by_distance : bool
        Instead of ``p_miss``, lose each hit with :func:`p_miss_at_distance` of the end effector's distance from
        the horizontal screen, taken at the base plane z = 0 (§4.3 [inferred]), so the distance is -z; the
        vertical screen's distance is not documented and gets the same probability (the document ascribes the
        decline to holding the pose, §8.4.3, not to the screen).
    seed : int
        Seed of the random generator (frames are reproducible).
    """

    geometry: GridGeometry = field(default_factory=GridGeometry)
    spot_half_width_mm: float = 1.0
    p_miss: float = 0.0
    p_false: float = 0.0
    p_miss_by_distance: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("p_miss", "p_false"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ConfigError(f"laser-grid simulator: {name} = {getattr(self, name)!r}, expected 0..1")
        if not 0.0 < self.spot_half_width_mm < 5.0:
            raise ConfigError(
                f"laser-grid simulator: spot_half_width_mm = {self.spot_half_width_mm!r}, "
                "expected 0 < r < half the 10 mm pitch"
            )
        if self.p_miss_by_distance and self.p_miss:
            raise ConfigError(
                f"laser-grid simulator: p_miss = {self.p_miss!r} with p_miss_by_distance, expected one of them"
            )

    def _miss_probability(self, positions_mm: np.ndarray) -> np.ndarray:
        """(N,) probability of losing each hit of each frame."""
        if self.p_miss_by_distance:
            return p_miss_at_distance(-positions_mm[:, 2])
        return np.full(len(positions_mm), self.p_miss)

    def _screen_hits(self, screen: Screen, positions_mm: np.ndarray, rng: np.random.Generator) -> list[tuple[int, ...]]:
        spots = screen.be_from_pose(positions_mm)[:, None, :] + screen.offsets_mm[None, :, :]  # (N, 12, 2)
        cell = np.rint((spots - np.asarray(screen.first_centre_mm)) / screen.pitch_mm).astype(int)
        residual = spots - (np.asarray(screen.first_centre_mm) + screen.pitch_mm * cell)
        lit = np.all(np.abs(residual) <= self.spot_half_width_mm, axis=-1) & np.all(
            (cell >= 0) & (cell < screen.size), axis=-1
        )
        p_miss = self._miss_probability(positions_mm)
        if np.any(p_miss > 0):
            lit &= rng.random(lit.shape) >= p_miss[:, None]
        n_cells = screen.size * screen.size
        frames = []
        for row, hit in zip(cell, lit):
            found = set(screen.index_of_cell(row[hit, 0], row[hit, 1]).tolist())
            if self.p_false > 0 and rng.random() < self.p_false:
                found.add(int(rng.integers(0, n_cells)) + screen.index_base)
            frames.append(tuple(sorted(found)))
        return frames

    def observer(self) -> Callable[[np.ndarray], tuple[tuple[int, ...], tuple[int, ...]]]:
        """``observe(pose_mm) -> (horizontal, vertical)`` for one true end-effector centre (first 3 entries, mm),
        with the random state carried from frame to frame: the ``sensor`` hook of a simulated controller."""
        rng = np.random.default_rng(self.seed)

        def observe(pose_mm: np.ndarray) -> tuple[tuple[int, ...], tuple[int, ...]]:
            position = np.asarray(pose_mm, float).reshape(-1)[:3].reshape(1, 3)
            frame = self._frames(position, rng)[0]
            return frame.horizontal, frame.vertical

        return observe

    def frame_source(self, true_position_mm: Callable[[], np.ndarray]) -> Callable[[], GridFrame]:
        """A frame source for :class:`~bench.sensors.lasergrid.LaserGridSensor` that observes the true
        end-effector centre (3,) in mm returned by ``true_position_mm`` (e.g. a robot simulator's state)."""
        observe = self.observer()
        return lambda: GridFrame(*observe(true_position_mm()))

    def frames(self, positions_mm: np.ndarray) -> list[GridFrame]:
        """One :class:`GridFrame` per true end-effector centre, positions of shape (N, 3) in mm."""
        positions_mm = np.asarray(positions_mm, float)
        if positions_mm.ndim != 2 or positions_mm.shape[1] != 3 or not np.all(np.isfinite(positions_mm)):
            raise ConfigError(
                f"laser-grid simulator: positions_mm shape {positions_mm.shape}, "
                "expected finite (N, 3) end-effector centres in mm"
            )
        return self._frames(positions_mm, np.random.default_rng(self.seed))

    def _frames(self, positions_mm: np.ndarray, rng: np.random.Generator) -> list[GridFrame]:
        horizontal = self._screen_hits(self.geometry.horizontal, positions_mm, rng)
        vertical = self._screen_hits(self.geometry.vertical, positions_mm, rng)
        return [GridFrame(h, v) for h, v in zip(horizontal, vertical)]


def format_report(frame: GridFrame) -> bytes:
    """A frame in the default wire grammar: ``HnnnX`` / ``VnnnX`` per hit (3 digits, as the simulated delta4
    controller sends them), ``h`` / ``v`` for no hit, horizontal first (delta4-lasergrid.md §5.7 item 5)."""
    parts = [
        b"".join(b"%s%03dX" % (tag, k) for k in hits) if hits else tag.lower()
        for tag, hits in ((b"H", frame.horizontal), (b"V", frame.vertical))
    ]
    return b"".join(parts)
