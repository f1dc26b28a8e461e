"""Gauges: readings that come from a calliper or depth gauge rather than from a capture.

A typed calliper is the operator: the prompt asks and the person types (``[calliper] kind = "typed"``). A serial
calliper answers the reading prompts itself (:class:`GaugeOperator`): the prompt is shown, the person presses the
gauge's data button (or the interface answers its request string), and the line it sends is the reading; the
instructions (mount, zero, load) still go to the person. The actuator bench has no capture instrument at all
(:class:`CalliperOnly`).
"""

from __future__ import annotations

import sys
from typing import Any

from bench.errors import LinkError
from bench.rigs.interfaces import Entry, Measurement, Operator
from bench.steps import Capture, Prompt

__all__ = ["CalliperOnly", "GaugeOperator"]


class CalliperOnly:
    """The instrument of the actuator bench: every reading is a calliper (depth gauge) entry, so no capture."""

    def __init__(self, calliper: dict[str, Any] | None = None) -> None:
        self.calliper = dict(calliper or {})

    def measure(self, capture: Capture) -> Measurement:
        raise LinkError(
            f"actuator bench: no instrument for capture {capture.kind!r} at {capture.pose!r}; readings "
            "are calliper entries"
        )

    def settings(self) -> dict[str, Any]:
        return {"instrument": "depth gauge / calliper entries (actuator bench, 000 §8.4)", **self.calliper}


class GaugeOperator:
    """Reading prompts answered by a serial calliper (:class:`bench.sensors.calliper.SerialCalliper`), the rest by
    ``person``. A reading outside the prompt's bounds is refused and the gauge read again (the person re-seats it)."""

    def __init__(self, gauge: Any, person: Operator, *, timeout_s: float = 60.0, attempts: int = 3) -> None:
        self.gauge, self.person, self.timeout_s, self.attempts = gauge, person, timeout_s, attempts

    def ask(self, prompt: Prompt) -> float | None:
        if prompt.field is None:
            return self.person.ask(prompt)
        for _ in range(self.attempts):
            print(f"{prompt.text}: press the calliper's data button", file=sys.stderr, flush=True)
            reading = self.gauge.read(self.timeout_s)
            value = Entry(float(reading.value), str(reading.raw).strip())
            low, high = prompt.minimum, prompt.maximum
            if (low is None or value >= low) and (high is None or value <= high):
                return value
            print(
                f"  {prompt.field} = {value:g} from the calliper, expected a value in [{low}, {high}]; read again",
                file=sys.stderr,
                flush=True,
            )
        raise LinkError(
            f"calliper: {prompt.field} out of [{prompt.minimum}, {prompt.maximum}] on "
            f"{self.attempts} readings in a row ({prompt.text})"
        )
