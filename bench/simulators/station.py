"""Rehearse a station without hardware: each device the station names is replaced by its simulator, device for
device, and the rig is then built from the resulting station by the hardware builder (:mod:`bench.rigs.builder`).

- ``[controller]``: ``bench sim pkm5`` / ``bench sim delta4`` on a pseudo-terminal, started ``--hardware-only``
  (the pkm5 simulator answers its SIM verbs as unknown, as the firmware does), so a rehearsal proves the hardware
  path never asks a simulator for its truth. Each simulator writes its truth log, for the tests to compare with.

Each sensor is stood in for by the function its record names (:attr:`bench.sensor_kinds.SensorKind.stand_in`):

- ``[mice]``: the pkm5 simulator's ``--mice DIR`` FIFOs, read as event devices.
- ``[laser_grid]``: the delta4 simulator's own sensor reports (the grid is read by the controller).
- ``[camera]`` (delta4): the delta4 simulator's ``--camera FIFO`` video stream of the true laser spot
  (:mod:`bench.simulators.camera_feed`), with a plane calibration made from the simulated camera's own chessboard
  image (the station's calibration file belongs to the real camera).
- ``[calliper]`` typed: the operator types, as on hardware; a serial calliper is rehearsed as typed (its simulator
  needs the gauge's position, which only the person at the bench knows).
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from collections.abc import Callable
from typing import Any

from bench.errors import ConfigError
from bench.rigs.station import Station
from bench.sensor_kinds import sensor_kind
from bench.simulators.rig import end_process, start_simulator

__all__ = ["Rehearsal", "rehearse"]


@dataclasses.dataclass
class Rehearsal:
    """A station whose devices are simulators, the simulators' truth log, and how to stop them."""

    station: Station
    truth_path: str
    closers: list[Callable[[], None]]
    #: what the run's ``settings.simulator`` records of the simulated robot (``ideal``, ``true_geometry_seed``)
    settings: dict = dataclasses.field(default_factory=dict)

    def close(self) -> None:
        while self.closers:
            self.closers.pop()()


def rehearse(
    station: Station,
    *,
    seed: int = 0,
    speed_factor: float = 10000.0,
    ideal: bool = False,
    true_geometry_seed: int | None = None,
) -> Rehearsal:
    """Start a simulator for every device of ``station``; the returned station names the simulators' devices.
    ``true_geometry_seed``: the simulated robot moves by that seed's true geometry (``--true-geometry-seed``)."""
    if true_geometry_seed is not None and station.controller.fixture != "assembled":
        raise ConfigError(
            f"--true-geometry-seed {true_geometry_seed}: the {station.controller.fixture} has no "
            "geometry, expected an assembled robot's station"
        )
    if not speed_factor > 0 or speed_factor == float("inf"):
        raise ConfigError(f"--speed-factor = {speed_factor:g}, expected a finite number > 0")
    folder = tempfile.TemporaryDirectory(prefix="bench-rehearsal-")
    closers: list[Callable[[], None]] = [folder.cleanup]
    truth_path = os.path.join(folder.name, "truth.jsonl")
    options = ["--truth", truth_path]
    if true_geometry_seed is not None:
        options += ["--true-geometry-seed", str(int(true_geometry_seed))]
    if station.robot == "delta4" and station.sensor("laser_grid") is None:
        options.append("--no-grid")  # a controller whose screens are not plugged in reports no hit
    if station.robot == "pkm5":
        options += ["--hardware-only", "--fixture", station.controller.fixture]
    sensors: dict[str, Any] = {}
    try:
        for name, spec in station.sensors.items():
            kind = sensor_kind(name)
            if kind.stand_in is not None and kind.serves(station.robot, station.controller.fixture):
                spec, needs = kind.resolved("stand_in")(station, spec, folder=folder.name, truth_path=truth_path)
                options += needs
            sensors[name] = spec
        process, pty_path = start_simulator(
            station.robot, seed=seed, speed_factor=speed_factor, ideal=ideal, options=tuple(options)
        )
    except BaseException:
        folder.cleanup()
        raise
    closers.append(lambda: end_process(process))
    simulated = dataclasses.replace(
        station,
        controller=dataclasses.replace(station.controller, port=pty_path),
        sensors=sensors,
        simulated=True,
        devices={
            "controller.port": pty_path,
            **{
                key: device
                for name, spec in sensors.items()
                for key, device in sensor_kind(name).named_devices(spec).items()
            },
        },
    )
    settings = {
        **({"ideal": True} if ideal else {}),
        **({"true_geometry_seed": int(true_geometry_seed)} if true_geometry_seed is not None else {}),
    }
    return Rehearsal(simulated, truth_path, closers, settings)
