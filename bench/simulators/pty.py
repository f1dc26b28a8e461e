"""Process scaffolding of the simulated controllers: a pseudo-terminal, an event loop, and the truth log.

A simulator is a real program (``python -m bench.simulators.pkm5`` / ``bench.simulators.delta4``, or ``bench sim ...``). It opens a
pty with ``os.openpty``, prints the slave device path as the first line of stdout (then the truth-log path, if
any), and serves bytes on the master side until SIGTERM/SIGINT or until its parent process exits. Clients open the
printed path with pyserial exactly as they would open hardware.

The truth log is the simulator-only side channel for sensor simulators: one JSON object per line, appended and
flushed after every completed or stopped move: ``{"seq", "t_monotonic_s", "t_wall_s", "commanded", "pose",
"pose_fields", "load_kg"}``. :func:`read_last_truth` returns the newest entry. Real controllers have no such log.
"""

from __future__ import annotations

import argparse
import json
import os
import select
import signal
import sys
import time
import tty
from pathlib import Path
from typing import Any, Protocol

from bench.errors import BenchError, ConfigError

__all__ = ["SimDevice", "TruthLog", "add_common_arguments", "main_for", "read_last_truth", "run_simulator", "serve"]

_TICK_S = 0.002
#: Longest sleep of a device that says when its next completion is due (``next_due_s``) while none is: it wakes on
#: the port's input and at the due time anyway; this bounds how late it sees its parent gone. Polling every _TICK_S
#: instead cost the pkm5 simulator ~0.1 ms of CPU per wake-up, a CPU the host's campaign shares.
_IDLE_WAIT_S = 0.05


class SimDevice(Protocol):
    """What the event loop needs from a simulated controller."""

    def feed(self, data: bytes, now_s: float) -> bytes:
        """Consume bytes from the PC; return bytes to send back."""

    def tick(self, now_s: float) -> bytes:
        """Advance simulated time to ``now_s`` (monotonic); return bytes to send (completions, reports)."""

    # optional: ``idle(now_s) -> None``, run after each turn's replies are sent (work a reply need not wait for),
    # ``next_due_s() -> float | None``, when the next completion is due (the loop then wakes on time for it), and
    # ``ready() -> None``, run once before the port is served (deferred start-up work)


class TruthLog:
    """Appends the true attained pose after each move to a JSON-lines file (simulator-only side channel)."""

    def __init__(self, path: str | os.PathLike[str] | None, pose_fields: tuple[str, ...]) -> None:
        self.path = None if path is None else Path(path)
        self.pose_fields = pose_fields
        self._seq = 0
        # kept open (each entry flushed whole before the reply it belongs to is sent): an open and a close per
        # move were a quarter of the record's cost, on the way to every DONE
        self._handle = None if self.path is None else self.path.open("w", encoding="utf-8")

    def record(self, commanded: list[float], pose: list[float], load_kg: float) -> dict[str, Any]:
        self._seq += 1
        entry = {
            "seq": self._seq,
            "t_monotonic_s": time.monotonic(),
            "t_wall_s": time.time(),
            "commanded": [float(c) for c in commanded],
            "pose": [float(p) for p in pose],
            "pose_fields": list(self.pose_fields),
            "load_kg": float(load_kg),
        }
        if self._handle is not None:
            self._handle.write(json.dumps(entry) + "\n")
            self._handle.flush()
        return entry


#: Bytes read from the end of a truth log for its newest entry (an entry is ~300 bytes); the whole file if they
#: hold no complete one. A run reads the log after every move, and the whole file grows with the run.
_TRUTH_TAIL_BYTES = 4096


