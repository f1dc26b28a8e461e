"""Programs forked from a warm parent (a *zygote*), for a test suite that starts the same programs many times.

``python -m bench.simulators.pkm5`` spends ~0.3 s of CPU in the interpreter's start and its imports before it
prints its pty, and ``bench run`` ~0.4 s before it does anything; the suite starts ~130 simulators and the kill drill
21 ``bench`` processes. A :class:`Zygote` runs this file once as a process that has imported what those programs
import (its ``preload``), and forks one child per ``python -m MODULE ...`` command: the child takes the caller's
pipe or files as its standard streams and runs the module as ``python -m`` does (``runpy``, ``__main__``), so it
parses the same argv, prints the same lines and leaves through the interpreter's own exit. Each child is a real
process of its own (its own pid, pty or port, store connection, signal handlers) that SIGTERM asks to stop and
SIGKILL ends at once.

:func:`install` puts the simulators' zygote in :data:`bench.simulators.rig.spawn` (production code starts simulators
with ``subprocess.Popen``; this file is test infrastructure only); tests/forked_bench.py has a zygote of ``bench``.

Wire: one ``SOCK_SEQPACKET`` Unix socket between the test process and the zygote. A request is a JSON packet
``{"module", "argv", "cwd", "env"}`` carrying the child's stdout and stderr descriptors (``SCM_RIGHTS``); the zygote
answers ``{"pid"}`` once the child exists, and ``{"exited": pid, "code": N}`` when it has reaped it (``-N`` for
signal N, as ``Popen.returncode``). A simulator ends when its parent does, and the zygote is that parent: when the
test process closes the socket (or dies), the zygote kills the children left and ends.
"""

from __future__ import annotations

import glob
import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
from typing import Any

from bench.simulators.pkm5_plant import load_fk_kernel
from motion.pkm5 import compiled as pkm5_compiled

#: What the simulators' zygote imports before it forks (each child imports anything else itself).
SIMULATORS = (
    "numpy",
    "bench.simulators.pkm5",
    "bench.simulators.pkm5_plant",
    "bench.simulators.delta4",
    "bench.simulators.lasergrid",
    "bench.simulators.true_geometry",
    "bench.simulators.error_model",
    "motion.pkm5",
    "motion.delta4",
)
_PACKET = 65536


class ForkedProcess:
    """A program forked by a zygote: ``pid``, ``args``, ``stdout``, ``returncode``, ``poll``, ``wait``,
    ``terminate``, ``kill``, ``send_signal`` and ``communicate`` as on the ``subprocess.Popen`` it stands for."""

    def __init__(self, forks: Zygote, pid: int, args: list[str], stdout: Any) -> None:
        self.forks, self.pid, self.args, self.stdout = forks, pid, args, stdout
        self.stdin = self.stderr = None

    @property
    def returncode(self) -> int | None:
        return self.forks.exit_codes.get(self.pid)

    def poll(self) -> int | None:
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        with self.forks.exited:
            if not self.forks.exited.wait_for(lambda: self.pid in self.forks.exit_codes, timeout):
                raise subprocess.TimeoutExpired(self.args, timeout)
            return self.forks.exit_codes[self.pid]

    def send_signal(self, signum: int) -> None:
        if self.returncode is None:  # not reaped, so the pid is still this child's
            try:
                os.kill(self.pid, signum)
            except ProcessLookupError:  # reaped by the zygote, its exit not yet read here (as Popen)
                pass

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def communicate(self, timeout: float | None = None) -> tuple[Any, None]:
        out = self.stdout.read() if self.stdout is not None else None
        self.wait(timeout)
        return out, None

    def __enter__(self) -> ForkedProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.stdout is not None:
            self.stdout.close()
        self.wait()


