"""A mouse paced like the kernel's evdev: one report per write, at its report rate, into a small buffer that
*drops* what does not fit (a FIFO would block the writer instead, and then nothing can ever be lost).

``python -m bench.simulators.paced_mouse --out FIFO --rate-hz 8000 --duration-s 60 --buffer-bytes 4096`` writes
report ``k`` as REL_X = 1, REL_Y = 0, SYN_REPORT with the timestamp ``k`` microseconds, so that a reader recovers
every report's sequence number (:func:`sequence_numbers`) and counts the gaps itself. The pipe's buffer is set to
``--buffer-bytes`` (``F_SETPIPE_SZ``): 4096 holds 56 reports of 72 bytes, 7 ms at 8 kHz, about an evdev client
buffer. A report that finds it full is waited for as long as the kernel's buffer would have held it (until the
report ``capacity`` before it is ``capacity / rate`` old, measured from when it was written, so that a writer
late by the scheduler is not counted as the reader's loss), then dropped and counted. At the end one JSON line on
stdout: ``{"written": n, "dropped": d, "capacity": c}``.
"""

from __future__ import annotations

import argparse
import collections
import fcntl
import json
import os
import select
import selectors
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass

import numpy as np

from bench.sensors.calibration import CountsCalibration
from bench.sensors.input_event import EV_REL, EV_SYN, EVENT, REL_X, SYN_REPORT, MotionFrames
from bench.sensors.mouse import EvdevMouse

__all__ = ["PacedIngest", "ingest_beside_busy_work", "report_bytes", "run", "sequence_numbers"]

_F_SETPIPE_SZ = 1031


def report_bytes(sequence: int) -> bytes:
    """Report ``sequence``: REL_X = 1 and SYN_REPORT, both stamped ``sequence`` microseconds."""
    sec, usec = divmod(sequence, 1_000_000)
    return EVENT.pack(sec, usec, EV_REL, REL_X, 1) + EVENT.pack(sec, usec, EV_SYN, SYN_REPORT, 0)


def sequence_numbers(t_s: np.ndarray) -> np.ndarray:
    """The sequence numbers of frames read back (their timestamps in microseconds)."""
    return np.round(np.asarray(t_s, float) * 1e6).astype(np.int64)


def run(
    out: str, *, rate_hz: float, duration_s: float, buffer_bytes: int, start_on_stdin: bool = False
) -> dict[str, int]:
    """Write ``rate_hz * duration_s`` reports into the FIFO ``out``, paced (after a line on stdin with
    ``start_on_stdin``: the reader is set up by then, as a mouse is read before the robot moves); the counts."""
    fd = os.open(out, os.O_WRONLY)  # waits for the reader, as a device waits to be opened
    try:
        fcntl.fcntl(fd, _F_SETPIPE_SZ, buffer_bytes)
        capacity = fcntl.fcntl(fd, 1032) // len(report_bytes(0))  # F_GETPIPE_SZ: what the kernel granted
        os.set_blocking(fd, False)
        total = int(round(rate_hz * duration_s))
        written_at: collections.deque[float] = collections.deque(maxlen=capacity)
        poller = select.poll()
        poller.register(fd, select.POLLOUT)
        dropped = 0
        if start_on_stdin:
            sys.stdin.readline()
        start = time.perf_counter()
        for sequence in range(total):
            lag = start + sequence / rate_hz - time.perf_counter()
            if lag > 0:
                time.sleep(lag)
            data = report_bytes(sequence)
            held_until = None
            checked_late = False
            while True:
                try:
                    os.write(fd, data)
                    written_at.append(time.perf_counter())
                    break
                except BlockingIOError:
                    if held_until is None:
                        held_until = written_at[0] + capacity / rate_hz if written_at else 0.0
                    wait_s = held_until - time.perf_counter()
                    # full past the deadline, checked once more now (this writer may itself have been
                    # descheduled after the failed write, while the reader emptied the buffer): a drop
                    if checked_late or not poller.poll(max(wait_s, 0.0) * 1e3):
                        dropped += 1
                        break
                    checked_late = wait_s <= 0
        return {"written": total - dropped, "dropped": dropped, "capacity": capacity}
    finally:
        os.close(fd)


@dataclass(frozen=True)
class PacedIngest:
    """What a reader got of a paced stream: ``expected`` reports written or dropped by the writer, ``received``
    distinct sequence numbers read back, ``lost`` = expected - received, the writer's own ``dropped`` count,
    the largest gap between consecutive received reports (ms) and the busy work done meanwhile (loops)."""

    expected: int
    received: int
    lost: int
    dropped: int
    largest_gap_ms: float
    busy_loops: int
    invalid_frames: int
    reader_kind: str


