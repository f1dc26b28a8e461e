"""The window's software emergency stop: a latch that a thread of its own takes to the wire.

Pressing the stop (:meth:`EmergencyStop.press`) only sets two ``threading.Event`` objects and returns: it never
waits, so the window's thread (which also draws, opens dialogs and closes the window) can press it from any state.
The stop thread, which does nothing else, wakes on the press and calls every registered stop function: the
campaign worker's (the runner's latching ``emergency_stop``, which writes ``STOP`` on the controller's link from this
thread, at once) and the jogging robot's (its mover's latching ``emergency_stop``). A driver's stop may block until
the controller acknowledges it (about a second at most): it blocks this thread only, never the window.

The latch stays set after the stop went out: no run starts and no jog moves until the operator resets it
(:meth:`reset`, the window's "Reset e-stop" after checking the robot). A function registered while the latch is
set (a worker whose rig was still starting) is stopped at once by the stop thread.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable

__all__ = ["HANDOFF_S", "EmergencyStop"]

_log = logging.getLogger(__name__)

#: How long the window's thread lets the stop thread go first after a press, s (it redraws nothing meanwhile; the
#: stop never waits for the window).
HANDOFF_S = 0.05


class EmergencyStop:
    """The latch and its stop thread (started on construction, a daemon: it never keeps the process alive).

    Attributes
    ----------
    pressed_at_s : float or None
        ``time.perf_counter()`` of the last press (for the stop-latency benchmark).
    """

    def __init__(self) -> None:
        self._latched = threading.Event()
        self._wake = threading.Event()
        # copy-on-write: the stop thread reads the tuple without a lock the window's thread could hold
        self._targets: tuple[Callable[[], None], ...] = ()
        self._lock = threading.Lock()  # only between registrations (window thread, worker start), never the stop
        self.pressed_at_s: float | None = None
        self.presses = 0
        self._served: deque[threading.Event] = deque()  # each press's "the stop thread has called every target"
        self._thread = threading.Thread(target=self._serve, name="bench-emergency-stop", daemon=True)
        self._thread.start()

    @property
    def latched(self) -> bool:
        return self._latched.is_set()

    def press(self, handoff_s: float = 0.0) -> bool:
        """Latch and wake the stop thread (safe from any thread, any number of times, never blocks beyond
        ``handoff_s``).

        ``handoff_s``: wait up to this long for the stop thread to have called every stop (the window's thread
        passes :data:`HANDOFF_S`: on a loaded PC its own work right after a press, e.g. the jog panel's pre-flight,
        would otherwise compete with the stop thread for the interpreter lock). True when it had."""
        served = threading.Event()
        self._served.append(served)
        self.pressed_at_s = time.perf_counter()
        self.presses += 1
        self._latched.set()
        self._wake.set()
        return served.wait(handoff_s) if handoff_s > 0 else False

    def reset(self) -> None:
        """The operator checked the robot: runs and jogs may start again (each robot's own latch is released by
        its owner: a new run's rig is a fresh one, the jog robot's ``release_stop``)."""
        self._latched.clear()

    def register(self, stop: Callable[[], None]) -> None:
        """Call ``stop()`` on the stop thread at every press; now too, if the latch is set already."""
        with self._lock:
            self._targets = (*self._targets, stop)
        if self._latched.is_set():
            self._wake.set()

    def unregister(self, stop: Callable[[], None]) -> None:
        with self._lock:
            self._targets = tuple(t for t in self._targets if t != stop)  # bound methods: equal, not identical

    def _serve(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            served = []
            while self._served:
                served.append(self._served.popleft())
            for stop in self._targets:
                try:
                    stop()
                except Exception:  # noqa: BLE001 - one failed target never keeps the stop from the others
                    _log.exception("emergency stop: %r failed", stop)
            for event in served:
                event.set()
