"""Helpers of the firmware-in-the-loop tests: build a firmware and its simavr harness (firmware/Makefile), run the pkm5
firmware on an emulated ATmega2560 with UART0 on a pseudo-terminal, and read the harness's pin-edge log."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import serial

ROOT = Path(__file__).resolve().parents[1]
F_CPU_HZ = 16_000_000
#: Build options of the firmware under test (firmware/Makefile defaults; docs/firmware.md)
ACCEL_STEPS_S2 = 4000
DRIVERS_ENABLED_LEVEL = 1


def missing_toolchain() -> str | None:
    """Why the emulation tests cannot run here, or None."""
    for tool in ("avr-gcc", "avr-size", "make", "cc"):
        if shutil.which(tool) is None:
            return f"{tool} not installed (apt-get install gcc-avr avr-libc simavr libsimavr-dev libsimavrparts1)"
    if not Path("/usr/include/simavr/sim_avr.h").exists():
        return "simavr headers not installed (apt-get install libsimavr-dev libsimavrparts1)"
    return None


class Build(NamedTuple):
    elf: Path
    harness: Path
    output: str  #: make's output for the firmware, with avr-size's flash / RAM use


_builds: dict[tuple, Build] = {}
_harnesses: dict[tuple, Path] = {}


def _make(out_dir: Path, targets: list[str], options: dict[str, object]) -> str:
    done = subprocess.run(
        [
            "make",
            "-C",
            str(ROOT / "firmware"),
            f"BUILD={out_dir}",
            *(str(out_dir / target) for target in targets),
            *(f"{k}={v}" for k, v in options.items()),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    if done.returncode:
        raise AssertionError(f"firmware build failed:\n{done.stdout}\n{done.stderr}")
    return done.stdout


def build(tmp_path_factory: pytest.TempPathFactory, firmware: str = "pkm5", **options: object) -> Build:
    """``firmware`` (pkm5, delta4: firmware/Makefile) built with the make variables ``options`` (e.g.
    WATCHDOG_MS=5000), and its simavr harness, into the session's temporary directory. Each is built once per test
    session: a build depends only on the sources and the options, and the harness on none of the options (the
    Makefile compiles it without them), so every build of one firmware shares one harness."""
    base = tmp_path_factory.getbasetemp()
    key = (base, firmware, tuple(sorted(options.items())))
    if key not in _builds:
        if (base, firmware) not in _harnesses:
            harness_dir = tmp_path_factory.mktemp(f"{firmware}_harness")
            _make(harness_dir, [f"{firmware}_harness"], {})
            _harnesses[base, firmware] = harness_dir / f"{firmware}_harness"
        out_dir = tmp_path_factory.mktemp(firmware)
        output = _make(out_dir, [f"{firmware}.elf", f"{firmware}.hex"], options)
        _builds[key] = Build(out_dir / f"{firmware}.elf", _harnesses[base, firmware], output)
    return _builds[key]


@dataclass
class Edge:
    t_s: float
    kind: str
    axis: int
    level: int
    line: bytes = b""


def start_harness(harness: Path, elf: Path, events: Path, **popen: object) -> tuple[subprocess.Popen, str]:
    """Start a simavr harness on ``elf``; returns the process and the pty it printed (``PTY /dev/pts/N``)."""
    process = subprocess.Popen(
        [str(harness), str(elf), str(events)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, **popen
    )
    for line in process.stdout:
        if line.startswith("PTY "):
            return process, line.split()[1]
    raise AssertionError("harness printed no PTY line")


class EmulatedController:
    """The firmware running in the harness: ``.path`` is its pty; :meth:`close` stops it and returns the events."""

    def __init__(self, elf: Path, harness: Path, events: Path, **popen: object) -> None:
        self.events = events
        self.process, self.path = start_harness(harness, elf, events, **popen)

    def open(self, timeout_s: float = 0.05) -> serial.Serial:
        return serial.serial_for_url(self.path, baudrate=115200, timeout=timeout_s)

    def close(self) -> list[Edge]:
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)
        return read_events(self.events)


def read_events(path: Path) -> list[Edge]:
    edges = []
    text = path.read_text()
    for line in text[: text.rfind("\n") + 1].splitlines():  # complete lines: the harness may be writing
        fields = line.split()
        if fields[1] in ("RX", "TX"):  # a line received / (script mode) sent by the MCU
            line = b"" if fields[2] == "-" else bytes.fromhex(fields[2])
            edges.append(Edge(int(fields[0]) / F_CPU_HZ, fields[1], 0, 0, line))
        else:
            edges.append(Edge(int(fields[0]) / F_CPU_HZ, fields[1], int(fields[2]), int(fields[3])))
    return edges


def step_times(edges: list[Edge], axis: int) -> np.ndarray:
    """Emulated times of the rising STEP edges of ``axis`` (1-6), s."""
    return np.array([e.t_s for e in edges if e.kind == "STEP" and e.axis == axis and e.level == 1])


def serve_simulator() -> tuple[subprocess.Popen, str]:
    """``python -m bench.simulators.pkm5 --ideal`` started as a user would; returns the process and its pty path."""
    process = subprocess.Popen(
        [sys.executable, "-m", "bench.simulators.pkm5", "--ideal"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    return process, process.stdout.readline().strip()


def exchange(port: serial.Serial, raw: bytes, settle_s: float = 0.15) -> list[bytes]:
    """Write ``raw`` and collect every reply line until the port has been quiet for ``settle_s``."""
    port.write(raw)
    data = b""
    quiet_since = time.monotonic()
    while time.monotonic() - quiet_since < settle_s:
        chunk = port.read(512)
        if chunk:
            data += chunk
            quiet_since = time.monotonic()
    return data.splitlines()


toolchain_reason = missing_toolchain()
needs_toolchain = pytest.mark.skipif(toolchain_reason is not None, reason=f"firmware emulation: {toolchain_reason}")


def run_script(built: Build, events: Path, lines: list[tuple[float, bytes]], end_s: float) -> list[Edge]:
    """Run ``built`` in the harness's script mode: each ``(t_s, raw)`` of ``lines`` goes to UART0 at emulated time
    ``t_s`` (in order, as fast as the UART takes it), the run ends at ``end_s``; unpaced, so deterministic whatever
    the load of the machine. Returns the events, the MCU's reply lines as ``TX`` edges."""
    script = events.with_suffix(".script")
    with script.open("w") as out:
        for t_s, raw in lines:
            for i in range(0, len(raw), 1000):
                out.write(f"{round(t_s * 1e6)} {raw[i : i + 1000].hex()}\n")
        out.write(f"{round(end_s * 1e6)} END\n")
    subprocess.run(
        [str(built.harness), str(built.elf), str(events)],
        env=dict(os.environ, HARNESS_SCRIPT=str(script)),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        timeout=600,
        check=True,
    )
    return read_events(events)
