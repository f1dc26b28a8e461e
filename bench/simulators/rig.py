"""Simulated rigs: a simulator process on a pseudo-terminal, the real driver over pyserial, simulated sensors.

The robot is the real :class:`bench.robots.pkm5.Pkm5Controller` talking to ``python -m bench.simulators.pkm5``
through the pty it prints, exactly as to hardware. The instrument is the dissertation's pair of optical mice
(one in the x-y plane, one in the x-z plane) simulated by :class:`bench.simulators.mouse.MouseSimulator`: after
each move the simulator's true attained pose (``SIMTRUE``) drives the simulated mice, which write kernel
``input_event`` records into FIFOs that :class:`bench.sensors.mouse.EvdevMouse` reads as it would read
``/dev/input``. Counts become mm through the stored calibration; the instrument's frame is registered once at the
robot's home. Prompts are answered by a scripted operator that also tells the simulator the payload, and calliper
readings come from the true pose with the calliper's noise and resolution.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import tempfile
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.errors import LinkError
from bench.rigs.gauges import CalliperOnly
from bench.rigs.interfaces import Measurement, Rig
from bench.rigs.mice import PATH, STREAMED_KINDS, MiceInstrument
from bench.rigs.movers import DeltaMover, Pkm5Mover
from bench.sensors.calibration import DEFAULT_CPI
from bench.simulators.calliper import depths_for_tilt
from bench.simulators.client import SimulatorClient
from bench.simulators.mice_feed import MOTION_S, PLANES, plane_seed
from bench.steps import Capture, Prompt

__all__ = [
    "BenchCalliper",
    "SimulatedCalliper",
    "end_process",
    "SimulatedMice",
    "SimulatedOperator",
    "simulated_rig",
    "start_simulator",
]

#: True samples taken of each streamed path segment, and the host's turnaround between two segments (s): [choice].
_PATH_TRACE_SAMPLES, _PATH_TURNAROUND_S = 40, 0.005
#: A segment starting farther than this from where the mice last were follows an unobserved move (mm).
_PATH_JUMP_MM = 0.5
#: Bytes written to a mouse FIFO before draining it (a pipe buffer holds 64 KiB).
_PIPE_CHUNK = 24 * 3 * 512


#: How a simulator's process starts: ``subprocess.Popen``'s signature and an object with its interface. The test
#: suite forks its simulators from a parent that has imported them (tests/zygote.py: the same program,
#: without 0.3 s of interpreter start and imports at each of its ~130 starts).
spawn: Callable[..., subprocess.Popen] = subprocess.Popen


def start_simulator(
    robot: str,
    *,
    seed: int,
    speed_factor: float,
    ideal: bool = False,
    timeout_s: float = 20.0,
    options: tuple[str, ...] = (),
) -> tuple[subprocess.Popen, str]:
    """Start ``python -m bench.simulators.<robot>`` (plus ``options``); returns the process and its pty path.

    ``timeout_s`` is for the start itself: a ``--kernel-wait-s W`` among the options (the simulator serves its port
    once its kernel is loaded) adds its W, so a loaded machine's kernel wait never eats into the start's limit."""
    if "--kernel-wait-s" in options:
        timeout_s += float(options[options.index("--kernel-wait-s") + 1])
    command = (
        [sys.executable, "-m", f"bench.simulators.{robot}", "--seed", str(seed), "--speed-factor", str(speed_factor)]
        + (["--ideal"] if ideal else [])
        + list(options)
    )
    # the simulator's log goes to a file: an undrained pipe would block the simulator once it filled up. Its own
    # session: a Ctrl-C at the terminal goes to the terminal's foreground process group, which must hold bench alone
    # (bench pauses; the simulator, the robot's stand-in, must not die under it: issue 31)
    with tempfile.TemporaryFile(mode="w+") as log:
        process = spawn(command, stdout=subprocess.PIPE, stderr=log, text=True, start_new_session=True)
        ready, _, _ = select.select([process.stdout], [], [], timeout_s)
        line = process.stdout.readline().strip() if ready else ""
        if not line.startswith("/dev/"):
            process.kill()
            process.wait(5)
            log.seek(0)
            error = log.read().strip().splitlines()
            raise LinkError(
                f"simulator {' '.join(command[1:3])}: no pty path within {timeout_s:g} s "
                f"({error[-1] if error else 'no output'})"
            )
    return process, line


class SimulatedMice(MiceInstrument):
    """Two simulated optical mice (x-y and x-z planes) observing the simulator's true pose, read through FIFOs.

    Each mouse is a :class:`bench.simulators.mouse.MouseStream` (quantisation with carry, white noise, a fixed
    report rate) followed through time on a simulated clock. For a static capture the robot's unobserved motion
    since the last capture is taken as a straight line over ``MOTION_S``; for an ``arrival`` capture the mice
    follow the simulator's sampled true arrival (``SIMTRACE``), so the stream shows the lag and the ringing.
    """

    def __init__(
        self,
        controller: Any,
        folder: str,
        *,
        seed: int,
        cpi: float = DEFAULT_CPI,
        noise_counts: float = 0.05,
        report_rate_hz: float = 500.0,
        trace_rate_hz: int = 250,
        calibration_id: str = "sim-mouse-800cpi",
        truth_log: str | None = None,
    ) -> None:
        from bench.sensors.calibration import CountsCalibration
        from bench.sensors.mouse import EvdevMouse
        from bench.simulators.mouse import MouseSimulator, MouseStream

        self.controller = controller
        self.truth = SimulatorClient(controller, truth_log)
        self.cpi, self.noise_counts, self.seed = cpi, noise_counts, seed
        self.report_rate_hz, self.trace_rate_hz = report_rate_hz, trace_rate_hz
        calibration = CountsCalibration.from_cpi(cpi, calibration_id=calibration_id, date="2026-01-01")
        self._writers, mice = {}, {}
        for plane in ("xy", "xz"):
            path = os.path.join(folder, f"mouse_{plane}.fifo")
            os.mkfifo(path)
            self._writers[plane] = os.open(path, os.O_RDWR)  # a writer first, so the reader's open returns
            mice[plane] = EvdevMouse(path, calibration, label=f"mouse_{plane}")
        registration = np.asarray(self.truth.true_pose(), dtype=float)[:3]
        super().__init__(mice, registration, calibration, noise_counts=noise_counts)
        self._clock_s = 0.0
        self._kind = ""
        self._last_xyz = registration.copy()
        self._streams = {
            plane: MouseStream(
                MouseSimulator(
                    cpi=cpi, noise_counts=noise_counts, report_rate_hz=report_rate_hz, seed=plane_seed(seed, index)
                ),
                origin_mm=registration[list(columns)],
            )
            for index, (plane, columns) in enumerate(PLANES.items())
        }

    def _follow(self, t_s: np.ndarray, true_xyz: np.ndarray) -> dict[str, Any]:
        """Feed the true motion (times on the simulated clock, positions (n, 3) mm) to both mice and read back
        their reports; the bytes go through the FIFOs in chunks a pipe buffer holds."""
        from bench.sensors.input_event import MotionFrames

        frames = {}
        for plane, columns in PLANES.items():
            data = self._streams[plane].input_events(t_s, true_xyz[:, list(columns)])
            parts = []
            for offset in range(0, len(data), _PIPE_CHUNK):
                os.write(self._writers[plane], data[offset : offset + _PIPE_CHUNK])
                parts.append(self.mice[plane].read_frames())
            frames[plane] = MotionFrames.concatenate(parts)
        self._clock_s = float(t_s[-1])
        self._last_xyz = np.asarray(true_xyz[-1], dtype=float)
        return frames

    def _stream(self, lead_s: float, hold_s: float) -> tuple[dict[str, Any], float]:
        rate_hz, gap_s = self.trace_rate_hz, MOTION_S
        if self._kind == PATH:
            # a path segment's move is straight in pose space in the simulator's dynamics, so some tens of true
            # samples per segment suffice (the mice still report at their own rate); the next segment follows the
            # last one after the host's turnaround (DONE -> capture -> MOVE), not after MOTION_S
            rate_hz = int(min(self.trace_rate_hz, max(1, np.ceil(_PATH_TRACE_SAMPLES / max(lead_s + hold_s, 1e-3)))))
            gap_s = _PATH_TURNAROUND_S
        times, poses = self.truth.trace(rate_hz, lead_s, hold_s)
        if self._kind == PATH and np.linalg.norm(poses[0, :3] - self._last_xyz) > _PATH_JUMP_MM:
            # moves between streamed segments (to the start, back along a line) reach the mice before the window,
            # over MOTION_S like any unobserved move (a long one takes the mice many reports); the lag and ringing
            # left at a segment's end (hundredths of a mm) are no such move
            self._follow(np.array([self._clock_s + MOTION_S]), poses[:1, :3])
        base = self._clock_s + gap_s - times[0]  # the unobserved motion up to the window's start takes gap_s
        return self._follow(base + times, poses[:, :3]), base

    def measure(self, capture: Capture) -> Measurement:
        self._kind = capture.kind
        true_pose = np.asarray(self.truth.true_pose(), dtype=float)
        if capture.kind not in STREAMED_KINDS:
            self._follow(np.array([self._clock_s + MOTION_S]), true_pose[None, :3])
        measured = super().measure(capture)
        return Measurement(measured.values, raw={**measured.raw, "true_pose": [round(float(v), 6) for v in true_pose]})

    def settings(self) -> dict[str, Any]:
        return {
            **super().settings(),
            "instrument": "two simulated optical mice (x-y, x-z) over FIFOs",
            "cpi": self.cpi,
            "noise_counts": self.noise_counts,
            "report_rate_hz": self.report_rate_hz,
        }

    def close(self) -> None:
        super().close()
        for writer in self._writers.values():
            os.close(writer)


class SimulatedOperator:
    """Confirms instructions (telling the simulator the payload) and answers readings with ``answer(prompt)``."""

    def __init__(self, controller: Any, answer: Callable[[Prompt], float] | None = None) -> None:
        self.controller = controller
        self.truth = SimulatorClient(controller)
        self.answer = answer

    def ask(self, prompt: Prompt) -> float | None:
        if "load_kg" in prompt.conditions:
            self.truth.set_load(float(prompt.conditions["load_kg"]))
        if prompt.field is None:
            return None
        if self.answer is None:
            raise LinkError(f"simulated operator: no answer for {prompt.field} ({prompt.text})")
        return self.answer(prompt)


class SimulatedCalliper:
    """Answers calliper prompts from the simulator's truth, with reading noise and 0.01 resolution: tilts (``a_deg``,
    ``b_deg``) from the true pose (``SIMTRUE``), leg lengths (``length_mm`` of leg ``conditions['leg']``) from the
    true, perturbed leg lengths (``SIMLEGS``), so a leg reading shows the actuator's own error (offset, scale,
    backlash, load compression) as well as the calliper's scatter."""

    def __init__(
        self, controller: Any, *, seed: int, length_sigma_mm: float = 0.02, tilt_sigma_deg: float = 0.1
    ) -> None:
        self.controller = controller
        self.truth = SimulatorClient(controller)
        self.rng = np.random.default_rng(seed + 7919)
        self.length_sigma_mm, self.tilt_sigma_deg = length_sigma_mm, tilt_sigma_deg
        self.depth_centre_mm = 30.0  #: depth from the bracket to the mirror's centre (mm)

    def __call__(self, prompt: Prompt) -> float:
        if prompt.field in ("a_deg", "b_deg"):
            angle = np.asarray(self.truth.true_pose(), dtype=float)[3 if prompt.field == "a_deg" else 4]
            return round(float(angle + self.rng.normal(0.0, self.tilt_sigma_deg)), 2)
        if prompt.field in ("depth1_mm", "depth2_mm") and "hole_spacing_mm" in prompt.conditions:
            # the two depths over the mirror tilted by the true angle the prompt asks about (cmd_a_deg/cmd_b_deg)
            axis = 3 if any(k.startswith("cmd_a") for k in prompt.commanded) else 4
            angle = float(np.asarray(self.truth.true_pose(), dtype=float)[axis])
            depths = depths_for_tilt(angle, float(prompt.conditions["hole_spacing_mm"]), self.depth_centre_mm)
            depth = float(depths[0 if prompt.field == "depth1_mm" else 1])
            return round(depth + float(self.rng.normal(0.0, self.length_sigma_mm)), 2)
        if prompt.field == "length_mm" and "leg" in prompt.conditions:
            length = self.truth.true_lengths()[int(prompt.conditions["leg"]) - 1]
            return round(float(length + self.rng.normal(0.0, self.length_sigma_mm)), 2)
        raise LinkError(f"simulated calliper: cannot answer {prompt.field!r} ({prompt.text})")


