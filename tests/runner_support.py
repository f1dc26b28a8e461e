"""Helpers for runner tests that act from another thread (an emergency stop, an abort): bounded waits only."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from bench.errors import ConfigError
from bench.protocols import Runner
from bench.store import Store


class StandInMover:
    """What the stand-in robots of the runner tests share to be a :class:`bench.rigs.interfaces.Mover`: a pkm5
    commanding by the documented geometry, without an actuator bench, whose emergency stop is its plain stop."""

    kind = "pkm5"
    geometry = None

    def move_actuator(self, axis, stroke_mm, *, velocity_pct):
        raise ConfigError(f"actuator {axis}: this stand-in has no actuator-bench mode")

    def emergency_stop(self):
        self.stop()


#: Longest wait for a run to end once told to; an interrupted 600 s settle or an endless move exceed it.
END_TIMEOUT_S = 30.0


def wait_until(predicate: Callable[[], bool], what: str, timeout_s: float = 10.0) -> None:
    """Poll ``predicate`` until true; fail naming ``what`` after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        assert time.monotonic() < deadline, f"timed out after {timeout_s:g} s waiting for {what}"
        time.sleep(0.002)


class RunInThread:
    """Runs ``protocol`` on ``rig`` in a thread named ``runner-thread`` with its own store connection, as the
    window's worker does; ``runner`` is ready when the constructor returns."""

    def __init__(self, path, rig, protocol) -> None:
        self.runner: Runner | None = None
        self.result = None
        ready = threading.Event()

        def work() -> None:
            with Store(path) as store:
                self.runner = Runner(rig, store)
                ready.set()
                self.result = self.runner.run(protocol)

        self.thread = threading.Thread(target=work, name="runner-thread", daemon=True)
        self.thread.start()
        assert ready.wait(10), "the runner thread did not start"

    def finished(self):
        """The run's result, once the thread has ended (fails after :data:`END_TIMEOUT_S`)."""
        self.thread.join(END_TIMEOUT_S)
        assert not self.thread.is_alive(), f"the run did not end within {END_TIMEOUT_S:g} s"
        return self.result
