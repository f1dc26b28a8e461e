"""The firmware (firmware/pkm5/pkm5.ino), built for the host with stand-ins for the Arduino core and
AccelStepper (tests/firmware_host/), answers a command script byte for byte like the simulated controller.
Skipped where no C++ compiler is installed."""

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bench.robots import pkm5_wire as wire
from bench.simulators.pkm5 import Pkm5SimDevice

HERE = Path(__file__).parent
COMPILER = shutil.which("g++") or shutil.which("c++")

SCRIPT = [
    "ID #1", "POS #2", "MOVE 900 800 800 800 1600 1600 200 #3", "ENABLE #4", "MOVE 900 800 800 800 1600 1600 200 #5",
    "POS #6", "MOVE 99999 800 800 800 1600 1600 200 #7", "MOVE 900 800 800 800 1600 1600 0 #8", "JUMP #9",
    "MOVE 1 2 #10", "SETPOS 1000 1000 1000 1000 2000 2000 #11", "POS #12", "STOP #13", "SIMTRUE #14",
    "DISABLE #15", "POS #16",
]
RAW_LINES = [b"POS #17*00\n", b"Q" * 200 + b"\n"]


@pytest.fixture(scope="module")
def firmware(tmp_path_factory):
    if COMPILER is None:
        pytest.skip("no C++ compiler to build the firmware for the host")
    binary = tmp_path_factory.mktemp("firmware") / "pkm5_host"
    subprocess.run([COMPILER, "-std=c++17", "-Wall", "-Wextra", "-Werror", "-I", str(HERE / "firmware_host"),
                    "-o", str(binary), str(HERE / "firmware_host" / "host_main.cpp")], check=True, timeout=120)
    return binary


def simulator_replies(raw):
    device = Pkm5SimDevice(lambda steps, load: np.zeros(5), speed_factor=1.0)
    out = device.tick(0.0)
    for i, line in enumerate(raw.splitlines(keepends=True)):
        out += device.feed(line, 1000.0 * i) + device.tick(1000.0 * i + 999.0)
    return out


def test_firmware_and_simulator_speak_the_same_bytes(firmware):
    raw = b"".join(wire.encode_line(body) for body in SCRIPT) + b"".join(RAW_LINES)
    replies = subprocess.run([str(firmware)], input=raw, capture_output=True, check=True, timeout=30).stdout
    firmware_lines = [wire.decode_line(line) for line in replies.splitlines()]  # every checksum verifies
    simulator_lines = [wire.decode_line(line).replace("1.0.0-sim", "1.0.0")
                       for line in simulator_replies(raw).splitlines()]
    # the one intended difference: SIMTRUE is simulator-only, the firmware refuses it
    simulator_lines[simulator_lines.index("OK #14 SIMTRUE 0.0000 0.0000 0.0000 0.0000 0.0000")] = "ERR #14 1 SYNTAX"
    assert firmware_lines == simulator_lines
    assert firmware_lines[5:7] == ["OK #5 MOVE 500", "DONE #5 900 800 800 800 1600 1600"]  # 100 steps at 200/s