class BenchCalliper:
    """The simulated depth gauge of the actuator bench (000 §8.4): zeroed on an actuator when the operator confirms
    a prompt with ``conditions['zero_actuator']``, it reads ``travel_mm`` = the simulator's true stroke of that
    actuator minus the stroke at zeroing, plus reading noise, at 0.01 mm resolution."""

    def __init__(self, controller: Any, *, seed: int, sigma_mm: float = 0.01) -> None:
        self.controller = controller
        self.truth = SimulatorClient(controller)
        self.rng = np.random.default_rng(seed + 7919)
        self.sigma_mm = sigma_mm
        self.zero_mm: dict[int, float] = {}

    def ask(self, prompt: Prompt) -> float | None:
        if prompt.field is None:
            if "zero_actuator" in prompt.conditions:
                axis = int(prompt.conditions["zero_actuator"])
                self.zero_mm[axis] = float(self.truth.true_strokes()[axis - 1])
            return None
        axis = int(prompt.conditions.get("actuator", 0))
        if prompt.field != "travel_mm" or axis not in self.zero_mm:
            raise LinkError(
                f"simulated depth gauge: cannot answer {prompt.field!r} ({prompt.text}): not zeroed on actuator {axis}"
            )
        travel = self.truth.true_strokes()[axis - 1] - self.zero_mm[axis]
        return round(float(travel + self.rng.normal(0.0, self.sigma_mm)), 2)


