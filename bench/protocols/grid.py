"""The delta robot's rig parts: the driver as a Mover and the laser grid (reported by the controller) as Instrument.

The delta4 controller streams the laser-grid sensor reports itself (``H..X``/``V..X`` tokens); a capture waits
for the first complete report that starts after the capture was asked for, so a report from before the move can
never be stored for the new pose. Poses are decoded with :func:`bench.sensors.lasergrid.decode_frame` against the
commanded position as prior; an invalid decode (no hit, ambiguous, screens disagreeing) raises ``LinkError``, so
the run stops safely (resumable) instead of storing a bad sample. ``grid_hit`` captures store what was hit.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from bench.errors import LinkError
from bench.protocols.rig import Measurement
from bench.protocols.steps import Capture

__all__ = ["DeltaMover", "LaserGridInstrument"]


class DeltaMover:
    """Adapts :class:`bench.robots.delta4.Delta4Controller` to ``Mover`` (hobby servos: velocity not settable)."""

    def __init__(self, controller: Any) -> None:
        self.controller = controller

    def move_to(self, target: tuple[float, ...], *, velocity_pct: float) -> None:
        self.controller.move_to(tuple(target[:3]), require_settled=True)

    def stop(self) -> None:
        self.controller.stop()

    def shutdown(self) -> None:
        self.controller.shutdown()

    def settings(self) -> dict[str, Any]:
        return {**self.controller.settings(), "velocity": "servo maximum (not settable)"}


class LaserGridInstrument:
    """Laser-grid readings from the controller's sensor reports."""

    def __init__(self, controller: Any, geometry: Any = None, *, report_timeout_s: float = 2.0) -> None:
        from bench.sensors.lasergrid import GridGeometry

        self.controller = controller
        self.geometry = geometry or GridGeometry()
        self.report_timeout_s = report_timeout_s

    def _fresh_frame(self) -> Any:
        asked = time.monotonic()
        deadline = asked + self.report_timeout_s
        while True:
            frame = self.controller.read_sensor_frame(max(0.001, deadline - time.monotonic()))
            if frame.t_monotonic_s >= asked:
                return frame

    def measure(self, capture: Capture) -> Measurement:
        from bench.sensors.lasergrid import ScreenStatus, decode_frame

        frame = self._fresh_frame()
        raw = {"horizontal": list(frame.horizontal), "vertical": list(frame.vertical),
               "calibration": self.geometry.calibration_id}
        if capture.kind == "grid_hit":
            screen = self.geometry.horizontal
            expected = int(screen.index_of_cell(capture.conditions["expected_i"], capture.conditions["expected_j"]))
            return Measurement({"expected_index": float(expected),
                                "hit_expected": float(expected in frame.horizontal),
                                "hit_any": float(bool(frame.horizontal)),
                                "hits": float(len(frame.horizontal))}, raw=raw)
        prior = np.array([capture.commanded[k] for k in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")])
        result = decode_frame(self.geometry, frame.horizontal, frame.vertical, prior)
        statuses = (result.horizontal.status, result.vertical.status)
        if any(s is not ScreenStatus.OK for s in statuses) or result.misaligned:
            raise LinkError(f"laser grid at {capture.pose} cycle {capture.cycle}: no valid reading "
                            f"({result.horizontal.status.value}/{result.vertical.status.value}, report {raw}); "
                            "the sample is not stored, fix the grid and resume the run")
        x_mm, y_mm, z_mm = result.position_mm
        return Measurement({"x_mm": x_mm, "y_mm": y_mm, "z_mm": z_mm}, raw=raw)

    def settings(self) -> dict[str, Any]:
        return {"instrument": "laser grid (controller reports)", "calibration_id": self.geometry.calibration_id,
                "report_timeout_s": self.report_timeout_s}
