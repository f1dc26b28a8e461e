"""A reader process for a streaming event device: the runner's Python work cannot starve it.

A reader *thread* shares the GIL with the runner: pure-Python work holds it for the switch interval (5 ms) and
longer, while an evdev client buffer (or a 4 KiB pipe) holds ~7 ms of an 8 kHz mouse; measured, 15 % of the
reports were lost that way (``benchmarks/bench_mouse_ingest.py --realtime``). :class:`ReaderProcess` hands the
open descriptor to a child (:mod:`bench.sensors._reader_child`, standard library only) that empties it at once and
sends decoded frames back through a pipe; frames the parent has not taken yet wait in the child's memory.

Drops are never silent: a kernel ``SYN_DROPPED`` gap arrives as an invalid frame (counted by
:attr:`bench.sensors.mouse.EvdevMouse.dropped_gaps`), and a read failure of the child (an unplugged device) is
raised as :class:`bench.errors.LinkError` with its reason.
The child ends when the parent closes it or dies (its stdin ends); :meth:`close` reaps it, so none is left over.
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import weakref
from pathlib import Path

import numpy as np

from bench.errors import LinkError
from bench.sensors.input_event import MotionFrames

__all__ = ["RECORD_DTYPE", "ReaderProcess"]

#: One decoded frame as the child sends it: ``struct "<dqqq"`` (t_s, dx, dy, valid).
RECORD_DTYPE = np.dtype([("t_s", "<f8"), ("dx", "<i8"), ("dy", "<i8"), ("valid", "<i8")])
_CHILD = str(Path(__file__).with_name("_reader_child.py"))
#: How long an ``up_to_now`` read waits for the child's marker (it answers in well under a millisecond).
_ANSWER_S = 5.0
#: The longest a reader child may take to start (a stdlib-only interpreter: well under 1 s on an idle PC).
_START_S = 30.0
_READ_SIZE = 1 << 20
_PIPE_SIZE = 1 << 20


def _reap(process: subprocess.Popen) -> None:
    """Close the child's leash and wait for it; kill it if it does not end (never left as a zombie)."""
    for stream in (process.stdin, process.stdout, process.stderr):
        if stream is not None:
            stream.close()
    try:
        process.wait(2.0)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


class ReaderProcess:
    """Frames of one ``input_event`` stream, read by a child process from the descriptor ``fd``.

    Parameters
    ----------
    fd : int
        An open event device, FIFO or file (the caller keeps it open, with any grab; only the child reads it).
    name : str
        The device as messages name it (``str(binding)``).
    realtime : bool
        Ask for real-time priority (``SCHED_FIFO``; granted to root, ``CAP_SYS_NICE`` or an ``RLIMIT_RTPRIO``);
        :attr:`realtime` says whether it was.
    """

    def __init__(self, fd: int, *, name: str, realtime: bool = True) -> None:
        self.name = name
        self.exhausted = False
        self._failure: str | None = None  # why the child failed: raised by every later read, never forgotten
        self._pending = b""
        command = [sys.executable, "-I", _CHILD, str(fd), *([] if realtime else ["normal"])]
        self._process = subprocess.Popen(
            command, pass_fds=(fd,), stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        self._finalizer = weakref.finalize(self, _reap, self._process)
        started = select.select([self._process.stderr], [], [], _START_S)[0]
        ready = self._process.stderr.read(1) if started else b""
        if ready not in (b"R", b"N"):  # started, or why not
            why = "" if not started else (ready + self._process.stderr.read(2000)).decode(errors="replace").strip()
            self._finalizer()
            raise LinkError(
                f"{name}: the reader process did not start within {_START_S:g} s"
                + (f": {why.splitlines()[-1]}" if why else f" (exit status {self._process.returncode})")
            )
        #: Whether the child runs at real-time priority (``SCHED_FIFO``); stored in the sensor's settings.
        self.realtime = ready == b"R"
        self._fd = self._process.stdout.fileno()
        os.set_blocking(self._fd, False)
        try:
            import fcntl

            fcntl.fcntl(self._fd, 1031, _PIPE_SIZE)  # F_SETPIPE_SZ: fewer wake-ups of the child when it is ahead
        except OSError:
            pass

    def fileno(self) -> int:
        """The pipe of decoded frames (readable when frames or the end arrived), for ``selectors``."""
        return self._fd

    def read_frames(self, *, up_to_now: bool = False) -> MotionFrames:
        """Every frame the child has sent so far (non-blocking), or with ``up_to_now`` every frame the device
        held when called (the child drains it and answers; a capture's reading then misses nothing in transit).
        Raises ``LinkError`` if the child failed, at this read and at every later one."""
        if self._failure is not None:
            raise LinkError(self._failure)
        chunks = [self._pending]
        asked = up_to_now and not self.exhausted
        if asked:
            try:
                os.write(self._process.stdin.fileno(), b"F")
            except BrokenPipeError:  # the child has ended: all it sent is in the pipe, up to its end
                asked = False
        while not self.exhausted:
            if asked and not select.select([self._fd], [], [], _ANSWER_S)[0]:
                raise LinkError(f"{self.name}: the reader process did not answer within {_ANSWER_S:g} s")
            try:
                data = os.read(self._fd, _READ_SIZE)
            except BlockingIOError:
                break
            if not data:
                self._ended()
                break
            chunks.append(data)
            if asked:
                chunks = [b"".join(chunks)]
                records = np.frombuffer(chunks[0], RECORD_DTYPE, count=len(chunks[0]) // RECORD_DTYPE.itemsize)
                asked = not (records["valid"] == -1).any()
        data = b"".join(chunks)
        whole = len(data) - len(data) % RECORD_DTYPE.itemsize
        self._pending = data[whole:]
        if not whole:
            return MotionFrames.empty()
        records = np.frombuffer(data, RECORD_DTYPE, count=whole // RECORD_DTYPE.itemsize)
        records = records[records["valid"] >= 0]  # the answers' markers (valid = -1) out
        return MotionFrames(records["t_s"].copy(), records["dx"].copy(), records["dy"].copy(), records["valid"] != 0)

    def _ended(self) -> None:
        """The child closed its output: the stream ended, or the child failed (then say why)."""
        self.exhausted = True
        status = self._process.wait()
        if status != 0:
            reason = self._process.stderr.read().decode(errors="replace").strip() or f"exit status {status}"
            self._failure = (
                f"{self.name}: {reason}; the device was probably unplugged: the run segment is "
                "invalid, re-bind and restart the cycle"
            )
            raise LinkError(self._failure)

    def close(self) -> None:
        """Stop the child and reap it."""
        self._finalizer()
