"""Benchmark: ingest an 8 kHz mouse stream, and store it.

Printed, all measured in this run:
- a FIFO stream (``python -m bench.simulators.mouse``, 60 s of simulated time) read with ``EvdevMouse``: reports
  received vs expected and the integrated counts. A FIFO blocks its writer, so this part cannot lose a report; it
  checks the decoding and measures the reader's CPU share;
- the paced stream that can lose (``bench.simulators.paced_mouse``): one report per write at 8 kHz into a 4 KiB
  pipe that drops what does not fit, as evdev does, while this process's main thread runs GIL-busy Python; the
  reports lost by the reader process (at real-time priority where granted, then at normal priority) against the
  in-process reader (a thread, as the mice reader was), counted from the writer's sequence numbers, with the
  largest gap;
- decode speed of the vectorised frame assembler relative to the plain per-event loop, on a whole stream and at
  live read sizes;
- the store: streamed rows/s in 0.1 s batches (8 kHz -> 800 rows, one transaction each, ``synchronous=FULL``)
  with min/median/max, against the floor of a bare ``executemany`` into an unindexed table, same pragmas.

Usage: ``python benchmarks/bench_mouse_ingest.py [--duration-s 60] [--rate-hz 8000] [--realtime]``
(``--realtime`` paces the FIFO writer to real time and runs the paced comparison for the full duration; without
it the paced comparison runs 10 s per reader).
"""

from __future__ import annotations

import argparse
import os
import sqlite3
import subprocess
import sys
import tempfile
import time

import numpy as np
from _timing import load_line, min_median_max

from bench.sensors.calibration import CountsCalibration
from bench.sensors.input_event import EVENT_DTYPE, FrameAssembler, MotionFrames
from bench.sensors.mouse import EvdevMouse, MouseGroup
from bench.simulators.mouse import MouseSimulator, circle_motion
from bench.simulators.paced_mouse import ingest_beside_busy_work
from bench.store import Store
from bench.store.streams import StreamWriter


def _timed(action) -> float:
    start = time.perf_counter()
    action()
    return time.perf_counter() - start


def paced(reader: str, duration_s: float, rate_hz: float, *, realtime: bool = True) -> bool:
    r = ingest_beside_busy_work(
        reader=reader, rate_hz=rate_hz, duration_s=duration_s, buffer_bytes=4096, realtime=realtime
    )
    label = "thread reader (in process)" if reader == "thread" else r.reader_kind
    print(
        f"paced {rate_hz:g} Hz x {duration_s:g} s into 4 KiB, beside busy Python, {label:34s}: "
        f"lost {r.lost} of {r.expected} ({100 * r.lost / r.expected:.2f} %), largest gap {r.largest_gap_ms:.3f} ms,"
        f" busy loops done {r.busy_loops}"
    )
    return r.lost == 0


def _batches(rate_hz: float, batch_s: float, count: int) -> list[MotionFrames]:
    n = int(rate_hz * batch_s)
    k = np.arange(n * count)
    frames = MotionFrames(k / rate_hz, k % 7 - 3, -(k % 5), np.ones(len(k), bool))
    return [
        MotionFrames(*(getattr(frames, f)[i * n : (i + 1) * n] for f in ("t_s", "dx", "dy", "valid")))
        for i in range(count)
    ]