def simulated_rig(
    robot: str = "pkm5",
    *,
    seed: int = 0,
    speed_factor: float = 1000.0,
    ideal: bool = False,
    answer: Callable[[Prompt], float] | None = None,
    fixture: str = "assembled",
    options: tuple[str, ...] = (),
) -> Rig:
    """A rig on a freshly started simulator (close it with ``rig.close()``); ``fixture="actuator-bench"``: the
    pkm5's actuators free-standing, moved one at a time and read by a simulated depth gauge. ``options`` go to the
    assembled robot's simulator command line (e.g. ``("--mode-hz", "1.0")``, ``("--true-geometry-seed", "3")``)."""
    import serial

    from bench.robots.pkm5 import Pkm5Controller

    if fixture == "actuator-bench":
        return _simulated_actuator_bench(robot, seed=seed, speed_factor=speed_factor, ideal=ideal)
    if fixture != "assembled":
        raise LinkError(f"fixture = {fixture!r}, expected 'assembled' or 'actuator-bench'")
    if robot == "delta4":
        return _simulated_delta_rig(seed=seed, speed_factor=speed_factor, ideal=ideal, options=options)
    if robot != "pkm5":
        raise LinkError(f"--robot {robot}: no simulated rig for this robot, expected pkm5 or delta4")
    folder = tempfile.TemporaryDirectory(prefix="bench-sim-")
    # the mice read the true pose after each move from the truth log, not by a SIMTRUE round trip (SimulatorClient)
    truth_log = os.path.join(folder.name, "truth.jsonl")
    try:
        process, path = start_simulator(
            robot, seed=seed, speed_factor=speed_factor, ideal=ideal, options=("--truth", truth_log) + tuple(options)
        )
    except BaseException:
        folder.cleanup()
        raise
    closers: list[Callable[[], None]] = [folder.cleanup, lambda: end_process(process)]
    try:
        controller = Pkm5Controller(serial.serial_for_url(path, baudrate=115200, timeout=0.05))
        controller.identify()
        controller.enable()
        mice = SimulatedMice(controller, folder.name, seed=seed, truth_log=truth_log)
    except BaseException:
        for close in reversed(closers):
            close()
        raise
    closers.append(mice.close)
    operator = SimulatedOperator(controller, answer or SimulatedCalliper(controller, seed=seed))
    return Rig(Pkm5Mover(controller), mice, operator, speed_factor=speed_factor, closers=closers)


