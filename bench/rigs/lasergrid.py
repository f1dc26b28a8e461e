"""The delta robot's rig parts: the driver as a Mover and the laser grid (reported by the controller) as Instrument.

The delta4 controller streams the laser-grid sensor reports itself (``H..X``/``V..X`` tokens). A capture takes the
first report whose first token was read after the capture was asked for: the move before it waited for ``z``, and
tokens are read in wire order, so that report was sent after the servos settled and a report of the previous pose
is never stored for the new one (the protocol's settle time, at least one 80 ms frame, covers the acquisition).

**Pose captures: partial readings.** Each screen is decoded on its own with
:func:`bench.sensors.lasergrid.decode_frame` against the commanded position as prior (the controller sends no
joint angles, so the command is the only prior; the decoding is guaranteed while each error component is below
3.75 mm, delta4-lasergrid.md §4.7). A screen whose status is ``ok`` measures its two axes (horizontal: x, y;
vertical: y, z, y taken from the horizontal screen when both measure it). A screen that reports no hit (25 % of
the 2.5 mm phases are blind, and with a 1 mm detection window 52 % of positions are, §4.5), an ambiguous
candidate or a fault measures nothing, and its axes are **absent** from the stored values: never the prior, never
0. When both screens decode but disagree on y by more than one 2.5 mm step, one of them took the wrong laser and
nothing says which, so neither is stored as a position. Each sample stores ``horizontal_valid`` /
``vertical_valid`` (1: that screen's axes are stored), ``horizontal_hits`` / ``vertical_hits`` (sensors lit) and,
when both decoded, ``y_disagreement_mm``; the raw data keep the report bytes, the lit sensor numbers, each screen's
status, reason and laser, and the decoder options, so every reading can be decoded again.

Why not move the robot to a detectable phase: a dithered reading would be of another commanded pose, and the
dither itself is realised only within the robot's own 2-3 mm positioning error (the very quantity measured), so
subtracting the commanded dither would put that error into the reading. Readings therefore measure the pose the
protocol commanded, or nothing; ``bench analyze grid-positioning`` reports the hit rate beside the statistics.

``grid_hit`` captures (hit repeatability) store what was hit on the horizontal screen.

**A grid that stops, closes or freezes fails the run at the first capture after it did** (issue 32): no report
begun within ``report_timeout_s`` of the capture is a ``LinkTimeout`` (the controller sends one every 80 ms), a
vanished device a ``LinkError`` (the link's), and a report byte-for-byte that of the previous pose capture, with
sensors lit, after the command moved by more than ``FROZEN_MOVE_MM`` on some axis is a ``SensorStalled``: a spot
that moved that far lights other sensors (a 10 mm pitch, a 1 mm detection window), so the same lit sensors are a
controller handing back its last frame. (A move of exactly a laser-offset difference on both screens could light
the same sensors by other lasers: such a capture is refused too, never stored wrong.)
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.errors import LinkTimeout
from bench.rigs.interfaces import Measurement
from bench.sensors.reading import SensorStalled
from bench.steps import Capture

if TYPE_CHECKING:
    from bench.rigs.opening import SensorOpening
    from bench.rigs.station import StationTable

__all__ = [
    "AXES",
    "DEFAULT_DECODER",
    "FROZEN_MOVE_MM",
    "LaserGridInstrument",
    "LaserGridSpec",
    "grid_pose_values",
    "open_laser_grid",
    "parse_laser_grid",
]

#: Robot-frame axis names, in the order of :attr:`bench.sensors.lasergrid.Screen.axes`.
AXES = ("x_mm", "y_mm", "z_mm")
#: Decoder options stored with every run unless the rig sets others (delta4-lasergrid.md §4.6, §4.10 defaults).
DEFAULT_DECODER = {"spot_half_width_mm": 1.0, "gate_mm": 3.75, "prior_uncertainty_mm": 0.0}
#: A commanded move (mm, largest axis) after which the same lit sensors mean a frozen grid: the decoding gate (§4.7).
FROZEN_MOVE_MM = 3.75


@dataclass(frozen=True)
class LaserGridSpec:
    """The delta4's laser grid (its screens are read by the delta4 controller) and the decoder's options."""

    spot_half_width_mm: float = DEFAULT_DECODER["spot_half_width_mm"]
    gate_mm: float = DEFAULT_DECODER["gate_mm"]


def parse_laser_grid(table: StationTable) -> LaserGridSpec:
    """``[laser_grid]`` of a station file (``spot_half_width_mm``, ``gate_mm``)."""
    defaults = LaserGridSpec()
    return LaserGridSpec(
        spot_half_width_mm=table.number("spot_half_width_mm", defaults.spot_half_width_mm),
        gate_mm=table.number("gate_mm", defaults.gate_mm),
    )


def open_laser_grid(opening: SensorOpening) -> LaserGridInstrument:
    """The grid as the rig's instrument, read from the delta4 controller's reports; its geometry recorded as the
    calibration in force."""
    spec: LaserGridSpec = opening.spec
    decoder = {**DEFAULT_DECODER, "spot_half_width_mm": spec.spot_half_width_mm, "gate_mm": spec.gate_mm}
    instrument = LaserGridInstrument(opening.controller, decoder=decoder)
    opening.calibration_ids.append(instrument.record_geometry(opening.store))
    return instrument


def grid_pose_values(
    geometry: Any, horizontal: Sequence[int], vertical: Sequence[int], prior_mm: Any, **options: float
) -> tuple[dict[str, float], dict[str, Any]]:
    """Decode one report into the stored values (measured axes only) and the decoding's raw record.

    Returns ``(values, decoding)``: ``values`` holds ``x_mm``/``y_mm``/``z_mm`` for the axes a valid screen
    measured, ``horizontal_valid``/``vertical_valid``, ``horizontal_hits``/``vertical_hits`` and, when both screens
    decoded, ``y_disagreement_mm``; ``decoding`` holds each screen's status, reason and laser(s) and whether the
    screens disagree. ``options`` go to :func:`bench.sensors.lasergrid.decode_screen`.

    >>> from bench.sensors.lasergrid import GridGeometry
    >>> values, decoding = grid_pose_values(GridGeometry(), [105], [], [0.0, 0.0, -200.0])
    >>> values, decoding["status"]
    ({'x_mm': 0.0, 'y_mm': 0.0, 'horizontal_valid': 1.0, 'vertical_valid': 0.0, 'horizontal_hits': 1.0, \
'vertical_hits': 0.0}, {'horizontal': 'ok', 'vertical': 'no-hit'})
    """
    from bench.sensors.lasergrid import ScreenStatus, decode_frame, screen_axes_mm

    result = decode_frame(geometry, list(horizontal), list(vertical), np.asarray(prior_mm, float), **options)
    screens = ((geometry.horizontal, result.horizontal), (geometry.vertical, result.vertical))
    measured: dict[int, float] = {}
    valid = {}
    for screen, decoded in screens:
        valid[screen.name] = decoded.status is ScreenStatus.OK and not result.misaligned
        if valid[screen.name]:
            for axis, value in screen_axes_mm(screen, decoded).items():
                measured.setdefault(axis, value)
    values = {AXES[axis]: measured[axis] for axis in sorted(measured)}
    values |= {
        "horizontal_valid": float(valid["horizontal"]),
        "vertical_valid": float(valid["vertical"]),
        "horizontal_hits": float(len(horizontal)),
        "vertical_hits": float(len(vertical)),
    }
    if result.y_disagreement_mm is not None:
        values["y_disagreement_mm"] = result.y_disagreement_mm
    decoding = {
        "status": {s.name: d.status.value for s, d in screens},
        "reason": {s.name: d.reason for s, d in screens if d.reason},
        "lasers": {s.name: list(d.lasers) for s, d in screens if d.lasers},
        "screens_disagree": bool(result.misaligned),
    }
    return values, decoding


class LaserGridInstrument:
    """Laser-grid readings from the controller's sensor reports.

    Parameters
    ----------
    controller : Delta4Controller
        The driver whose ``read_sensor_frame`` gives the reports.
    geometry : GridGeometry, optional
        Screens and index maps (default: the legacy GUI geometry); its ``calibration_id`` is stored with each sample.
    report_timeout_s : float
        How long to wait for a fresh report, s.
    decoder : dict, optional
        Options of :func:`bench.sensors.lasergrid.decode_screen` (``spot_half_width_mm``, ``gate_mm``,
        ``prior_uncertainty_mm``): the detection window must be the one measured on the rig (§4.5).
    truth : callable, optional
        Simulated rigs only: returns the simulator's true attained position (mm), stored in the raw data as
        ``true_pose`` for comparison; never used to decode.
    """

    def __init__(
        self,
        controller: Any,
        geometry: Any = None,
        *,
        report_timeout_s: float = 2.0,
        decoder: dict[str, float] | None = None,
        truth: Callable[[], Sequence[float]] | None = None,
    ) -> None:
        from bench.sensors.lasergrid import GridGeometry

        self.controller = controller
        self.geometry = geometry or GridGeometry()
        self.report_timeout_s = report_timeout_s
        self.decoder = {**DEFAULT_DECODER, **(decoder or {})}
        self.truth = truth
        self._last_pose_report: tuple[tuple[tuple[int, ...], tuple[int, ...]], np.ndarray] | None = None

    def _check_not_frozen(self, frame: Any, commanded_mm: np.ndarray) -> None:
        """Refuse a report identical to the previous pose capture's, with sensors lit, after a move the spot cannot
        have made without lighting other sensors (module docstring)."""
        lit = (tuple(frame.horizontal), tuple(frame.vertical))
        previous, self._last_pose_report = self._last_pose_report, (lit, commanded_mm)
        if previous is None or not (frame.horizontal or frame.vertical) or lit != previous[0]:
            return
        moved = float(np.max(np.abs(commanded_mm - previous[1])))
        if moved > FROZEN_MOVE_MM:
            raise SensorStalled(
                f"laser grid: the report {bytes(frame.raw).decode('ascii', 'replace')!r} lights the sensors of the previous pose's, "
                f"after a {moved:.1f} mm move (a frozen grid or controller); the reading is refused; "
                "check the controller's sensor reports, then resume the run"
            )

    def record_geometry(self, store: Any) -> int:
        """Record the screens' geometry as the calibration in force (get-or-create) in ``store``; returns its id."""
        return store.ensure_calibration(
            self.geometry.calibration_id,
            {"screens": repr(self.geometry)},
            notes="laser-grid geometry of the legacy GUI drawing",
        ).id

    def _fresh_frame(self) -> Any:
        asked = time.monotonic()
        deadline = asked + self.report_timeout_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise LinkTimeout(
                    f"laser grid: no sensor report begun within {self.report_timeout_s:g} s of the "
                    "capture; check that the controller was started (E) and its screens are wired"
                )
            frame = self.controller.read_sensor_frame(remaining)
            if frame.t_first_token_s >= asked:
                return frame

    def measure(self, capture: Capture) -> Measurement:
        frame = self._fresh_frame()
        raw: dict[str, Any] = {
            "report": frame.raw.decode("ascii", "replace"),
            "horizontal": list(frame.horizontal),
            "vertical": list(frame.vertical),
            "calibration": self.geometry.calibration_id,
        }
        if self.truth is not None:
            raw["true_pose"] = [round(float(v), 6) for v in self.truth()]
        if capture.kind == "grid_hit":
            screen = self.geometry.horizontal
            cell = (np.asarray(int(capture.conditions[key])) for key in ("expected_i", "expected_j"))
            expected = int(screen.index_of_cell(*cell))
            return Measurement(
                {
                    "expected_index": float(expected),
                    "hit_expected": float(expected in frame.horizontal),
                    "hit_any": float(bool(frame.horizontal)),
                    "hits": float(len(frame.horizontal)),
                },
                raw=raw,
            )
        prior = [capture.commanded[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")]
        self._check_not_frozen(frame, np.asarray(prior, dtype=float))
        values, decoding = grid_pose_values(self.geometry, frame.horizontal, frame.vertical, prior, **self.decoder)
        return Measurement(values, raw={**raw, **decoding, "decoder": self.decoder})

    def settings(self) -> dict[str, Any]:
        return {
            "instrument": "laser grid (controller reports)",
            "calibration_id": self.geometry.calibration_id,
            "report_timeout_s": self.report_timeout_s,
            "decoder": self.decoder,
            "prior": "commanded position",
            "readings": "per screen; axes of a screen without a valid decode are not stored",
        }
