"""A simulated PKM5 controller wired straight to a driver through a line that corrupts frames in both directions,
and the corrupted-frames drill of issue 31: moves and cross-thread stops through it, counting MOVEs the controller
executed twice and stops that were lost (``benchmarks/bench_pkm5_corrupted_frames.py``, tests/test_pkm5_noisy_link.py).

A corrupted frame is :func:`bench.robots.line_fuzz.corrupt` of the line without its terminator (bit flips or a
burst of up to 16 bits), each line independently with probability ``rate``.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from bench.errors import LinkError
from bench.robots import pkm5_kinematics as kinematics
from bench.robots.line_fuzz import corrupt
from bench.robots.pkm5 import ControllerError, Pkm5Controller
from bench.simulators.pkm5 import HOME_STEPS, Pkm5SimDevice
from motion import pkm5

__all__ = ["DrillResult", "NoisyDevicePort", "corrupted_frames_drill"]


class NoisyDevicePort:
    """A pyserial-like port whose other end is ``device`` (a :class:`Pkm5SimDevice`, fed in monotonic time); every
    line, either way, is corrupted with probability ``rate``. Thread-safe: a stop() thread may write while the
    waiting command reads."""

    def __init__(self, device: Pkm5SimDevice, rate: float, seed: int = 0, *, name: str = "noisy://") -> None:
        self.device, self.rate = device, rate
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._pending = b""
        self._readable = bytearray()
        self.port, self.baudrate, self.timeout, self.is_open = name, 115200, None, True
        self.corrupted = {"to_controller": 0, "to_host": 0}
        self.lines_written: list[bytes] = []

    def _maybe_corrupt(self, line: bytes, direction: str) -> bytes:
        if line and self._rng.random() < self.rate:
            self.corrupted[direction] += 1
            return corrupt(line, self._rng)
        return line

    def _emit(self, data: bytes) -> None:
        for line in data.split(b"\n")[:-1]:
            self._readable += self._maybe_corrupt(line, "to_host") + b"\n"

    def write(self, data: bytes) -> int:
        with self._lock:
            self._pending += bytes(data)
            *lines, self._pending = self._pending.split(b"\n")
            for line in lines:
                self.lines_written.append(line)
                self._emit(self.device.feed(self._maybe_corrupt(line, "to_controller") + b"\n", time.monotonic()))
        return len(data)

    def read(self, size: int = 1) -> bytes:
        with self._lock:
            self._emit(self.device.tick(time.monotonic()))
            chunk = bytes(self._readable[:size])
            del self._readable[:size]
        if not chunk:
            time.sleep(min(self.timeout or 0.0, 0.002))
        return chunk

    @property
    def in_waiting(self) -> int:
        return len(self._readable)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        with self._lock:
            self._readable.clear()

    def close(self) -> None:
        self.is_open = False


@dataclass
class DrillResult:
    moves: int
    completed: int  #: moves that reached their target
    stopped: int  #: moves ended by a stop() (ERR 8) or not re-sent after one
    failed: int  #: moves that raised anything else
    failures: list  #: their messages
    executed_twice: int  #: MOVEs the controller started more than once
    resent_moves: int  #: MOVE lines the driver sent more than once (the retransmissions the dedup answered)
    stops: int
    lost_stops: int  #: stop() raised, or the move still ran after stop() returned
    corrupted: dict


def corrupted_frames_drill(
    rate: float, moves: int, *, seed: int = 0, stop_every: int = 4, speed_factor: float = 2.0, retries: int = 5
) -> DrillResult:
    """``moves`` random moves (every ``stop_every``-th stopped from another thread mid-move) through a line
    corrupting ``rate`` of the frames each way; the simulated controller runs ``speed_factor`` times real speed."""
    device = Pkm5SimDevice(lambda steps, load_kg: np.zeros(5), speed_factor=speed_factor)
    port = NoisyDevicePort(device, rate, seed)
    robot = Pkm5Controller(port, reply_timeout_s=0.25, retries=retries, heartbeat_s=0.05)
    robot.identify()
    robot.enable()
    rng = np.random.default_rng(seed)
    lengths = pkm5.steps_to_lengths(np.asarray(HOME_STEPS)[None, :], pkm5.DEFAULT_GEOMETRY)
    home = np.asarray(kinematics.pose_deg_from_rad(pkm5.forward_kinematics(lengths, pkm5.DEFAULT_GEOMETRY).pose[0]))
    completed = stopped = failed = stops = lost = 0
    failures: list[str] = []
    for i in range(moves):
        target = robot.steps_for_pose(home + np.r_[rng.uniform(-2.0, 2.0, 3), 0.0, 0.0])
        stopper = None
        if i % stop_every == stop_every - 1:
            stops += 1
            outcome: list[bool] = []

            def stop_mid_move(outcome: list[bool] = outcome) -> None:
                time.sleep(float(rng.uniform(0.0, 0.1)))
                try:
                    robot.stop()
                except LinkError:
                    outcome.append(False)
                    return
                with port._lock:
                    outcome.append(device.move is None)

            stopper = threading.Thread(target=stop_mid_move)
            stopper.start()
        try:
            robot.move_steps(target, speed_steps_s=1000)
            completed += 1
        except (ControllerError, LinkError) as exc:
            if getattr(exc, "code", None) == 8 or "stop() was called" in str(exc):
                stopped += 1
            else:
                failed += 1
                failures.append(str(exc))
        if stopper is not None:
            stopper.join()
            lost += not all(outcome)
        robot.position()  # settles the link (a late ERR 8 / OK STOP is dropped as stale)
    moves_sent = [line for line in port.lines_written if b"MOVE " in line]
    return DrillResult(
        moves,
        completed,
        stopped,
        failed,
        failures,
        len(device.started_moves) - len(set(device.started_moves)),
        len(moves_sent) - len(set(moves_sent)),
        stops,
        lost,
        dict(port.corrupted),
    )