def _simulated_actuator_bench(robot: str, *, seed: int, speed_factor: float, ideal: bool) -> Rig:
    """The pkm5 simulator with free-standing actuators, the driver opened on the bench, a simulated depth gauge."""
    import serial

    from bench.robots.pkm5 import Pkm5Controller

    if robot != "pkm5":
        raise LinkError(f"--robot {robot}: the actuator bench exists for the pkm5 only")
    process, path = start_simulator(
        robot, seed=seed, speed_factor=speed_factor, ideal=ideal, options=("--fixture", "actuator-bench")
    )
    try:
        controller = Pkm5Controller(
            serial.serial_for_url(path, baudrate=115200, timeout=0.05), fixture="actuator-bench"
        )
        controller.identify()
        controller.enable()
    except BaseException:
        end_process(process)
        raise
    return Rig(
        Pkm5Mover(controller),
        CalliperOnly(),
        BenchCalliper(controller, seed=seed),
        speed_factor=speed_factor,
        closers=[lambda: end_process(process)],
    )


def end_process(process: subprocess.Popen) -> None:
    """Stop a simulator: SIGTERM (it closes its pty), then SIGKILL if it has not ended within 10 s (a loaded
    machine)."""
    process.terminate()
    try:
        process.wait(10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(10)


def _simulated_delta_rig(*, seed: int, speed_factor: float, ideal: bool, options: tuple[str, ...] = ()) -> Rig:
    """The delta4 simulator (laser-grid simulator attached) with the real driver; the laser grid is read from the
    controller's reports, and the truth log's attained pose goes into each sample's raw data for comparison."""
    import serial

    from bench.rigs.lasergrid import LaserGridInstrument
    from bench.robots.delta4 import Delta4Controller
    from bench.simulators.pty import read_last_truth

    folder = tempfile.TemporaryDirectory(prefix="bench-sim-delta4-")
    truth_path = os.path.join(folder.name, "truth.jsonl")
    try:
        process, path = start_simulator(
            "delta4",
            seed=seed,
            speed_factor=speed_factor,
            ideal=ideal,
            options=("--truth", truth_path) + tuple(options),
        )
    except BaseException:
        folder.cleanup()
        raise
    closers: list[Callable[[], None]] = [folder.cleanup, lambda: end_process(process)]
    try:
        controller = Delta4Controller(serial.serial_for_url(path, baudrate=9600, timeout=0.05))
        controller.start()
        controller.probe_fine_references()
    except BaseException:
        for close in reversed(closers):
            close()
        raise

    def true_position() -> list[float]:
        entry = read_last_truth(truth_path)
        if entry is None:
            raise LinkError(f"delta4 simulator: no attained pose in its truth log {truth_path} yet")
        return entry["pose"]

    instrument = LaserGridInstrument(controller, truth=true_position)
    return Rig(
        DeltaMover(controller), instrument, SimulatedOperator(controller), speed_factor=speed_factor, closers=closers
    )
