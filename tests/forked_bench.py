"""``bench`` processes forked from a warm parent, for a drill that starts many of them and kills them.

Starting ``bench run`` costs its process ~0.4 s of CPU in the interpreter and imports before the command does
anything; a drill of twenty segments pays that twenty times. :class:`BenchForks` keeps a :class:`zygote.Zygote`
that has imported what a run needs and forks one ``python -m bench ...`` per command (stdin /dev/null, stdout and
stderr into files of the folder, opened before the fork: they exist even when a kill lands before the child has run
a line). The child leaves through ``sys.exit(bench.cli.main())``, exactly as the ``bench`` entry point does. Each
child is a real process of its own (its own pid, port, store connection, lock file and signal handlers) that a
SIGKILL ends at once and a SIGTERM asks to stop.
"""

from __future__ import annotations

import sys
from pathlib import Path

from zygote import ForkedProcess, Zygote

#: What ``bench run`` / ``bench resume`` on a ``--port`` rig import in their handlers (the rest, if any, the child
#: imports itself).
PRELOAD = (
    "bench.cli",
    "bench.commands.campaign",
    "bench.calibration.compensate",
    "bench.launch",
    "bench.protocols",
    "bench.protocols.plan",
    "bench.rigs.builder",
    "bench.store",
)


class ForkedBench:
    """One ``bench`` command forked by the zygote: ``pid``, ``returncode``, ``poll``, ``wait`` and ``communicate``
    (its output files' texts) as on a ``subprocess.Popen`` with ``stdout`` and ``stderr`` piped."""

    def __init__(self, process: ForkedProcess, stdout: Path, stderr: Path) -> None:
        self.process, self.pid, self.stdout, self.stderr = process, process.pid, stdout, stderr

    @property
    def returncode(self) -> int | None:
        return self.process.returncode

    def poll(self) -> int | None:
        return self.process.poll()

    def wait(self, timeout: float | None = None) -> int:
        return self.process.wait(timeout)

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        return self.stdout.read_text(), self.stderr.read_text()


class BenchForks:
    """The zygote, for commands whose output files go to ``folder``; close it when done (it kills a command still
    running: a test that failed midway)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self._count = 0
        self.zygote = Zygote(PRELOAD)

    def start(self, argv: list[str]) -> ForkedBench:
        """Fork ``bench *argv``; returns once the child exists."""
        self._count += 1
        stdout, stderr = (self.folder / f"bench-{self._count}.{name}" for name in ("out", "err"))
        with open(stdout, "w") as out, open(stderr, "w") as err:
            process = self.zygote.popen([sys.executable, "-m", "bench", *argv], stdout=out, stderr=err)
        assert isinstance(process, ForkedProcess), process
        return ForkedBench(process, stdout, stderr)

    def close(self) -> None:
        self.zygote.close()
