"""The reader process of :mod:`bench.sensors.reader_process`: a tiny program (standard library only, run as
``python -I _reader_child.py FD [normal]``) that drains an ``input_event`` stream and sends decoded frames to its
parent.

It is its own process so that no Python work of the runner (which holds the GIL for milliseconds at a time) can
keep it from emptying the kernel's buffer, which holds only some tens of reports (~7 ms at 8 kHz). Frames go to
stdout as ``<dqqq`` records (t_s, dx, dy, valid); when the parent is slow they wait in this process's memory, never
in the kernel's buffer. A ``SYN_DROPPED`` gap becomes an invalid frame (counts lost, never repaired), as in
:class:`bench.sensors.input_event.FrameAssembler`. stdin is the parent's leash: its end (the parent closed it or
died) ends this process, and a byte ``F`` on it asks for everything readable now followed by a marker record
(valid = -1). It says it is ready with one byte on stderr (``R``: at real-time priority, ``N``: not); a read
error ends it with the reason on stderr and exit status 3.
"""

import os
import select
import struct
import sys

EVENT = struct.Struct("llHHi")
RECORD = struct.Struct("<dqqq")
#: Sent after everything readable when the parent asks ``F`` (up to now); valid = -1 tells it from a frame.
MARKER = RECORD.pack(0.0, 0, 0, -1)
EV_SYN, EV_REL = 0x00, 0x02
SYN_REPORT, SYN_DROPPED = 0, 3
REL_X, REL_Y = 0x00, 0x01
#: Real-time priority asked for (``SCHED_FIFO``; allowed to root, ``CAP_SYS_NICE`` or an ``RLIMIT_RTPRIO`` from
#: limits.conf): woken by a report, the reader then runs at once even on a loaded machine. Without it, a normal
#: process still escapes the GIL but waits its turn behind every runnable process.
REALTIME_PRIORITY = 10


def ask_realtime() -> bool:
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(REALTIME_PRIORITY))
    except (OSError, AttributeError):
        return False
    return True


class Decoder:
    """The per-event loop of ``sensors.md`` §4.10 (faster than a vectorised decode at live read sizes)."""

    def __init__(self) -> None:
        self.pending = b""
        self.fx = self.fy = 0
        self.dropping = False

    def feed(self, data: bytes) -> bytes:
        buffer = self.pending + data
        whole = len(buffer) - len(buffer) % EVENT.size
        self.pending = buffer[whole:]
        out = []
        for sec, usec, etype, code, value in EVENT.iter_unpack(buffer[:whole]):
            if etype == EV_REL:
                if code == REL_X:
                    self.fx += value
                elif code == REL_Y:
                    self.fy += value
            elif etype == EV_SYN:
                if code == SYN_REPORT:
                    valid = not self.dropping
                    out.append(RECORD.pack(sec + usec * 1e-6, self.fx if valid else 0, self.fy if valid else 0, valid))
                    self.dropping = False
                    self.fx = self.fy = 0
                elif code == SYN_DROPPED:
                    self.dropping = True
        return b"".join(out)


def drain(source: int, decoder: Decoder, backlog: bytearray, *, once: bool = False) -> bool:
    """Decode what ``source`` has now into ``backlog`` (one read with ``once``); False at its end. A read error
    ends the process with the reason on stderr."""
    while True:
        try:
            data = os.read(source, 1 << 16)
        except BlockingIOError:
            return True
        except OSError as exc:
            sys.stderr.write(f"read failed ({exc.strerror})")
            sys.exit(3)
        if not data:
            return False
        backlog += decoder.feed(data)
        if once:
            return True


def main(source: int, realtime: bool = True) -> int:
    os.set_blocking(1, False)
    # ready (R: real-time, N: normal priority): the parent waits for this byte, so no report comes before a reader
    os.write(2, b"R" if realtime and ask_realtime() else b"N")
    poller = select.poll()
    poller.register(source, select.POLLIN)
    poller.register(0, select.POLLIN)
    decoder, backlog = Decoder(), bytearray()
    source_open, writing = True, False
    while source_open or backlog:
        if bool(backlog) != writing:
            writing = bool(backlog)
            if writing:
                poller.register(1, select.POLLOUT)
            else:
                poller.unregister(1)
        for fd, event in poller.poll():
            if fd == 0:
                asks = os.read(0, 4096)
                if not asks:
                    return 0  # the parent is done (or gone): nothing more is wanted
                for _ in range(asks.count(b"F")):  # up to now: everything readable, then the marker
                    if source_open:
                        source_open = drain(source, decoder, backlog)
                        if not source_open:
                            poller.unregister(source)
                    backlog += MARKER
                continue
            if fd == 1:
                if event & (select.POLLERR | select.POLLHUP):
                    return 0
                try:
                    del backlog[: os.write(1, backlog)]
                except BlockingIOError:
                    pass
                except BrokenPipeError:
                    return 0
            elif fd == source and source_open:
                source_open = drain(source, decoder, backlog, once=True)
                if not source_open:
                    poller.unregister(source)
    return 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]), realtime=sys.argv[2:] != ["normal"]))
