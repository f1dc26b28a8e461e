"""Simulated PKM5 controller: ``python -m bench.simulators.pkm5`` (or ``bench sim pkm5``).

Implements the firmware's behaviour (``docs/protocol-pkm5.md``) on a pseudo-terminal, plus the simulator-only
commands ``SIMTRUE``, ``SIMLOAD``, ``SIMLEGS`` and ``SIMTRACE``.
With ``--fixture actuator-bench`` the six actuators stand free (000 §8.4): any step target inside the firmware
limits is a valid move, and ``SIMTRUE`` reports the six true strokes (mm) instead of a pose. Moves run at constant speed with all axes arriving together (MultiStepper),
in simulated time scaled by ``--speed-factor``. When a move ends, the plant (:class:`Pkm5Plant`) turns the reached
steps into the true attained pose through the seeded error model and the kinematics of :mod:`motion.pkm5`:
steps -> leg lengths -> perturbed lengths -> forward kinematics -> pose errors. The pose goes to ``SIMTRUE`` and
to the truth log (see :mod:`bench.simulators.pty`). How the end effector arrived there (lag during the move,
ringing after it) follows the structural mode of :mod:`bench.simulators.dynamics` (``--mode-hz``, ``--damping``);
``SIMTRACE`` samples that arrival, in simulated seconds, for the simulated sensors that stream.
"""

from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.rigs.mice_liveness import XZ_MOUNTS, XZ_PLATFORM
from bench.robots import pkm5_wire as wire
from bench.simulators.dynamics import StructuralMode, trace_times
from bench.simulators.pty import TruthLog, add_common_arguments, main_for

__all__ = [
    "DESCRIPTION",
    "FIRMWARE_VERSION",
    "HOME_STEPS",
    "MAX_STEPS",
    "Pkm5SimDevice",
    "add_arguments",
    "build_device",
    "main",
]

_log = logging.getLogger(__name__)

DESCRIPTION = "Simulated 5-DOF PKM controller on a pseudo-terminal (prints the device path)."
FIRMWARE_VERSION = "1.0.0-sim"
#: Step limits of the firmware (0 = full retraction; 66 mm stroke at 0.00625 / 0.003125 mm/step).
MAX_STEPS = (10560, 10560, 10560, 10560, 21120, 21120)
#: Position assumed at power-up: the documents' home, 5 mm stroke on every actuator.
HOME_STEPS = (800, 800, 800, 800, 1600, 1600)
MAX_SPEED_STEPS_S = 1000
_IDLE_ONLY = frozenset({"MOVE", "SETPOS", "ENABLE", "DISABLE"})


@dataclass
class _Move:
    tag: int
    start: np.ndarray
    target: np.ndarray
    t_start_s: float
    duration_s: float  # wall time; the move lasts duration_s x speed factor in simulated time

    def at(self, now_s: float) -> np.ndarray:
        fraction = 1.0 if self.duration_s <= 0 else min(1.0, (now_s - self.t_start_s) / self.duration_s)
        return np.rint(self.start + fraction * (self.target - self.start)).astype(np.int64)


