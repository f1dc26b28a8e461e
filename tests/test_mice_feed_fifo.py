"""The simulated mice's FIFOs behave as a kernel event device under a slow host: whole events only (a full FIFO
never leaves half an ``input_event`` for the host to read), and a host that has been reading gets every report even
when it is starved for a while (a loaded machine), instead of losing counts the mice cross-check would refuse."""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from bench.sensors.calibration import DEFAULT_CPI
from bench.sensors.input_event import EVENT_DTYPE
from bench.simulators.mice_feed import MiceFeed, fifo_paths

START = np.array([100.0, 0.0, 300.0])
#: a move long and large enough that its reports (500 Hz while counts change, three events each: about 720 kB)
#: overflow a FIFO's 64 KiB many times
LONG_MOVE_S = 20.0
FAR_MM = np.array([300.0, 200.0, 100.0])
#: the mice's clock runs this much faster than the wall's (as a rehearsal's): the long move fits in 30 ms of waiting
SPEED_FACTOR = 1000.0


def _feed(folder) -> MiceFeed:
    """Mice whose clock has run past :data:`LONG_MOVE_S` since they started (a move never starts before that)."""
    feed = MiceFeed(folder, START, seed=1, speed_factor=SPEED_FACTOR)
    time.sleep(1.5 * LONG_MOVE_S / SPEED_FACTOR)
    return feed


def _drain(fd: int) -> bytes:
    chunks = []
    while True:
        try:
            chunk = os.read(fd, 1 << 16)
        except BlockingIOError:
            return b"".join(chunks)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)


def _reader(path: str) -> int:
    return os.open(path, os.O_RDONLY | os.O_NONBLOCK)


def test_a_fifo_nobody_reads_holds_whole_events_only(tmp_path):
    feed = _feed(tmp_path)
    try:
        feed.rest(START + FAR_MM, motion_s=LONG_MOVE_S)  # far more than the FIFO holds: most is lost
        readers = {plane: _reader(path) for plane, path in fifo_paths(tmp_path).items()}
        for fd in readers.values():
            data = _drain(fd)
            assert len(data) > 40_000 and len(data) % EVENT_DTYPE.itemsize == 0, len(data)
            events = np.frombuffer(data, EVENT_DTYPE)
            assert set(np.unique(events["type"])) <= {0, 2}  # EV_SYN and EV_REL: no torn record read as another
            os.close(fd)
    finally:
        feed.close()


def test_a_host_seen_reading_gets_every_report_though_it_stalls(tmp_path):
    feed = _feed(tmp_path)
    readers = {plane: _reader(path) for plane, path in fifo_paths(tmp_path).items()}
    received = {plane: [] for plane in readers}
    try:
        feed.rest(START + [0.5, 0.0, 0.0], motion_s=0.01)  # a short move the host reads at once
        for plane, fd in readers.items():
            received[plane].append(_drain(fd))
        stop = threading.Event()

        def stalled_host() -> None:  # starved for 0.3 s (six times the wait for a host never seen reading)
            time.sleep(0.3)
            while not stop.is_set():
                for plane, fd in readers.items():
                    received[plane].append(_drain(fd))
                time.sleep(0.001)

        host = threading.Thread(target=stalled_host)
        time.sleep(1.5 * LONG_MOVE_S / SPEED_FACTOR)
        host.start()
        feed.rest(START + FAR_MM, motion_s=LONG_MOVE_S)
        time.sleep(0.2)
        stop.set()
        host.join()
        for plane, fd in readers.items():
            received[plane].append(_drain(fd))
            events = np.frombuffer(b"".join(received[plane]), EVENT_DTYPE)
            moved = events[events["type"] == 2]
            x_counts = int(moved["value"][moved["code"] == 0].sum())
            # 300 mm of x in all (both mice see x): 9449 counts at the default CPI, noise and quantisation within a few
            assert abs(x_counts - FAR_MM[0] / 25.4 * DEFAULT_CPI) < 5, (plane, x_counts)
    finally:
        for fd in readers.values():
            os.close(fd)
        feed.close()
