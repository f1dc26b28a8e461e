"""The simulator's own verbs (``SIMTRUE``, ``SIMLEGS``, ``SIMTRACE``, ``SIMLOAD``), spoken over a real pkm5 driver.

Only pretend hardware knows its truth, so these live here and not in :mod:`bench.robots.pkm5`: the driver offers
``query`` for verbs it does not know, and this client turns the replies into numbers. Simulated sensors and the
simulated operator use it; a rig built from a station (the hardware path) never does, and the simulator can be told
to refuse these verbs (``--no-sim-verbs``) so a test proves it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.errors import ConfigError, LinkError
from bench.robots import pkm5_wire as wire
from bench.robots.link import WireProtocolError
from bench.simulators.dynamics import trace_times

__all__ = ["SimulatorClient"]


def _checked(name: str, value: float, low: float, high: float) -> float:
    if not low <= value <= high:
        raise ConfigError(f"{name} = {value!r}, expected a number in [{low:g}, {high:g}]")
    return value


class SimulatorClient:
    """Truth queries to a ``bench sim pkm5`` controller through an open :class:`~bench.robots.pkm5.Pkm5Controller`.

    With ``truth_log`` (the file the simulator was started with ``--truth``), :meth:`true_pose` reads the pose from
    the log's newest entry instead of asking ``SIMTRUE``: the simulator writes that entry before it sends the
    ``DONE`` (or the ``STOP``/``SETPOS`` reply) it belongs to, so it is the pose ``SIMTRUE`` answers, given to the
    same 4 decimals; a file read instead of a pty round trip that wakes the simulator between two moves. Before the
    first move the log is empty and ``SIMTRUE`` answers.
    """

    def __init__(self, controller: Any, truth_log: str | None = None) -> None:
        self.controller = controller
        self.truth_log = truth_log

    @property
    def _port(self) -> str:
        return self.controller.link.port_name

    def true_pose(self) -> np.ndarray:
        """The true attained pose (x_mm, y_mm, z_mm, alpha_deg, beta_deg), shape (5,)."""
        if self.truth_log is not None:
            from bench.simulators.pty import read_last_truth

            entry = read_last_truth(self.truth_log)
            if entry is not None:  # SIMTRUE's own rounding (f"{v:.4f}"), so both give the same numbers
                return np.array([float(f"{v:.4f}") for v in entry["pose"]], dtype=float)
        reply = self.controller.query("SIMTRUE")
        try:
            return np.array([float(f) for f in reply.fields[1:6]], dtype=float)
        except ValueError as exc:
            raise WireProtocolError(f"{self._port}: SIMTRUE reply {reply} is not 5 numbers") from exc

    def true_strokes(self) -> np.ndarray:
        """Actuator bench only: the true stroke of each actuator, mm, shape (6,)."""
        try:
            return self._numbers("SIMTRUE", wire.AXES)
        except LinkError as exc:
            raise LinkError(f"{exc} strokes (is the simulator running with --fixture actuator-bench?)") from None

    def true_lengths(self) -> np.ndarray:
        """Assembled robot: the true, perturbed leg lengths after the last move, mm, shape (6,)."""
        return self._numbers("SIMLEGS", wire.AXES)

    def trace(self, rate_hz: int, lead_s: float, hold_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The true arrival of the last move, sampled at ``rate_hz`` from ``lead_s`` before the move ended to
        ``hold_s`` after; returns times (n,) in simulated s relative to the move's end and poses (n, 5)."""
        _checked("rate_hz", rate_hz, 1, 10_000)
        _checked("lead_s", lead_s, 0.0, 60.0)
        _checked("hold_s", hold_s, 0.0, 60.0)
        window = (int(rate_hz), round(lead_s * 1000), round(hold_s * 1000))
        first = self.controller.query("SIMTRACE", window + (0,))
        times = trace_times(window[0], window[1] / 1000.0, window[2] / 1000.0)
        if int(first.fields[1]) != len(times):
            raise WireProtocolError(
                f"{self._port}: SIMTRACE announced {first.fields[1]} samples, expected {len(times)} for {window}"
            )
        rest = self.controller.query_many("SIMTRACE", [window + (index,) for index in range(1, len(times))])
        return times, np.array([self._trace_fields(reply) for reply in (first, *rest)], dtype=float)

    def _trace_fields(self, reply: Any) -> list[float]:
        try:
            return [float(f) for f in reply.fields[3:]]
        except ValueError as exc:
            raise WireProtocolError(f"{self._port}: SIMTRACE reply {reply} is not numbers") from exc

    def _numbers(self, verb: str, count: int) -> np.ndarray:
        reply = self.controller.query(verb)
        try:
            values = np.array([float(f) for f in reply.fields[1:]], dtype=float)
        except ValueError as exc:
            raise WireProtocolError(f"{self._port}: {verb} reply {reply} is not numbers") from exc
        if values.shape != (count,):
            raise LinkError(f"{self._port}: {verb} answered {len(values)} numbers, expected {count}")
        return values

    def set_load(self, load_kg: float) -> None:
        """The payload carried by the end effector, kg (0-30)."""
        _checked("load_kg", load_kg, 0.0, 30.0)
        self.controller.query("SIMLOAD", (round(load_kg * 1000),))
