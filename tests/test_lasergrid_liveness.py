"""Drills: a laser grid that goes silent, whose device closes (EOF) or that freezes mid-run ends the run ``failed``
with the reason at the first capture after it did, never ``completed`` with stale readings (issue 32).

The robot is the real :class:`bench.robots.delta4.Delta4Controller` driver over an in-process port to the delta4
firmware emulator (:class:`bench.simulators.delta4.Delta4SimDevice`, ideal geometry, its laser-grid simulator);
the instrument is the real :class:`bench.rigs.lasergrid.LaserGridInstrument`. After ``HEALTHY`` settled moves the
drill silences the grid's reports (the controller still answers), closes the device, or latches the last report.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pytest

from bench.protocols import Rig, Runner
from bench.protocols.delta import DeltaPositioning
from bench.rigs.lasergrid import LaserGridInstrument
from bench.rigs.movers import DeltaMover
from bench.robots.delta4 import Delta4Controller
from bench.robots.testing import ScriptedPort
from bench.simulators import delta4 as sim_delta4
from bench.store import Store

SEED = 4  # P1 and P3 lit on the horizontal screen, P3 on the vertical one, P2 blind (tests/test_delta_positioning.py)
HEALTHY = 4  # settled moves before the drill: the 4th is the second cycle's P1, a pose with sensors lit


class DevicePort(ScriptedPort):
    """A pyserial stand-in wired to a firmware emulator in this process (its clock: time.monotonic): what the
    emulator sends is what the port reads; ``closed_device`` makes it fail as a vanished USB serial device does."""

    def __init__(self, device) -> None:
        super().__init__([], name="emulator://delta4")
        self.device, self.baudrate = device, 9600
        self.closed_device = False

    def _pull(self) -> None:
        if self.closed_device:
            raise OSError(5, "Input/output error")
        self._readable += self.device.tick(time.monotonic())

    def write(self, data: bytes) -> int:
        if self.closed_device:
            raise OSError(5, "Input/output error")
        self._readable += self.device.feed(bytes(data), time.monotonic())
        return len(data)

    @property
    def in_waiting(self) -> int:
        self._pull()
        return len(self._readable)

    def read(self, size: int = 1) -> bytes:
        self._pull()
        return super().read(size)


class NoPrompts:
    def ask(self, prompt):
        return None


def _device(drill: str):
    parser = argparse.ArgumentParser()
    sim_delta4.add_arguments(parser)
    device = sim_delta4.build_device(parser.parse_args(["--ideal", "--seed", str(SEED), "--speed-factor", "2000"]))
    port = DevicePort(device)
    plant, sensor, report = device.plant, device.sensor, device._report
    state = {"moves": 0, "latched": None}  # settled moves (the plant is read once per settle)

    def counting_plant(*args):
        state["moves"] += 1
        if drill == "eof" and state["moves"] > HEALTHY:
            port.closed_device = True
        return plant(*args)

    def drilled_sensor(pose):
        if drill == "frozen" and state["moves"] > HEALTHY:
            return state["latched"]
        state["latched"] = sensor(pose)
        return state["latched"]

    def drilled_report():
        return b"" if drill == "silent" and state["moves"] > HEALTHY else report()

    device.plant, device.sensor, device._report = counting_plant, drilled_sensor, drilled_report
    return port


def _run(tmp_path, drill: str):
    controller = Delta4Controller(_device(drill), settle_timeout_s=2.0)
    controller.start()
    instrument = LaserGridInstrument(controller)  # the default 2 s wait for a report begun after the capture
    rig = Rig(DeltaMover(controller), instrument, NoPrompts(), speed_factor=1e6, sleep=lambda s: None, closers=[])
    with Store(tmp_path / "bench.db") as store:
        result = Runner(rig, store).run(DeltaPositioning(cycles=3))
        samples = store.samples(result.run_id)
    return result, [s for s in samples if "horizontal_valid" in s.values]


def _check_rows(rows) -> None:
    """Every stored axis is the commanded one (ideal geometry: the grid reads it to its 2.5 mm phase)."""
    for row in rows:
        for axis in "xyz":
            if f"{axis}_mm" in row.values:
                assert row.values[f"{axis}_mm"] == pytest.approx(row.values[f"cmd_{axis}_mm"], abs=1.3)


def test_a_healthy_grid_completes_the_run(tmp_path):
    result, rows = _run(tmp_path, "")
    assert result.exit_status == "completed" and len(rows) == 9
    assert any("x_mm" in r.values for r in rows)
    _check_rows(rows)


@pytest.mark.parametrize(
    "drill, what",
    [
        ("silent", "no reply to 'sensor report'"),
        ("eof", "Input/output error"),
        ("frozen", "lights the sensors of the previous pose's"),
    ],
)
def test_a_stalled_grid_fails_the_run_at_the_first_capture_after_it_stalled(tmp_path, drill, what):
    result, rows = _run(tmp_path, drill)
    assert result.exit_status == "failed", result
    assert what in result.reason
    assert len(rows) == HEALTHY  # the captures before the stall, every one right; none after it
    _check_rows(rows)
    assert np.all([r.values["cmd_x_mm"] is not None for r in rows])
