"""Rehearse a station without hardware: each device the station names is replaced by its simulator, device for
device, and the rig is then built from the resulting station by the hardware builder (:mod:`bench.rigs.builder`).

- ``[controller]``: ``bench sim pkm5`` / ``bench sim delta4`` on a pseudo-terminal, started ``--hardware-only``
  (the pkm5 simulator answers its SIM verbs as unknown, as the firmware does), so a rehearsal proves the hardware
  path never asks a simulator for its truth. Each simulator writes its truth log, for the tests to compare with.
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

from bench.errors import ConfigError
from bench.rigs.station import CalliperSpec, Station
from bench.simulators.mice_feed import fifo_paths
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
    if station.camera is not None and station.robot != "delta4":
        raise ConfigError(
            f"{station.source}: [camera] on the {station.robot} cannot be rehearsed yet (only the "
            "delta4 simulator streams a camera); check it with bench station check, or rehearse the "
            "protocol with [mice]"
        )
    if station.camera is not None and station.camera.plane != "xy":
        raise ConfigError(
            f"{station.source}: camera.plane = {station.camera.plane!r}: the simulated camera watches "
            "the x-y plane, expected 'xy' for a rehearsal"
        )
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
    if station.robot == "delta4" and station.laser_grid is None:
        options.append("--no-grid")  # a controller whose screens are not plugged in reports no hit
    mice, camera = station.mice, station.camera
    if camera is not None:
        from bench.simulators.camera_feed import write_plane_calibration

        device = os.path.join(folder.name, "camera.y4m")
        calibration = os.path.join(folder.name, "camera-plane.json")
        os.mkfifo(device)
        write_plane_calibration(calibration)
        options += ["--camera", device]
        camera = dataclasses.replace(camera, device=device, calibration=calibration)
    if station.robot == "pkm5":
        options += ["--hardware-only", "--fixture", station.controller.fixture]
        if mice is not None and station.controller.fixture == "assembled":
            options += ["--mice", folder.name]
            paths = fifo_paths(folder.name)
            for path in paths.values():
                os.mkfifo(path)
            mice = dataclasses.replace(
                mice,
                xy=paths["xy"],
                xz=paths["xz"],
                grab=False,
                noise_counts=mice.noise_counts if mice.noise_counts is not None else 0.05,
            )
    try:
        process, pty_path = start_simulator(
            station.robot, seed=seed, speed_factor=speed_factor, ideal=ideal, options=tuple(options)
        )
    except BaseException:
        folder.cleanup()
        raise
    closers.append(lambda: end_process(process))
    calliper = station.calliper
    if calliper is not None and calliper.kind == "serial":
        calliper = CalliperSpec(kind="typed", resolution_mm=calliper.resolution_mm)
    simulated = dataclasses.replace(
        station,
        controller=dataclasses.replace(station.controller, port=pty_path),
        mice=mice,
        camera=camera,
        calliper=calliper,
        simulated=True,
        devices={
            **station.devices,
            "controller.port": pty_path,
            **({"camera.device": camera.device} if camera else {}),
        },
    )
    settings = {
        **({"ideal": True} if ideal else {}),
        **({"true_geometry_seed": int(true_geometry_seed)} if true_geometry_seed is not None else {}),
    }
    return Rehearsal(simulated, truth_path, closers, settings)