class Zygote:
    """A warm parent that has imported ``preload`` (module names) and forks the programs of :meth:`popen`, and what
    its children's exits were; ``load_fk_kernel``: it also loads the pkm5 plant's compiled FK kernel once numba's
    cache holds it (the simulators' zygote)."""

    def __init__(self, preload: tuple[str, ...], *, load_fk_kernel: bool = False) -> None:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        setup = json.dumps({"preload": list(preload), "load_fk_kernel": load_fk_kernel})
        self.zygote = subprocess.Popen(
            [sys.executable, __file__, str(theirs.fileno()), setup],
            pass_fds=(theirs.fileno(),),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
        )
        theirs.close()
        self.socket = ours
        self.exit_codes: dict[int, int] = {}
        self.exited = threading.Condition()
        self._started: list[int] = []
        self._request = threading.Lock()  # one request in flight: its answer is the next "pid" packet
        self._pids = threading.Condition()
        threading.Thread(target=self._listen, name="simulator-forks", daemon=True).start()

    def _listen(self) -> None:
        while True:
            packet = self.socket.recv(_PACKET)
            if not packet:  # the zygote ended
                return
            message = json.loads(packet)
            if "pid" in message:
                with self._pids:
                    self._started.append(message["pid"])
                    self._pids.notify_all()
            else:
                with self.exited:
                    self.exit_codes[message["exited"]] = message["code"]
                    self.exited.notify_all()

    def popen(
        self,
        command: list[str],
        *,
        stdout: Any = None,
        stderr: Any = None,
        text: bool = False,
        start_new_session: bool = False,
        **unsupported: Any,
    ) -> ForkedProcess | subprocess.Popen:
        """``subprocess.Popen(command, stdout=, stderr=, text=)`` for ``[python, -m, MODULE, ...]``, stdout a pipe,
        a file or None, stderr a file or None; any other command or option goes to ``subprocess.Popen``."""
        forkable_out = stdout in (None, subprocess.PIPE) or hasattr(stdout, "fileno")
        forkable_err = stderr is None or hasattr(stderr, "fileno")
        if (
            unsupported
            or len(command) < 3
            or command[:2] != [sys.executable, "-m"]
            or not forkable_out
            or not forkable_err
        ):
            return subprocess.Popen(
                command, stdout=stdout, stderr=stderr, text=text, start_new_session=start_new_session, **unsupported
            )
        read_end = None
        if stdout == subprocess.PIPE:
            read_end, write_end = os.pipe()
        else:
            write_end = os.open(os.devnull, os.O_WRONLY) if stdout is None else os.dup(stdout.fileno())
        error = os.open(os.devnull, os.O_WRONLY) if stderr is None else os.dup(stderr.fileno())
        request = {
            "module": command[2],
            "argv": command[3:],
            "cwd": os.getcwd(),
            "env": dict(os.environ),
            "new_session": start_new_session,
        }
        try:
            with self._request, self._pids:
                socket.send_fds(self.socket, [json.dumps(request).encode()], [write_end, error])
                if not self._pids.wait_for(lambda: self._started, 60):
                    raise RuntimeError(f"the zygote forked nothing within 60 s for {command[2]}")
                pid = self._started.pop()
        finally:
            os.close(write_end)
            os.close(error)
        pipe = None if read_end is None else open(read_end, "r" if text else "rb", buffering=-1 if text else 0)
        return ForkedProcess(self, pid, command, pipe)

    def close(self) -> None:
        """End the zygote (it kills any child still running)."""
        self.socket.shutdown(socket.SHUT_RDWR)  # wakes the listening thread; the zygote reads the end
        self.zygote.wait(30)
        self.socket.close()


_simulators: Zygote | None = None
_starting = threading.Lock()


def spawn(command: list[str], **options: Any) -> ForkedProcess | subprocess.Popen:
    """A simulator's ``python -m bench.simulators.X`` forked by this process's simulator zygote (started on first
    use); any other command as ``subprocess.Popen`` starts it."""
    global _simulators
    if len(command) < 3 or not command[2].startswith("bench.simulators."):
        return subprocess.Popen(command, **options)
    with _starting:
        if _simulators is None:
            _simulators = Zygote(SIMULATORS, load_fk_kernel=True)
    return _simulators.popen(command, **options)