def store_rates(folder: str, rate_hz: float, repeat: int = 5, batches: int = 20) -> bool:
    """Rows/s of StreamWriter batches into a bench store against a bare executemany into an unindexed table."""
    parts = _batches(rate_hz, 0.1, batches)
    rows = sum(len(p) for p in parts)
    store_times, floor_times = [], []
    for attempt in range(repeat):
        with Store(os.path.join(folder, f"stream{attempt}.db")) as store:
            run = store.start_run(protocol_name="stream", protocol_version="1", robot="pkm5", config={})
            writer = StreamWriter(store, run, "mouse_xy", batch_s=1e9, batch_rows=len(parts[0]))
            start = time.perf_counter()
            for p in parts:
                writer.append(p)
            writer.close()
            store_times.append(time.perf_counter() - start)
            assert writer.committed == rows
        db = sqlite3.connect(os.path.join(folder, f"floor{attempt}.db"), isolation_level=None)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.execute("CREATE TABLE t (run_id, stream, t_s, dx_counts, dy_counts, valid)")
        plain = [
            list(
                zip(
                    [1] * len(p),
                    ["mouse_xy"] * len(p),
                    p.t_s.tolist(),
                    p.dx.tolist(),
                    p.dy.tolist(),
                    p.valid.astype(int).tolist(),
                )
            )
            for p in parts
        ]
        start = time.perf_counter()
        for batch in plain:
            db.execute("BEGIN")
            db.executemany("INSERT INTO t VALUES (?, ?, ?, ?, ?, ?)", batch)
            db.execute("COMMIT")
        floor_times.append(time.perf_counter() - start)
        db.close()
    with Store(os.path.join(folder, "samples.db")) as store:  # before: one committed sample per report
        run = store.start_run(protocol_name="stream", protocol_version="1", robot="pkm5", config={})
        start = time.perf_counter()
        for k in range(200):
            store.add_sample(run, k, values={"dx_counts": 1.0, "dy_counts": 0.0}, kind="mouse", t_s=k / rate_hz)
        sample_rate = 200 / (time.perf_counter() - start)
    store_rate = [rows / t for t in store_times]
    floor_rate = [rows / t for t in floor_times]
    print(
        f"store: {batches} batches of {len(parts[0])} rows (0.1 s of {rate_hz:g} Hz), one transaction each; "
        f"{repeat} runs"
    )
    print(
        f"  StreamWriter -> stream_rows: rows/s min {min(store_rate):,.0f}, median {np.median(store_rate):,.0f}, "
        f"max {max(store_rate):,.0f} ({min_median_max(store_times)} for {rows} rows)"
    )
    print(
        f"  floor, bare executemany into an unindexed table: rows/s min {min(floor_rate):,.0f}, median "
        f"{np.median(floor_rate):,.0f}, max {max(floor_rate):,.0f}"
    )
    print(f"  before, one add_sample (one transaction) per report: {sample_rate:,.0f} rows/s")
    print(
        f"  median ratio floor / store {np.median(floor_rate) / np.median(store_rate):.2f}x; sustained "
        f"{np.median(store_rate) / rate_hz:.1f}x the {rate_hz:g} Hz stream (min {min(store_rate) / rate_hz:.1f}x)"
    )
    return min(store_rate) >= rate_hz


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--duration-s", type=float, default=60.0)
    parser.add_argument("--rate-hz", type=float, default=8000.0)
    parser.add_argument("--cpi", type=float, default=1600.0)
    parser.add_argument("--realtime", action="store_true")
    args = parser.parse_args()
    started = os.getloadavg()

    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "event-mouse")
        os.mkfifo(fifo)
        writer = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "bench.simulators.mouse",
                "--out",
                fifo,
                "--duration-s",
                str(args.duration_s),
                "--rate-hz",
                str(args.rate_hz),
                "--cpi",
                str(args.cpi),
                *(["--realtime"] if args.realtime else []),
            ]
        )
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
    counts_match = np.array_equal(frames.dx, expected.dx) and np.array_equal(frames.dy, expected.dy)
    gaps_ms = np.diff(frames.t_s).max() * 1e3 if len(frames) > 1 else float("nan")
    print(
        f"stream: {args.rate_hz:g} Hz x {args.duration_s:g} s at {args.cpi:g} CPI "
        f"({'real time' if args.realtime else 'as fast as the pipe allows'})"
    )
    print(
        f"reports: received {len(frames)}, expected {len(expected.t_s)}, lost {lost}; "
        f"per-report counts identical: {counts_match}; all valid: {bool(frames.valid.all())}; "
        f"largest gap {gaps_ms:.3f} ms"
    )
    print(
        f"reader: {cpu_s:.2f} s CPU, {wall_s:.2f} s wall -> CPU share of the {args.duration_s:g} s stream "
        f"{100 * cpu_s / args.duration_s:.2f} %"
    )

    data = sim.input_events(*circle_motion(min(args.duration_s, 5.0), 20.0, 4.0, args.rate_hz))
    fast = min(_timed(lambda: FrameAssembler().feed(data)) for _ in range(5))
    events = np.frombuffer(data, EVENT_DTYPE)
    slow = min(_timed(lambda: FrameAssembler()._feed_events_loop(events)) for _ in range(3))
    print(
        f"decode of {len(data) // EVENT_DTYPE.itemsize} events: vectorised {fast * 1e3:.1f} ms, "
        f"per-event loop {slow * 1e3:.1f} ms -> ratio {slow / fast:.1f}x (best of repeats)"
    )
    live = data[: 8 * 3 * EVENT_DTYPE.itemsize]  # 8 reports: what one read of a live 8 kHz mouse gets in 1 ms
    fast = min(_timed(lambda: [FrameAssembler().feed(live) for _ in range(1000)]) for _ in range(5))
    live_events = np.frombuffer(live, EVENT_DTYPE)
    slow = min(_timed(lambda: [FrameAssembler()._feed_events_loop(live_events) for _ in range(1000)]) for _ in range(5))
    print(
        f"decode at live read size (8 reports): vectorised {fast * 1e3:.1f} us, per-event loop {slow * 1e3:.1f} us"
        f" -> ratio vectorised / loop {fast / slow:.1f}x (the reader process decodes with the loop)"
    )

    paced_s = args.duration_s if args.realtime else 10.0
    paced_ok = paced("process", paced_s, args.rate_hz)
    paced("process", paced_s, args.rate_hz, realtime=False)  # a bench without real-time rights
    paced("thread", paced_s, args.rate_hz)  # the old reader, for comparison: it is expected to lose
    with tempfile.TemporaryDirectory() as tmp:
        store_ok = store_rates(tmp, args.rate_hz)
    print(load_line(started))
    return 0 if lost == 0 and counts_match and paced_ok and store_ok else 1


if __name__ == "__main__":
    sys.exit(main())
