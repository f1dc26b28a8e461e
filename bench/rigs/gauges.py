"""Gauges: readings that come from a calliper or depth gauge rather than from a capture.

A typed calliper is the operator: the prompt asks and the person types (``[calliper] kind = "typed"``). A serial
calliper answers the reading prompts itself (:class:`GaugeOperator`): the prompt is shown, the person presses the
gauge's data button (or the interface answers its request string), and the line it sends is the reading; the
instructions (mount, zero, load) still go to the person. The actuator bench has no capture instrument at all
(:class:`CalliperOnly`).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from bench.errors import LinkError
from bench.rigs.interfaces import Entry, Measurement, Operator
from bench.steps import Capture, Prompt

if TYPE_CHECKING:
    from bench.rigs.check import DeviceCheck
    from bench.rigs.opening import SensorOpening
    from bench.rigs.station import Station, StationTable

__all__ = ["CalliperOnly", "CalliperSpec", "GaugeOperator", "calliper_operator", "check_calliper", "parse_calliper"]

#: How a calliper's readings reach bench: typed at the prompt, or sent on a serial line.
CALLIPER_KINDS = ("typed", "serial")


@dataclass(frozen=True)
class CalliperSpec:
    """Readings the operator takes: typed at the prompt, or sent by a serial calliper (data button or request)."""

    kind: str = "typed"
    port: str = ""
    baud: int = 9600
    request: str = ""  #: sent before each reading by interfaces that answer requests; empty for push-button cables
    terminator: str = "\n"
    resolution_mm: float = 0.01
    timeout_s: float = 60.0


def parse_calliper(table: StationTable) -> CalliperSpec:
    """``[calliper]`` of a station file; a serial calliper names its port."""
    kind = table.choice("kind", CALLIPER_KINDS, "typed")
    defaults = CalliperSpec()
    return CalliperSpec(
        kind=kind,
        port=table.get(
            "port", str, "", required=kind == "serial", expected='the calliper\'s serial port (kind = "serial")'
        ),
        baud=table.baud("baud", defaults.baud),
        request=table.get("request", str, "", blank_ok=True),
        terminator=table.get("terminator", str, defaults.terminator, blank_ok=True),
        resolution_mm=table.number("resolution_mm", defaults.resolution_mm),
        timeout_s=table.number("timeout_s", defaults.timeout_s),
    )


def calliper_operator(opening: SensorOpening, person: Operator) -> Operator:
    """A serial calliper answers the reading prompts itself (the rest go to ``person``); a typed one is the person."""
    spec: CalliperSpec = opening.spec
    if spec.kind != "serial":
        return person
    from bench.sensors.calliper import SerialCalliper

    port = opening.port("calliper.port", spec.port, spec.baud)
    gauge = SerialCalliper(port, request=spec.request.encode(), terminator=spec.terminator.encode())
    return GaugeOperator(gauge, person, timeout_s=spec.timeout_s)


def check_calliper(station: Station, spec: CalliperSpec) -> list[DeviceCheck]:
    """A serial calliper's port opened once; a typed calliper has no device."""
    from bench.rigs.check import DeviceCheck, guarded
    from bench.robots.link import open_port

    if spec.kind != "serial":
        return [DeviceCheck("calliper", "typed", True, "readings typed at the prompt")]

    def opens() -> str:
        open_port(spec.port, baudrate=spec.baud, timeout=0.05, exclusive=True).close()
        return f"opened at {spec.baud} baud (press the data button during a run)"

    return [guarded("calliper.port", spec.port, "serial", opens)]


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
