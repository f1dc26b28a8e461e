"""How a sensor of a station is opened: :class:`SensorOpening`, what the opener its registry record names is given
(:attr:`bench.sensor_kinds.SensorKind.instrument` and ``operator``), and the one way a station's serial port opens."""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

from bench.errors import LinkError
from bench.rigs.station import Station
from bench.robot_kinds import robot_kind
from bench.robots.link import open_port

__all__ = ["POLL_S", "SensorOpening", "open_station_port"]

#: Read slice of the controller ports (the drivers poll in slices; deadlines are theirs).
POLL_S = 0.05


@dataclass
class SensorOpening:
    """What a sensor's opener (:attr:`bench.sensor_kinds.SensorKind.instrument` / ``operator``) works with: the
    station, the sensor's spec, the robot's controller, the store (a calibration in force is recorded there and its
    id appended to ``calibration_ids``, so every sample names it) and ``opened``, which closes what the opener
    opened, newest first, when a later device fails or the rig closes."""

    station: Station
    spec: Any
    controller: Any
    store: Any
    opened: ExitStack
    calibration_ids: list[int]
    #: how much faster than real time the rig runs (1 on hardware; a rehearsal's speed factor)
    speed_factor: float = 1.0

    def port(self, key: str, url: str, baud: int) -> Any:
        """A serial port opened exclusively; a failure names the station ``key``, the device and what to check."""
        return open_station_port(self.station, key, url, baud, self.opened)

    def home(self) -> tuple[float, ...]:
        """The robot's home pose (a zeroed instrument's origin)."""
        return tuple(robot_kind(self.station.robot).resolved("home")())


def open_station_port(station: Station, key: str, url: str, baud: int, opened: ExitStack) -> Any:
    """Open a port exclusively; a failure names the station key, the device and what to check."""
    try:
        port = open_port(url, baudrate=baud, timeout=POLL_S, exclusive=True)
    except LinkError as exc:
        cause = exc.__cause__
        why = getattr(cause, "strerror", None) or str(cause or exc)
        raise LinkError(
            f"{station.source}: {key} = {url!r}: cannot open it ({why}); is the device plugged in, the "
            "name right and the port free? (bench station check)"
        ) from None
    opened.callback(port.close)
    return port
