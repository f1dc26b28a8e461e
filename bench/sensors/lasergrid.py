"""Laser-grid end-effector sensor of the delta robot: geometry and decoder (hits -> end-effector position).

Spec: ``delta4-lasergrid.md`` §4. Twelve lasers per screen (bull's eye BE, a 15 mm grid G5 and a 22.5 mm grid
G2.5) over 16 x 16 phototransistors at 10 mm pitch give a 2.5 mm resolution. A hit on sensor ``s`` by laser ``l``
means ``BE = s - o_l``; the index alone does not say which laser, so the candidate nearest the a-priori position
is chosen (§4.6), and decoding is guaranteed only while both components of the prior error are below 3.75 mm
(§4.7). This module depends only on the sensor geometry defined here, never on the robot's kinematics.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bench.errors import ConfigError
from bench.sensors.reading import MalformedSample, Reading, now

__all__ = [
    "LASER_NAMES",
    "LASER_OFFSETS_MM",
    "MIN_CANDIDATE_SEPARATION_MM",
    "GridDecode",
    "GridFrame",
    "GridGeometry",
    "LaserGridSensor",
    "Screen",
    "ScreenDecode",
    "ScreenStatus",
    "decode_frame",
    "decode_screen",
    "screen_axes_mm",
]

#: Laser names and offsets from BE in the screen's (i right, j up) axes, mm (§4.4, reconstructed table).
LASER_NAMES = (
    "BE",
    "G5-a",
    "G5-b",
    "G5-c",
    "G2.5-W",
    "G2.5-E",
    "G2.5-S",
    "G2.5-N",
    "G2.5-SW",
    "G2.5-NW",
    "G2.5-SE",
    "G2.5-NE",
)
LASER_OFFSETS_MM = np.array(
    [
        (0.0, 0.0),
        (15.0, 0.0),
        (0.0, -15.0),
        (15.0, -15.0),
        (-22.5, 0.0),
        (22.5, 0.0),
        (0.0, -22.5),
        (0.0, 22.5),
        (-22.5, -22.5),
        (-22.5, 22.5),
        (22.5, -22.5),
        (22.5, 22.5),
    ]
)
LASER_OFFSETS_MM.setflags(write=False)
#: Smallest Chebyshev distance between two candidates of one sensor (mm): the prior must be within half (§4.7).
MIN_CANDIDATE_SEPARATION_MM = 7.5


@dataclass(frozen=True)
class Screen:
    """One detector screen: a square array of sensors in a plane of the robot frame.

    Parameters
    ----------
    name : str
        ``"horizontal"`` or ``"vertical"``.
    axes : tuple of int
        Robot-frame axes (0 = x, 1 = y, 2 = z) along the screen's column (i) and row (j) directions.
    first_centre_mm : tuple of float
        Robot-frame coordinates (along ``axes``) of the centre of sensor (i, j) = (0, 0), mm.
    laser_offset_mm : float
        Offset of this screen's laser set from the end-effector centre along the row axis, mm (the vertical set
        sits 40 mm below z0, §4.2).
    pitch_mm, size : float, int
        Sensor pitch (10 mm) and sensors per side (16).
    index_base : int
        0 or 1: the number of the first sensor (§4.8).
    index_map : ndarray of int, shape (size*size, 2) or None
        (i, j) of each index from a mapping test; ``None`` means the placeholder ``index = size*j + i``.
    mirror : bool
        Mirror the laser pattern along i (the G5 orientation is uncertain, §4.4).
    """

    name: str
    axes: tuple[int, int]
    first_centre_mm: tuple[float, float]
    laser_offset_mm: float = 0.0
    pitch_mm: float = 10.0
    size: int = 16
    index_base: int = 0
    index_map: np.ndarray | None = field(default=None, compare=False, repr=False)
    mirror: bool = False

    def __post_init__(self) -> None:
        if self.index_base not in (0, 1):
            raise ConfigError(f"screen {self.name}: index_base = {self.index_base!r}, expected 0 or 1")
        if self.index_map is not None and np.shape(self.index_map) != (self.size * self.size, 2):
            raise ConfigError(
                f"screen {self.name}: index_map has shape {np.shape(self.index_map)}, "
                f"expected ({self.size * self.size}, 2) rows of (i, j)"
            )

    @property
    def offsets_mm(self) -> np.ndarray:
        """Laser offsets (12, 2) in this screen's (i, j) directions, mirrored if asked."""
        return LASER_OFFSETS_MM * ((-1.0 if self.mirror else 1.0), 1.0)

    def cell_of_index(self, index: int) -> tuple[int, int]:
        """(i, j) of a reported sensor number; raises ``ConfigError`` outside the screen."""
        k = int(index) - self.index_base
        if not 0 <= k < self.size * self.size:
            raise ConfigError(
                f"screen {self.name}: sensor index = {index!r}, expected "
                f"{self.index_base}..{self.size * self.size - 1 + self.index_base}"
            )
        if self.index_map is not None:
            i, j = self.index_map[k]
            return int(i), int(j)
        return k % self.size, k // self.size

    def index_of_cell(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Sensor numbers of cells (i, j) (inverse of :meth:`cell_of_index`)."""
        if self.index_map is None:
            return self.size * np.asarray(j) + np.asarray(i) + self.index_base
        lookup = np.full((self.size, self.size), -1)
        lookup[self.index_map[:, 0], self.index_map[:, 1]] = np.arange(self.size * self.size)
        return lookup[np.asarray(i), np.asarray(j)] + self.index_base

    def centre_mm(self, i: float, j: float) -> np.ndarray:
        """Screen-plane coordinates (2,) of the centre of cell (i, j), mm."""
        return np.asarray(self.first_centre_mm) + self.pitch_mm * np.array([i, j], float)

    def be_from_pose(self, position_mm: np.ndarray) -> np.ndarray:
        """Where this screen's BE laser points, in screen-plane coordinates: shape (..., 3) -> (..., 2)."""
        position_mm = np.asarray(position_mm, float)
        return np.stack(
            [position_mm[..., self.axes[0]], position_mm[..., self.axes[1]] - self.laser_offset_mm], axis=-1
        )


@dataclass(frozen=True)
class GridGeometry:
    """Both screens. Defaults follow the legacy GUI drawing (§4.3): horizontal screen centres at x, y in
    {+-5, ..., +-75} mm; vertical screen in the plane x = x_V reading (y, z), centres at y in {+-5..+-75} mm and
    z in {-225, ..., -75} mm, with its laser set 40 mm below z0. Overwrite from the software calibration (§6.5).
    """

    horizontal: Screen = Screen("horizontal", (0, 1), (-75.0, -75.0))
    vertical: Screen = Screen("vertical", (1, 2), (-75.0, -225.0), laser_offset_mm=40.0)
    calibration_id: str = "lasergrid-gui-default"


@dataclass(frozen=True)
class GridFrame:
    """Sorted sensor numbers lit on each screen in one acquisition (empty tuple: no hit)."""

    horizontal: tuple[int, ...]
    vertical: tuple[int, ...]


class ScreenStatus(enum.Enum):
    """Outcome of decoding one screen (§4.6 step 8)."""

    OK = "ok"
    AMBIGUOUS = "ambiguous"
    FAULT = "fault"
    NO_HIT = "no-hit"


@dataclass(frozen=True)
class ScreenDecode:
    """Result for one screen: BE in screen-plane coordinates (prior kept unless OK/AMBIGUOUS), the laser(s)."""

    status: ScreenStatus
    be_mm: tuple[float, float]
    lasers: tuple[str, ...] = ()
    margin_mm: float = float("inf")
    reason: str = ""


@dataclass(frozen=True)
class GridDecode:
    """Decoded end-effector position for one frame of both screens.

    ``position_mm`` holds measured axes where ``measured`` is True and the prior elsewhere (never NaN); an
    AMBIGUOUS screen contributes its best candidate, so check each screen's status before trusting an axis;
    ``error_mm`` = measured - prior on measured axes, 0 elsewhere; ``y_disagreement_mm`` compares the two screens'
    y (misalignment check, §8.1.2), ``None`` unless both screens are OK.
    """

    position_mm: tuple[float, float, float]
    measured: tuple[bool, bool, bool]
    error_mm: tuple[float, float, float]
    horizontal: ScreenDecode
    vertical: ScreenDecode
    y_disagreement_mm: float | None
    misaligned: bool


_REPORT_TOKEN = re.compile(rb"([HV])(\d{1,3})X|([hv])")


def parse_report(report: bytes, *, source: str = "laser grid") -> GridFrame:
    """Parse one frame of sensor reports: ``H<digits>X`` / ``V<digits>X`` per lit sensor (padded or not), ``h`` /
    ``v`` for no hit on that screen (delta4-lasergrid.md §5.7 item 5). Other bytes raise ``MalformedSample``.

    >>> parse_report(b"H105XV041X"), parse_report(b"hV7X")
    (GridFrame(horizontal=(105,), vertical=(41,)), GridFrame(horizontal=(), vertical=(7,)))
    """
    hits: dict[bytes, set[int]] = {b"H": set(), b"V": set()}
    position = 0
    while position < len(report):
        match = _REPORT_TOKEN.match(report, position)
        if match is None:
            raise MalformedSample(
                f"{source}: unexpected bytes {report[position : position + 8]!r} at offset "
                f"{position} of {report!r}; expected H<n>X, V<n>X, h or v"
            )
        if match.group(1):
            hits[match.group(1)].add(int(match.group(2)))
        position = match.end()
    return GridFrame(tuple(sorted(hits[b"H"])), tuple(sorted(hits[b"V"])))


def _chebyshev(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.max(np.abs(a - b), axis=-1)


def decode_screen(
    screen: Screen,
    indices: list[int] | tuple[int, ...],
    prior_be_mm: np.ndarray,
    *,
    spot_half_width_mm: float = 1.0,
    gate_mm: float = 3.75,
    prior_uncertainty_mm: float = 0.0,
) -> ScreenDecode:
    """Decode the sensor numbers one screen reported into the BE position on that screen (§4.6).

    Parameters
    ----------
    screen : Screen
        Geometry of the screen.
    indices : sequence of int
        Reported sensor numbers (any order; empty for "no hit").
    prior_be_mm : array_like, shape (2,)
        A-priori BE position in screen-plane coordinates (from the command or the FK of the pots), mm.
    spot_half_width_mm : float
        Half-width r of a sensor's detection window, mm; candidates of several hits must agree within 2r.
    gate_mm : float
        The chosen candidate must lie within this distance of the prior on both axes (3.75 mm, §4.7).
    prior_uncertainty_mm : float
        How far the prior may be off; at 3.75 mm or more the laser identity cannot be guaranteed (AMBIGUOUS).

    Returns
    -------
    ScreenDecode
        NO_HIT keeps the prior; FAULT (no consistent explanation) keeps the prior; AMBIGUOUS gives the best guess.
    """
    prior = np.asarray(prior_be_mm, float)
    if len(indices) == 0:
        return ScreenDecode(ScreenStatus.NO_HIT, tuple(prior), reason="no sensor lit; prior kept")
    centres = np.array([screen.centre_mm(*screen.cell_of_index(k)) for k in indices])
    candidates = centres[:, None, :] - screen.offsets_mm[None, :, :]  # (hits, 12, 2)
    # every laser of the first hit at once (a decoder runs per frame): how far each other hit's 12 candidates lie
    # from each of its 12, (hits-1, 12, 12); a laser explains the frame when every other hit has a candidate near it
    apart = _chebyshev(candidates[1:, None, :, :], candidates[0][None, :, None, :])
    firsts = np.flatnonzero((apart <= 2 * spot_half_width_mm).any(axis=2).all(axis=0))
    if firsts.size == 0:
        return ScreenDecode(
            ScreenStatus.FAULT,
            tuple(prior),
            reason=f"sensors {list(indices)} cannot all be lit by one BE position "
            "(spurious light, wrong index map or misalignment); prior kept",
        )
    # the other hits' nearest candidates to each explaining laser: (solutions, hits)
    chosen = np.column_stack([firsts, apart[:, firsts, :].argmin(axis=2).T])
    points = candidates[np.arange(len(indices)), chosen].mean(axis=1)  # (solutions, 2)
    distances = _chebyshev(points, prior)
    order = np.argsort(distances)
    best, lasers = points[order[0]], tuple(LASER_NAMES[c] for c in chosen[order[0]])
    margin = float(distances[order[1]] - distances[order[0]]) if len(order) > 1 else float("inf")
    if distances[order[0]] >= gate_mm:
        status, reason = (
            ScreenStatus.AMBIGUOUS,
            (f"nearest candidate is {distances[order[0]]:.2f} mm from the prior, outside the {gate_mm} mm gate"),
        )
    elif margin < 2 * spot_half_width_mm:
        status, reason = ScreenStatus.AMBIGUOUS, f"two candidates within {margin:.2f} mm of each other"
    elif prior_uncertainty_mm >= MIN_CANDIDATE_SEPARATION_MM / 2:
        status, reason = (
            ScreenStatus.AMBIGUOUS,
            (
                f"prior uncertainty {prior_uncertainty_mm} mm >= "
                f"{MIN_CANDIDATE_SEPARATION_MM / 2} mm: laser identity not assured"
            ),
        )
    else:
        status, reason = ScreenStatus.OK, ""
    return ScreenDecode(status, (float(best[0]), float(best[1])), lasers, margin, reason)


def screen_axes_mm(screen: Screen, result: ScreenDecode) -> dict[int, float]:
    """The robot-frame coordinates (axis index -> mm) of the end-effector centre that one screen's decoded BE
    gives: the screen's two axes, with its laser set's offset added back (vertical screen: z = BE_j + 40 mm).

    >>> screen_axes_mm(GridGeometry().vertical, ScreenDecode(ScreenStatus.OK, (-5.0, -240.0)))
    {1: -5.0, 2: -200.0}
    """
    values = (result.be_mm[0], result.be_mm[1] + screen.laser_offset_mm)
    return {axis: float(value) for axis, value in zip(screen.axes, values)}


def decode_frame(
    geometry: GridGeometry,
    horizontal_indices: list[int] | tuple[int, ...],
    vertical_indices: list[int] | tuple[int, ...],
    prior_mm: np.ndarray,
    **options: float,
) -> GridDecode:
    """Decode both screens into the end-effector centre (x, y, z) in mm (§4.6 step 7).

    The horizontal screen gives (x, y), the vertical one (y, z) after adding back its laser offset. y is taken from
    the horizontal screen; when both screens are OK a y disagreement over 2.5 mm flags misalignment. ``options``
    are passed to :func:`decode_screen`.

    Examples
    --------
    BE over sensor (7, 7) of the horizontal screen, i.e. (-5, -5) mm, moved 5 mm in +x: G5-a lands on (9, 7),
    index 16*7 + 9 = 121 (Fig. 10 a).

    >>> result = decode_frame(GridGeometry(), [121], [], [0.0, -5.0, -150.0])
    >>> result.position_mm[:2], result.horizontal.lasers
    ((0.0, -5.0), ('G5-a',))
    """
    prior = np.asarray(prior_mm, float)
    if prior.shape != (3,) or not np.all(np.isfinite(prior)):
        raise ConfigError(f"laser grid: prior_mm = {prior_mm!r}, expected a finite (x, y, z) in mm")
    h = decode_screen(geometry.horizontal, horizontal_indices, geometry.horizontal.be_from_pose(prior), **options)
    v = decode_screen(geometry.vertical, vertical_indices, geometry.vertical.be_from_pose(prior), **options)
    position = prior.copy()
    measured = [False, False, False]
    for screen, result in ((geometry.horizontal, h), (geometry.vertical, v)):
        if result.status in (ScreenStatus.OK, ScreenStatus.AMBIGUOUS):
            for axis, value in screen_axes_mm(screen, result).items():
                if not measured[axis]:
                    position[axis], measured[axis] = value, True
    disagreement = None
    if h.status is ScreenStatus.OK and v.status is ScreenStatus.OK:
        disagreement = float(v.be_mm[0] - h.be_mm[1])
    error = np.where(measured, position - prior, 0.0)
    return GridDecode(
        tuple(float(p) for p in position),
        tuple(measured),
        tuple(float(e) for e in error),
        h,
        v,
        disagreement,
        disagreement is not None and abs(disagreement) > 2.5,
    )


class LaserGridSensor:
    """The laser grid as a :class:`~bench.sensors.reading.Sensor`: one frame decoded against the current prior.

    Parameters
    ----------
    frames : callable
        Returns the next :class:`GridFrame` (from the controller's sensor reports, or a simulator's
        ``frame_source``).
    prior_mm : callable
        Returns the a-priori end-effector centre (3,) in mm (commanded pose or FK of the pot angles).
    geometry : GridGeometry
        Screens and index maps; its ``calibration_id`` travels with every reading.
    options
        Passed to :func:`decode_screen` (``spot_half_width_mm``, ``gate_mm``, ``prior_uncertainty_mm``).

    A reading is valid only when both screens decode OK and agree on y; otherwise ``note`` says why and the
    value holds the prior on unmeasured axes.
    """

    def __init__(
        self,
        frames: Callable[[], GridFrame],
        prior_mm: Callable[[], np.ndarray],
        *,
        geometry: GridGeometry = GridGeometry(),
        name: str = "laser-grid",
        **options: float,
    ) -> None:
        self.name = name
        self._frames = frames
        self._prior = prior_mm
        self.geometry = geometry
        self.options = options

    def settings(self) -> dict[str, object]:
        """What a run manifest stores about the laser grid: geometry choices and decoding options."""
        screens = {
            s.name: {
                "axes": list(s.axes),
                "first_centre_mm": list(s.first_centre_mm),
                "laser_offset_mm": s.laser_offset_mm,
                "pitch_mm": s.pitch_mm,
                "size": s.size,
                "index_base": s.index_base,
                "mirror": s.mirror,
                "index_map": s.index_map is not None,
            }
            for s in (self.geometry.horizontal, self.geometry.vertical)
        }
        return {
            "sensor": "laser grid",
            "name": self.name,
            "calibration_id": self.geometry.calibration_id,
            "screens": screens,
            "options": dict(self.options),
        }

    def read(self) -> Reading:
        frame = self._frames()
        t_mono, t_wall = now()
        result = decode_frame(self.geometry, frame.horizontal, frame.vertical, self._prior(), **self.options)
        screens = (("horizontal", result.horizontal), ("vertical", result.vertical))
        valid = all(s.status is ScreenStatus.OK for _, s in screens) and not result.misaligned
        note = "; ".join(f"{n}: {s.status.value} {s.reason}".strip() for n, s in screens)
        if result.misaligned:
            note += f"; screens disagree on y by {result.y_disagreement_mm:+.2f} mm (misalignment)"
        raw = f"H:{','.join(map(str, frame.horizontal))} V:{','.join(map(str, frame.vertical))}"
        return Reading(
            result.position_mm,
            "mm",
            t_mono,
            t_wall,
            raw=raw,
            calibration_id=self.geometry.calibration_id,
            source=self.name,
            valid=valid,
            note=note,
        )