def duration_ms(steps: int, speed_steps_s: int) -> int:
    """Announced duration of a constant-speed move, ms: 1000 n / v rounded half up, in integers as the firmware."""
    return (1000 * steps + speed_steps_s // 2) // speed_steps_s


class Pkm5SimDevice:
    """The firmware state machine; ``plant(steps, load_kg) -> pose`` supplies the true pose after each move."""

    def __init__(
        self,
        plant: Any,
        *,
        speed_factor: float = 1.0,
        truth: TruthLog | None = None,
        load_kg: float = 0.0,
        mode: StructuralMode | None = None,
        sim_verbs: bool = True,
        observers: tuple[Any, ...] = (),
        kernel_wait_s: float = 0.0,
    ) -> None:
        self.plant = plant
        #: how long :meth:`ready` waits for the plant's deferred start-up work (its compiled kernel), s
        self.kernel_wait_s = kernel_wait_s
        #: False (``--hardware-only``): the SIM verbs are unknown, as to the real firmware (ERR SYNTAX)
        self.sim_verbs = sim_verbs
        #: told ``rest(true_pose, motion_s)`` each time the robot comes to rest after moving ``motion_s`` simulated
        #: seconds, before DONE is sent (``--mice``)
        self.observers = observers
        self.mode = mode or StructuralMode()
        self.speed_factor = speed_factor
        self.truth = truth or TruthLog(None, ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"))
        self.load_kg = load_kg
        self.steps = np.array(HOME_STEPS, dtype=np.int64)
        self.enabled = False
        self.move: _Move | None = None
        self.true_pose = np.asarray(plant(self.steps, load_kg), dtype=float)
        #: the last arrival: (true pose before, true pose after, duration in simulated s); at rest after power-up
        self.arrival = (self.true_pose, self.true_pose, 0.0)
        self._trace: tuple[tuple[int, int, int], np.ndarray] | None = None
        self._unprepared: np.ndarray | None = None  # the accepted move's target, until the plant has prepared it
        self._line = bytearray()
        self._overflow = False
        self._booted = False
        self.protocol = 1  # framing of the link: 1 = XOR-8, 2 = CRC-16 after PROTOCOL 2 (until reset), 3 = + dedup
        #: version 3: the last accepted MOVE's tag, its OK and (once it ended) its end reply, for a retransmission
        self._last_move: tuple[int, bytes, bytes] = (-1, b"", b"")
        self.started_moves: list[int] = []  #: tags of the MOVEs started (a retransmission answered is not one)

    # -- bytes in, bytes out -----------------------------------------------------------------------------------
    def feed(self, data: bytes, now_s: float) -> bytes:
        out = bytearray(self.tick(now_s))
        *lines, rest = data.split(b"\n")  # line by line, not byte by byte (a third of a SIMTRACE exchange's time)
        for part in lines:
            self._receive(part)
            out += self._end_line(now_s)
        self._receive(rest)
        return bytes(out)

    def _receive(self, part: bytes) -> None:
        """Bytes of the line being received: kept up to MAX_LINE, as the firmware's buffer; one more marks the line
        too long."""
        room = wire.MAX_LINE - len(self._line)
        if len(part) > room:
            self._overflow = True
        self._line += part[:room]

    def _end_line(self, now_s: float) -> bytes:
        line, overflow = bytes(self._line), self._overflow
        self._line.clear()
        self._overflow = False
        if overflow:
            return _reframe(_error(0, wire.ErrorCode.TOO_LONG), self.protocol)
        if line in (b"", b"\r"):
            return b""
        version = self.protocol  # a PROTOCOL command is answered in the framing it arrived in
        try:
            command = wire.parse_command(line, version)
        except wire.CommandRefused as exc:  # the code and the tag follow the firmware's rules (pkm5_wire)
            _log.info("refused %r: %s", line, exc)  # version 2 is kept until reset: no line downgrades it
            return _reframe(_error(exc.tag, exc.code), version)
        return _reframe(self._execute(command, now_s), version)

    def tick(self, now_s: float) -> bytes:
        return _reframe(self._tick(now_s), self.protocol)

    def _tick(self, now_s: float) -> bytes:
        out = b""
        if not self._booted:
            self._booted = True
            out += wire.format_reply("BOOT", 0, wire.DEVICE_NAME, max(wire.PROTOCOL_VERSIONS), FIRMWARE_VERSION)
        if self.move is not None and now_s >= self.move.t_start_s + self.move.duration_s:
            move, self.move = self.move, None
            self.steps = move.target.copy()
            self._settle(move.duration_s * self.speed_factor)
            out += self._ended(move.tag, wire.format_reply("DONE", move.tag, *self.steps))
        return out

    def _ended(self, tag: int, reply: bytes) -> bytes:
        """``reply`` ends move ``tag``: kept for a version-3 retransmission of its MOVE."""
        if self._last_move[0] == tag:
            self._last_move = (tag, self._last_move[1], reply)
        return reply

    def next_due_s(self) -> float | None:
        """When the running move ends (monotonic s), so the event loop wakes for its ``DONE`` on time."""
        return None if self.move is None else self.move.t_start_s + self.move.duration_s

    def ready(self) -> None:
        """Called once built, before the port is served: the plant's deferred start-up work begins (its compiled
        kernel loads on a thread), waited for up to :attr:`kernel_wait_s`."""
        warm_up = getattr(self.plant, "warm_up", None)
        if warm_up is not None:
            warm_up(self.kernel_wait_s)

    def idle(self, now_s: float) -> None:
        """Work the event loop runs once this turn's replies are sent: the true pose at the end of an accepted move
        is computed during the move (:meth:`Plant.prepare`), so the ``DONE`` reply never waits for the kinematics."""
        target, self._unprepared = self._unprepared, None
        prepare = getattr(self.plant, "prepare", None)
        if target is not None and prepare is not None and self.move is not None:
            prepare(target, self.load_kg)

    # -- commands ----------------------------------------------------------------------------------------------
    def _execute(self, command: wire.Command, now_s: float) -> bytes:
        verb, args, tag = command.verb, command.args, command.tag
        if verb == "MOVE" and self.protocol >= 3 and tag == self._last_move[0]:  # a retransmission: not again
            return self._last_move[1] + self._last_move[2]
        if verb in _IDLE_ONLY and self.move is not None:
            return _error(tag, wire.ErrorCode.BUSY)
        if verb == "ID":
            return wire.format_reply("OK", tag, "ID", wire.DEVICE_NAME, max(wire.PROTOCOL_VERSIONS), FIRMWARE_VERSION)
        if verb == "PROTOCOL":
            if args[0] not in wire.PROTOCOL_VERSIONS or args[0] < self.protocol:  # never back to XOR-8
                return _error(tag, wire.ErrorCode.ARGUMENT)
            self.protocol = args[0]
            return wire.format_reply("OK", tag, "PROTOCOL", args[0])
        if verb == "POS":
            state = "MOVING" if self.move else "IDLE" if self.enabled else "DISABLED"
            return wire.format_reply("OK", tag, "POS", *self._current(now_s), state)
        if verb == "STOP":
            return self._stop(tag, now_s)
        if verb in ("ENABLE", "DISABLE"):
            self.enabled = verb == "ENABLE"
            return wire.format_reply("OK", tag, verb)
        if verb == "SETPOS":
            return self._setpos(tag, args)
        if verb == "MOVE":
            return self._start_move(tag, args, now_s)
        if verb.startswith("SIM") and not self.sim_verbs:
            _log.error("SIM verb %s refused (--hardware-only)", verb)
            return _error(tag, wire.ErrorCode.SYNTAX)
        if verb == "SIMLOAD":
            if not 0 <= args[0] <= 30000:
                return _error(tag, wire.ErrorCode.ARGUMENT)
            self.load_kg = args[0] / 1000.0
            return wire.format_reply("OK", tag, "SIMLOAD")
        if verb == "SIMTRUE":
            return wire.format_reply("OK", tag, "SIMTRUE", *(f"{v:.4f}" for v in self.true_pose))
        if verb == "SIMLEGS":
            lengths = getattr(self.plant, "true_joints", None)
            if lengths is None:  # the actuator bench has no legs: SIMTRUE gives its strokes
                return _error(tag, wire.ErrorCode.ARGUMENT)
            return wire.format_reply("OK", tag, "SIMLEGS", *(f"{v:.4f}" for v in lengths))
        if verb == "SIMTRACE":
            return self._trace_sample(tag, args)
        return _error(tag, wire.ErrorCode.SYNTAX)

    def _trace_sample(self, tag: int, args: tuple[int, ...]) -> bytes:
        """``SIMTRACE rate_hz lead_ms hold_ms index``: sample ``index`` of the last arrival sampled at ``rate_hz``
        from ``lead_ms`` before the move ended to ``hold_ms`` after; one sample per reply keeps lines short."""
        rate_hz, lead_ms, hold_ms, index = args
        if not (1 <= rate_hz <= 10_000 and 0 <= lead_ms <= 60_000 and 0 <= hold_ms <= 60_000):
            return _error(tag, wire.ErrorCode.ARGUMENT)
        key = (rate_hz, lead_ms, hold_ms)
        if self._trace is None or self._trace[0] != key:
            start, end, duration_s = self.arrival
            times = trace_times(rate_hz, lead_ms / 1000.0, hold_ms / 1000.0)
            self._trace = key, self.mode.arrival(times, start, end, duration_s)
        samples = self._trace[1]
        if not 0 <= index < len(samples):
            return _error(tag, wire.ErrorCode.ARGUMENT)
        return wire.format_reply("OK", tag, "SIMTRACE", len(samples), index, *(f"{v:.4f}" for v in samples[index]))

    def _current(self, now_s: float) -> np.ndarray:
        return self.move.at(now_s) if self.move is not None else self.steps

    def _setpos(self, tag: int, args: tuple[int, ...]) -> bytes:
        if not _within_limits(args):
            return _error(tag, wire.ErrorCode.LIMIT)
        self.steps = np.array(args, dtype=np.int64)
        self._settle()
        return wire.format_reply("OK", tag, "SETPOS")

    def _start_move(self, tag: int, args: tuple[int, ...], now_s: float) -> bytes:
        targets, speed = args[: wire.AXES], args[wire.AXES]
        if not 1 <= speed <= MAX_SPEED_STEPS_S:
            return _error(tag, wire.ErrorCode.ARGUMENT)
        if not _within_limits(targets):
            return _error(tag, wire.ErrorCode.LIMIT)
        if not self.enabled:
            return _error(tag, wire.ErrorCode.DISABLED)
        target = np.array(targets, dtype=np.int64)
        duration_s = float(np.max(np.abs(target - self.steps))) / speed
        self.move = _Move(tag, self.steps.copy(), target, now_s, duration_s / self.speed_factor)
        self._unprepared = target
        ok = wire.format_reply(
            "OK", tag, "MOVE", round(duration_ms(int(np.max(np.abs(target - self.steps))), speed) / self.speed_factor)
        )
        self._last_move = (tag, ok, b"")
        self.started_moves.append(tag)
        return ok

    def _stop(self, tag: int, now_s: float) -> bytes:
        out = b""
        if self.move is not None:
            self.steps = self.move.at(now_s)
            ran_s = min(self.move.duration_s, now_s - self.move.t_start_s) * self.speed_factor
            out += self._ended(self.move.tag, _error(self.move.tag, wire.ErrorCode.STOPPED, *self.steps))
            self.move = None
            self._settle(ran_s)
        return out + wire.format_reply("OK", tag, "STOP", *self.steps)

    def _settle(self, duration_s: float = 0.0) -> None:
        before = self.true_pose
        self.true_pose = np.asarray(self.plant(self.steps, self.load_kg), dtype=float)
        self.arrival, self._trace = (before, self.true_pose, duration_s), None
        self.truth.record(list(self.steps), list(self.true_pose), self.load_kg)
        for observer in self.observers:
            observer.rest(self.true_pose, duration_s)


def _within_limits(steps: tuple[int, ...]) -> bool:
    return all(0 <= s <= high for s, high in zip(steps, MAX_STEPS))


def _reframe(data: bytes, version: int) -> bytes:
    """Version-1 reply lines re-framed for ``version`` (the replies are built once, in version 1)."""
    if version == 1 or not data:
        return data
    return b"".join(wire.encode_line(wire.decode_line(line), version) for line in data.splitlines())


def _error(tag: int, code: wire.ErrorCode, *fields: object) -> bytes:
    return wire.format_reply("ERR", tag, int(code), code.name, *fields)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench sim pkm5`` / ``python -m bench.simulators.pkm5``."""
    add_common_arguments(parser)
    parser.add_argument(
        "--fixture",
        choices=("assembled", "actuator-bench"),
        default="assembled",
        help="the assembled robot (SIMTRUE: the pose) or the six actuators free-standing on the "
        "bench, 000 §8.4 (SIMTRUE: the six true strokes, mm)",
    )
    parser.add_argument(
        "--mice",
        default=None,
        metavar="DIR",
        help="two simulated optical mice watching the robot, read as event devices from "
        "DIR/mouse_xy.fifo and DIR/mouse_xz.fifo (assembled robot)",
    )
    parser.add_argument(
        "--mice-xz-mount",
        choices=XZ_MOUNTS,
        default=XZ_PLATFORM,
        help="the simulated x-z mouse rides the platform (sees x and z) or runs on vertical guides pushed by the "
        "end effector (sees z only, the dissertation's Z mouse); a station's [mice] xz_mount",
    )
    parser.add_argument(
        "--hardware-only",
        action="store_true",
        help="answer the SIM verbs as the real firmware does (unknown verb): proves a rig built "
        "for hardware never asks the simulator for its truth",
    )
    parser.add_argument(
        "--mode-hz",
        type=float,
        default=StructuralMode.frequency_hz,
        help="natural frequency of the structural mode that rings after each move, Hz "
        "(default %(default)s; a choice, no document measures it)",
    )
    parser.add_argument(
        "--damping",
        type=float,
        default=StructuralMode.damping_ratio,
        help="damping ratio of that mode, 0-1 (default %(default)s)",
    )
    parser.add_argument(
        "--kernel-wait-s",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="wait up to this long for the compiled FK kernel (numba) before serving the pty, so "
        "the first moves run at speed (bench demo); 0: serve at once, the kernel loads behind the port "
        "once numpy has solved 200 moves (a short session never loads it)",
    )
    parser.add_argument(
        "--true-geometry-seed",
        type=int,
        default=None,
        metavar="SEED",
        help="move by a seeded perturbed geometry (bench.simulators.true_geometry) instead of the "
        "error model's geometric stand-ins",
    )


def build_device(args: argparse.Namespace) -> Pkm5SimDevice:
    """The simulated controller described by the command-line ``args``."""
    from bench.robots.pkm5_kinematics import ACTUATOR_BENCH
    from bench.simulators.pkm5_plant import build_actuator_bench, build_plant

    kernel_wait_s = getattr(args, "kernel_wait_s", 0.0)
    if not 0 <= kernel_wait_s < float("inf"):  # (NaN fails too) a thread's join refuses inf with a traceback
        raise ConfigError(f"--kernel-wait-s = {kernel_wait_s}, expected a finite number of seconds >= 0")
    try:
        mode = StructuralMode(
            getattr(args, "mode_hz", StructuralMode.frequency_hz),
            getattr(args, "damping", StructuralMode.damping_ratio),
        )
    except ValueError as exc:
        raise ConfigError(f"--mode-hz/--damping: {exc}") from None
    if getattr(args, "fixture", "assembled") == ACTUATOR_BENCH:
        plant = build_actuator_bench(args.seed, ideal=args.ideal)
        truth = TruthLog(args.truth, tuple(f"stroke{axis}_mm" for axis in range(1, wire.AXES + 1)))
        return Pkm5SimDevice(
            plant,
            speed_factor=args.speed_factor,
            truth=truth,
            mode=mode,
            sim_verbs=not getattr(args, "hardware_only", False),
        )
    true_seed = getattr(args, "true_geometry_seed", None)
    if true_seed is None:
        plant = build_plant(args.seed, ideal=args.ideal)
    else:
        from bench.simulators.true_geometry import true_geometry

        plant = build_plant(args.seed, ideal=args.ideal, true_geometry=true_geometry(true_seed))
    truth = TruthLog(args.truth, ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"))
    observers: tuple[Any, ...] = ()
    if getattr(args, "mice", None):
        from bench.simulators.mice_feed import MiceFeed

        start = plant(np.array(HOME_STEPS), args.load_kg)
        mount = getattr(args, "mice_xz_mount", XZ_PLATFORM)
        observers = (MiceFeed(args.mice, start, seed=args.seed, xz_mount=mount, speed_factor=args.speed_factor),)
    return Pkm5SimDevice(
        plant,
        speed_factor=args.speed_factor,
        truth=truth,
        load_kg=args.load_kg,
        mode=mode,
        sim_verbs=not getattr(args, "hardware_only", False),
        observers=observers,
        kernel_wait_s=kernel_wait_s,
    )


def main(argv: list[str] | None = None) -> int:
    return main_for(build_device, add_arguments, DESCRIPTION, argv)


if __name__ == "__main__":
    sys.exit(main())
