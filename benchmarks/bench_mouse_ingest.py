"""Benchmark: ingest an 8 kHz mouse stream for 60 s of simulated time through a FIFO.

The simulator runs as a separate program (``python -m bench.simulators.mouse``) writing kernel ``input_event``
records into a FIFO; this process reads it with ``EvdevMouse`` exactly as it would read ``/dev/input/event*``.
Printed, all measured in this run:
- reports received vs expected (lost reports must be 0) and the integrated counts vs the simulator's;
- the reader's CPU time as a share of the 60 s of stream it ingested (its load when reading live);
- decode speed of the vectorised frame assembler relative to the plain per-event loop on the same bytes.

Usage: ``python benchmarks/bench_mouse_ingest.py [--duration-s 60] [--rate-hz 8000] [--realtime]``
(``--realtime`` paces the writer to real time, so the run takes the full duration).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from bench.sensors.calibration import CountsCalibration
from bench.sensors.input_event import EVENT_DTYPE, FrameAssembler
from bench.sensors.mouse import EvdevMouse, MouseGroup
from bench.simulators.mouse import MouseSimulator, circle_motion


def _timed(action) -> float:
    start = time.perf_counter()
    action()
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration-s", type=float, default=60.0)
    parser.add_argument("--rate-hz", type=float, default=8000.0)
    parser.add_argument("--cpi", type=float, default=1600.0)
    parser.add_argument("--realtime", action="store_true")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "event-mouse")
        os.mkfifo(fifo)
        writer = subprocess.Popen([sys.executable, "-m", "bench.simulators.mouse", "--out", fifo,
                                   "--duration-s", str(args.duration_s), "--rate-hz", str(args.rate_hz),
                                   "--cpi", str(args.cpi), *(["--realtime"] if args.realtime else [])])
        mouse = EvdevMouse(fifo, CountsCalibration.from_cpi(args.cpi), label="bench")
        group = MouseGroup([mouse])
        wall0, cpu0 = time.perf_counter(), time.process_time()
        frames = group.collect(args.duration_s * 10 + 60)["bench"]
        cpu_s, wall_s = time.process_time() - cpu0, time.perf_counter() - wall0
        group.close()
        if writer.wait() != 0:
            print("simulator failed", file=sys.stderr)
            return 1

    sim = MouseSimulator(cpi=args.cpi, report_rate_hz=args.rate_hz, report_idle=True)
    expected = sim.reports(*circle_motion(args.duration_s, 20.0, 4.0, args.rate_hz))
    lost = len(expected.t_s) - len(frames)
    counts_match = (np.array_equal(frames.dx, expected.dx) and np.array_equal(frames.dy, expected.dy))
    gaps_ms = np.diff(frames.t_s).max() * 1e3 if len(frames) > 1 else float("nan")
    print(f"stream: {args.rate_hz:g} Hz x {args.duration_s:g} s at {args.cpi:g} CPI "
          f"({'real time' if args.realtime else 'as fast as the pipe allows'})")
    print(f"reports: received {len(frames)}, expected {len(expected.t_s)}, lost {lost}; "
          f"per-report counts identical: {counts_match}; all valid: {bool(frames.valid.all())}; "
          f"largest gap {gaps_ms:.3f} ms")
    print(f"reader: {cpu_s:.2f} s CPU, {wall_s:.2f} s wall -> CPU share of the {args.duration_s:g} s stream "
          f"{100 * cpu_s / args.duration_s:.2f} %")

    data = sim.input_events(*circle_motion(min(args.duration_s, 5.0), 20.0, 4.0, args.rate_hz))
    fast = min(_timed(lambda: FrameAssembler().feed(data)) for _ in range(5))
    events = np.frombuffer(data, EVENT_DTYPE)
    slow = min(_timed(lambda: FrameAssembler()._feed_events_loop(events)) for _ in range(3))
    print(f"decode of {len(data) // EVENT_DTYPE.itemsize} events: vectorised {fast * 1e3:.1f} ms, "
          f"per-event loop {slow * 1e3:.1f} ms -> ratio {slow / fast:.1f}x (best of repeats)")
    return 0 if lost == 0 and counts_match else 1


if __name__ == "__main__":
    sys.exit(main())