def _busy_python(stop: threading.Event) -> int:
    """Pure-Python work that holds the GIL (as the runner's bookkeeping does) until ``stop``; the loops done."""
    loops = 0
    while not stop.is_set():
        sum(i * i for i in range(20_000))
        loops += 1
    return loops


def ingest_beside_busy_work(
    *,
    reader: str,
    rate_hz: float = 8000.0,
    duration_s: float = 10.0,
    buffer_bytes: int = 4096,
    realtime: bool = True,
    one_cpu: bool = False,
) -> PacedIngest:
    """Read a paced mouse (:func:`run` in a writer process) with ``reader`` = ``"process"`` (a reader process,
    :mod:`bench.sensors.reader_process`) or ``"thread"`` (the in-process reader, as a reader thread uses it),
    while this process's main thread runs GIL-busy Python work; a thread takes the frames as the mice
    instrument's reader does. ``realtime``: the reader process asks for real-time priority.

    ``one_cpu``: the writer, the reader and the busy work all run on one CPU (this thread's affinity, which the
    children inherit; restored at the end). The reader then competes with the busy work for that CPU, and a
    stall of the CPU itself (a virtual machine's CPU taken away by its host for milliseconds, seen once in a test
    suite on a loaded 2-vCPU machine) stops the writer as well, whose lateness :func:`run` does not count as the
    reader's loss. Across two CPUs the writer went on filling the 7 ms buffer while the reader's CPU stood."""
    if one_cpu and hasattr(os, "sched_setaffinity"):
        allowed = os.sched_getaffinity(0)
        os.sched_setaffinity(0, {min(allowed)})
        try:
            return ingest_beside_busy_work(
                reader=reader, rate_hz=rate_hz, duration_s=duration_s, buffer_bytes=buffer_bytes, realtime=realtime
            )
        finally:
            os.sched_setaffinity(0, allowed)
    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "event-mouse")
        os.mkfifo(fifo)
        writer = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "bench.simulators.paced_mouse",
                "--out",
                fifo,
                "--rate-hz",
                str(rate_hz),
                "--duration-s",
                str(duration_s),
                "--buffer-bytes",
                str(buffer_bytes),
                "--start-on-stdin",
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
        )
        mouse = EvdevMouse(fifo, CountsCalibration.from_cpi(1600), label="paced")
        if reader == "process":
            mouse.start_reader_process(realtime=realtime)
        reader_kind = mouse.settings()["reader"]
        parts: list[MotionFrames] = []
        stop = threading.Event()

        def take() -> None:
            with selectors.PollSelector() as selector:
                selector.register(mouse.fileno(), selectors.EVENT_READ)
                while not mouse.exhausted:
                    if selector.select(0.05):
                        parts.append(mouse.read_frames())
            stop.set()

        taker = threading.Thread(target=take, name="paced-taker", daemon=True)
        try:
            writer.stdin.write(b"go\n")
            writer.stdin.close()
            taker.start()
            loops = _busy_python(stop)
            taker.join()
        finally:
            stop.set()
            mouse.close()
            out = writer.stdout.read()
            writer.wait()
    counts = json.loads(out)
    frames = MotionFrames.concatenate(parts)
    sequence = np.unique(sequence_numbers(frames.t_s[frames.valid]))
    expected = counts["written"] + counts["dropped"]
    gaps = np.diff(np.r_[-1, sequence, expected])
    return PacedIngest(
        expected,
        len(sequence),
        expected - len(sequence),
        counts["dropped"],
        float(gaps.max() * 1e3 / rate_hz),
        loops,
        int((~frames.valid).sum()),
        reader_kind,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", required=True, help="a FIFO (the reader opens it)")
    parser.add_argument("--rate-hz", type=float, default=8000.0)
    parser.add_argument("--duration-s", type=float, default=10.0)
    parser.add_argument("--buffer-bytes", type=int, default=4096)
    parser.add_argument("--start-on-stdin", action="store_true", help="start once a line arrives on stdin")
    args = parser.parse_args(argv)
    print(
        json.dumps(
            run(
                args.out,
                rate_hz=args.rate_hz,
                duration_s=args.duration_s,
                buffer_bytes=args.buffer_bytes,
                start_on_stdin=args.start_on_stdin,
            )
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
