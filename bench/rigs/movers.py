"""Movers: each robot's driver adapted to the runner's :class:`~bench.rigs.interfaces.Mover` (mm, degrees, % of the
rated velocity), with one emergency-stop latch for every robot.

The latch lives here, once: after :meth:`LatchingMover.emergency_stop` every later move of the rig is refused until
:meth:`LatchingMover.release_stop` (a person has looked at the robot; the pkm5's drivers are enabled again). The pkm5 driver latches as well, inside the driver,
with its MOVE and STOP writes under one lock (``Pkm5Controller.emergency_stop``), so a MOVE decided just before the
stop can never follow it on the wire; the mover's latch is what the runner and the GUI see for both robots.
"""

from __future__ import annotations

import threading
from typing import Any

from bench.errors import ConfigError, LinkError
from bench.robots.pkm5 import RATED_SPEED_STEPS_S

__all__ = ["DeltaMover", "LatchingMover", "Pkm5Mover"]


class LatchingMover:
    """The emergency-stop latch shared by every robot's mover; subclasses implement ``_move`` and ``_stop_now``."""

    #: the robot's record in :mod:`bench.robot_kinds`
    kind = "robot"

    def __init__(self, controller: Any) -> None:
        self.controller = controller
        self._latched = threading.Event()

    @property
    def stop_latched(self) -> bool:
        return self._latched.is_set()

    def _refuse_if_latched(self, what: str) -> None:
        if self._latched.is_set():
            raise LinkError(
                f"{self.kind}: {what} refused: an emergency stop is latched (release it after checking the robot)"
            )

    def move_to(self, target: tuple[float, ...], *, velocity_pct: float) -> None:
        self._refuse_if_latched(f"move to {tuple(target)}")
        self._move(tuple(target), velocity_pct)

    def move_actuator(self, axis: int, stroke_mm: float, *, velocity_pct: float) -> None:
        """One actuator of an actuator bench to ``stroke_mm``; this robot has none."""
        raise ConfigError(f"actuator {axis} to {stroke_mm:g} mm: the {self.kind} has no actuator-bench mode")

    def stop(self) -> None:
        self.controller.stop()

    def emergency_stop(self) -> None:
        """Stop now and refuse every later move of this rig."""
        self._latched.set()
        self._stop_now()

    def release_stop(self) -> None:
        """A person checked the robot: moves are allowed again."""
        self._release()
        self._latched.clear()

    def shutdown(self) -> None:
        self.controller.shutdown()

    @property
    def geometry(self) -> Any:
        """The geometry every move is commanded and pre-flighted by (the driver's; None: the documented one)."""
        return self.controller.geometry

    def use_geometry(self, geometry: Any) -> None:
        """Command and pre-flight every later move by ``geometry`` (a kinematic calibration in force)."""
        self.controller.geometry = geometry

    def _release(self) -> None:
        """What the controller needs after an emergency stop before it moves again (nothing by default)."""

    def _move(self, target: tuple[float, ...], velocity_pct: float) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def settings(self) -> dict[str, Any]:  # pragma: no cover - abstract
        raise NotImplementedError

    def _stop_now(self) -> None:
        self.controller.stop()


class Pkm5Mover(LatchingMover):
    """The pkm5 controller: velocity in % of the rated speed (:data:`bench.robots.pkm5.RATED_SPEED_STEPS_S`)."""

    kind = "pkm5"

    def __init__(self, controller: Any, rated_speed_steps_s: int = RATED_SPEED_STEPS_S) -> None:
        super().__init__(controller)
        self.rated_speed_steps_s = rated_speed_steps_s

    def _speed(self, velocity_pct: float) -> int:
        return max(1, round(self.rated_speed_steps_s * velocity_pct / 100.0))

    def _move(self, target: tuple[float, ...], velocity_pct: float) -> None:
        pose = target + (0.0,) * (5 - len(target))
        self.controller.move_to_pose(pose, speed_steps_s=self._speed(velocity_pct))

    def move_actuator(self, axis: int, stroke_mm: float, *, velocity_pct: float) -> None:
        """Actuator bench only (the controller refuses otherwise): one axis to ``stroke_mm``, the others hold."""
        self._refuse_if_latched(f"actuator {axis} to {stroke_mm:g} mm")
        self.controller.move_actuator(axis, stroke_mm, speed_steps_s=self._speed(velocity_pct))

    def _stop_now(self) -> None:
        self.controller.emergency_stop()  # the driver's own latch, ordered with its MOVE writes

    def _release(self) -> None:
        self.controller.enable()  # releases the driver's latch

    def settings(self) -> dict[str, Any]:
        return {**self.controller.settings(), "rated_speed_steps_s": self.rated_speed_steps_s}


class DeltaMover(LatchingMover):
    """The delta4 controller (hobby servos: velocity not settable). Its stop is one ``G`` byte; a reference already
    on its way is only stored by the stopped controller, which runs it on the next ``E``, and a latched rig never
    sends ``E`` again."""

    kind = "delta4"

    def _move(self, target: tuple[float, ...], velocity_pct: float) -> None:
        self.controller.move_to(target[:3], require_settled=True)

    def settings(self) -> dict[str, Any]:
        return {**self.controller.settings(), "velocity": "servo maximum (not settable)"}
