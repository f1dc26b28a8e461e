"""``bench`` processes forked from a warm parent, for a drill that starts many of them and kills them.

Starting ``bench run`` costs its process ~0.4 s of CPU in the interpreter and imports before the command does
anything; a drill of twenty segments pays that twenty times. :class:`BenchForks` starts this file once as a
*zygote* that has imported what a run needs, and forks one child per command: the child points its standard
streams at /dev/null and files, then leaves through ``sys.exit(bench.cli.main(argv))``, exactly as the ``bench``
entry point does, so it ends through the interpreter's own exit. Each child is a real process of its own (its own
pid, port, store connection, lock file and signal handlers) that a SIGKILL ends at once and a SIGTERM asks to stop.

The zygote serves one command at a time: it reads a JSON request (argv and the two output files) on stdin, answers
the child's pid, waits for the child and answers its exit code (``-N`` for signal N, as ``Popen.returncode``).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

#: What ``bench run`` / ``bench resume`` on a ``--port`` rig import in their handlers (the rest, if any, the child
#: imports itself).
PRELOAD = ("bench.cli", "bench.commands.campaign", "bench.calibration_compensation", "bench.launch",
           "bench.protocols", "bench.protocols.plan", "bench.rigs.builder", "bench.store")


class ForkedBench:
    """One ``bench`` command forked by the zygote; ``poll``, ``wait``, ``communicate`` and ``returncode`` as on a
    ``subprocess.Popen`` with ``stdout`` and ``stderr`` piped."""

    def __init__(self, forks: BenchForks, pid: int, stdout: Path, stderr: Path) -> None:
        self.forks, self.pid, self.stdout, self.stderr = forks, pid, stdout, stderr
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            line = self.forks.answer(timeout_s=0.0)
            if line is not None:
                self.returncode = int(line)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None:
            line = self.forks.answer(timeout_s=timeout)
            if line is None:
                raise subprocess.TimeoutExpired(f"bench (pid {self.pid})", timeout)
            self.returncode = int(line)
        return self.returncode

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        return self.stdout.read_text(), self.stderr.read_text()


class BenchForks:
    """The zygote, started in ``folder`` (each command's output files go there); close it when done."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self._count = 0
        self._last: ForkedBench | None = None
        self._buffer = b""
        self.zygote = subprocess.Popen([sys.executable, __file__], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                       bufsize=0)

    def start(self, argv: list[str]) -> ForkedBench:
        """Fork ``bench *argv`` (stdin /dev/null); returns once the child exists."""
        self._count += 1
        stdout, stderr = (self.folder / f"bench-{self._count}.{name}" for name in ("out", "err"))
        request = {"argv": argv, "stdout": str(stdout), "stderr": str(stderr)}
        self.zygote.stdin.write(json.dumps(request).encode() + b"\n")
        pid = self.answer(timeout_s=60.0)
        assert pid is not None, "the zygote forked no bench within 60 s"
        self._last = ForkedBench(self, int(pid), stdout, stderr)
        return self._last

    def answer(self, timeout_s: float | None) -> str | None:
        """The zygote's next answer line, or None if none came within ``timeout_s`` (None: wait for it)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while b"\n" not in self._buffer:
            wait_s = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready, _, _ = select.select([self.zygote.stdout], [], [], wait_s)
            if not ready:
                return None
            chunk = os.read(self.zygote.stdout.fileno(), 4096)
            assert chunk, f"the zygote ended (exit code {self.zygote.wait()})"
            self._buffer += chunk
        line, self._buffer = self._buffer.split(b"\n", 1)
        return line.decode()

    def close(self) -> None:
        """End the zygote; a command still running (a test that failed midway) is killed first."""
        if self._last is not None and self._last.poll() is None:
            os.kill(self._last.pid, signal.SIGKILL)
            self._last.wait(30)
        self.zygote.stdin.close()  # end of requests: the zygote leaves its loop
        self.zygote.wait(30)
        self.zygote.stdout.close()


def _serve() -> None:
    """The zygote's loop (this file run as a program)."""
    import importlib

    del sys.path[0]  # the tests folder: nothing of it may shadow what bench imports, as for the entry point
    for module in PRELOAD:
        importlib.import_module(module)
    from bench.cli import main

    written = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
    for line in sys.stdin:
        request = json.loads(line)
        # opened before the fork: the files exist even when a kill lands before the child has run a line
        streams = [os.open(os.devnull, os.O_RDONLY), os.open(request["stdout"], written, 0o644),
                   os.open(request["stderr"], written, 0o644)]
        pid = os.fork()
        if pid == 0:
            for fd, opened in enumerate(streams):
                os.dup2(opened, fd)
                os.close(opened)
            sys.exit(main(request["argv"]))  # the child leaves as the ``bench`` entry point does
        for opened in streams:
            os.close(opened)
        print(pid, flush=True)
        _, status = os.waitpid(pid, 0)
        print(os.waitstatus_to_exitcode(status), flush=True)


if __name__ == "__main__":
    _serve()