def read_last_truth(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The newest complete entry of a truth log, or ``None`` if no move has finished yet."""
    with open(path, "rb") as handle:
        size = handle.seek(0, os.SEEK_END)
        for start in dict.fromkeys((max(0, size - _TRUTH_TAIL_BYTES), 0)):
            handle.seek(start)
            lines = handle.read().splitlines()
            if start > 0:
                lines = lines[1:]  # the first line of a tail may be cut
            for line in reversed(lines):
                try:
                    return json.loads(line)
                except json.JSONDecodeError:  # a line being written right now
                    continue
    return None


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0, help="seed of the robot's error model and noise")
    parser.add_argument("--ideal", action="store_true", help="no error model: attain exactly what is commanded")
    parser.add_argument(
        "--speed-factor", type=float, default=1.0, help="simulated time runs this many times faster than real moves"
    )
    parser.add_argument("--load-kg", type=float, default=0.0, help="payload on the end effector, kg")
    parser.add_argument("--truth", default=None, help="append the true attained pose after each move to this file")
    parser.add_argument("--reply-delay-s", type=float, default=0.0, help="fault: delay every reply by this, s")
    parser.add_argument(
        "--garbage-every-s",
        type=float,
        default=0.0,
        help="fault: send a burst of random bytes this often, s (0: never)",
    )


def _open_pty() -> tuple[int, int, str]:
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)  # with no client reading, a full pty buffer must not freeze the simulator
    return master, slave, os.ttyname(slave)


def _send(master: int, data: bytes) -> None:
    try:
        os.write(master, data)
    except BlockingIOError:  # nobody reads: like a real UART, output is lost
        pass


class _Faults:
    def __init__(self, args: argparse.Namespace) -> None:
        self.delay_s = max(0.0, args.reply_delay_s)
        self.garbage_every_s = max(0.0, args.garbage_every_s)
        self._rng_state = (args.seed * 2654435761 + 1) & 0xFFFFFFFF
        self._next_garbage = time.monotonic() + self.garbage_every_s
        self.outbox: list[tuple[float, bytes]] = []

    @property
    def active(self) -> bool:
        """Any fault that needs the event loop to wake on a clock of its own (delayed replies, noise bursts)."""
        return self.delay_s > 0 or self.garbage_every_s > 0

    def garbage(self, now_s: float) -> bytes:
        if not self.garbage_every_s or now_s < self._next_garbage:
            return b""
        self._next_garbage = now_s + self.garbage_every_s
        out = bytearray()
        for _ in range(8):  # xorshift: deterministic noise without touching the error model's streams
            self._rng_state ^= (self._rng_state << 13) & 0xFFFFFFFF
            self._rng_state ^= self._rng_state >> 17
            self._rng_state ^= (self._rng_state << 5) & 0xFFFFFFFF
            out.append(self._rng_state & 0xFF)
        return bytes(out).replace(b"\n", b"~")


def serve(device: SimDevice, args: argparse.Namespace) -> int:
    """Run ``device`` on a new pty until SIGTERM/SIGINT or until the parent process exits."""
    stopping = []
    for signum in (signal.SIGTERM, signal.SIGINT):  # before the path is printed: a client may signal at once
        signal.signal(signum, lambda *_: stopping.append(True))
    master, slave, path = _open_pty()
    ready = getattr(device, "ready", None)
    if ready is not None:
        ready()
    print(path, flush=True)
    if args.truth:
        print(os.path.abspath(args.truth), flush=True)
    parent = os.getppid()
    faults = _Faults(args)
    idle = getattr(device, "idle", None)
    next_due_s = getattr(device, "next_due_s", None)
    scheduled = next_due_s is not None and not faults.active  # it says when to wake; else poll every _TICK_S
    turns = 0
    # a signal makes select return at once (its handler only notes it), however long the loop sleeps
    woken, wake = os.pipe()
    os.set_blocking(woken, False)
    os.set_blocking(wake, False)
    previous_wakeup = signal.set_wakeup_fd(wake)
    try:
        while not stopping and os.getppid() == parent:
            due = next_due_s() if next_due_s is not None else None
            if scheduled and turns > 0:  # the first turn ticks at once (the BOOT line)
                wait_s = _IDLE_WAIT_S if due is None else min(_IDLE_WAIT_S, max(0.0, due - time.monotonic()))
            else:
                wait_s = _TICK_S if due is None else min(_TICK_S, max(0.0, due - time.monotonic()))
            turns += 1
            readable, _, _ = select.select([master, woken], [], [], wait_s)
            if woken in readable:
                os.read(woken, 512)
                continue
            now = time.monotonic()
            out = b""
            if readable:
                try:
                    out += device.feed(os.read(master, 4096), now)
                except BlockingIOError:
                    pass
            out += device.tick(now)
            if out:
                faults.outbox.append((now + faults.delay_s, out))
            out = faults.garbage(now) + b"".join(data for due, data in faults.outbox if due <= now)
            faults.outbox = [(due, data) for due, data in faults.outbox if due > now]
            if out:
                _send(master, out)
            if idle is not None:
                idle(time.monotonic())
    finally:
        signal.set_wakeup_fd(previous_wakeup)
        os.close(woken)
        os.close(wake)
        os.close(master)
        os.close(slave)
    return 0


def run_simulator(build_device: Any, args: argparse.Namespace) -> int:
    """Check the common arguments, build the device and serve it (shared by ``python -m`` and ``bench sim``)."""
    if not 0 < args.speed_factor < float("inf"):
        raise ConfigError(f"--speed-factor = {args.speed_factor}, expected a finite number > 0")
    if not 0 <= args.load_kg <= 30:
        raise ConfigError(f"--load-kg = {args.load_kg}, expected a number in [0, 30]")
    return serve(build_device(args), args)


def main_for(build_device: Any, add_arguments: Any, description: str, argv: list[str] | None = None) -> int:
    """``python -m`` entry point shared by the simulators: parse arguments, build the device, serve it."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    add_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run_simulator(build_device, args)
    except BenchError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return exc.exit_code