def install() -> None:
    """Start this process's simulators by forking them (:data:`bench.simulators.rig.spawn`). The zygote ends with
    the process (it reads the end of the socket)."""
    import bench.simulators.rig as rig

    rig.spawn = spawn


# ---- the zygote (this file run as a program) --------------------------------------------------------------------


def _serve(sock: socket.socket, load_kernel: bool) -> dict | None:
    """Fork a child per request until the test process closes the socket; in a child, return its request."""
    children: set[int] = set()
    woken, wake = os.pipe()
    os.set_blocking(wake, False)
    signal.set_wakeup_fd(wake)
    signal.signal(signal.SIGCHLD, lambda *_: None)  # a handler, so that SIGCHLD wakes the select below
    while True:
        readable, _, _ = select.select([sock, woken], [], [])
        if woken in readable:
            os.read(woken, 512)
        while children:  # reap every child that has ended, and say how it ended
            pid, status = os.waitpid(-1, os.WNOHANG)
            if pid == 0:
                break
            children.discard(pid)
            _tell(sock, {"exited": pid, "code": os.waitstatus_to_exitcode(status)})
        if sock not in readable:
            continue
        packet, fds, _, _ = socket.recv_fds(sock, _PACKET, 2)
        if not packet:  # the test process has gone: so do its children
            for pid in children:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
            return None
        if load_kernel:
            _load_kernel_once_cached()
        pid = os.fork()
        if pid == 0:
            signal.set_wakeup_fd(-1)
            signal.signal(signal.SIGCHLD, signal.SIG_DFL)
            sock.close()
            if json.loads(packet).get("new_session"):
                os.setsid()  # as Popen(start_new_session=True): out of the terminal's foreground process group
            os.close(woken)
            os.close(wake)
            stdin = os.open(os.devnull, os.O_RDONLY)
            for target, fd in enumerate((stdin, *fds)):
                os.dup2(fd, target)
                os.close(fd)
            return json.loads(packet)
        for fd in fds:
            os.close(fd)
        children.add(pid)
        _tell(sock, {"pid": pid})


_kernel_loaded = False


def _load_kernel_once_cached() -> None:
    """Load the pkm5 plant's compiled FK kernel here once numba's cache holds it (a load, 0.5-1 s, never a compile
    of 10-20 s of CPU: on a fresh checkout the first compile happens elsewhere), so that every child has it from
    its first solve instead of solving ~200 moves with numpy before it loads the kernel itself
    (:meth:`bench.simulators.pkm5_plant._KernelLoader.engine`)."""
    global _kernel_loaded
    if _kernel_loaded or not glob.glob(
        os.path.join(os.path.dirname(pkm5_compiled.__file__), "__pycache__", "_kernels.fk_batch-*.nbi")
    ):
        return
    _kernel_loaded = True
    try:
        load_fk_kernel()
    except Exception:  # noqa: BLE001 - no numba, a broken cache: each child decides for itself, as on its own
        pass


def _tell(sock: socket.socket, message: dict) -> None:
    try:
        sock.send(json.dumps(message).encode())
    except OSError:  # the test process has gone; the loop finds the socket closed and ends its children
        pass


def _main() -> None:
    import importlib
    import runpy

    del sys.path[0]  # the tests folder: nothing of it may shadow what a program imports
    sock = socket.socket(fileno=int(sys.argv[1]))
    setup = json.loads(sys.argv[2])
    for module in setup["preload"]:
        importlib.import_module(module)
    request = _serve(sock, setup["load_fk_kernel"])
    if request is None:
        return
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    sys.argv = [request["module"], *request["argv"]]  # runpy puts the module's file first, as ``python -m`` does
    runpy.run_module(request["module"], run_name="__main__", alter_sys=True)


if __name__ == "__main__":
    _main()
