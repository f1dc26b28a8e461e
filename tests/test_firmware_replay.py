"""The same raw command lines (tests/pkm5_replay.py) replayed against the pkm5 firmware on the emulated ATmega2560 and
against the simulator started as a user starts it (``python -m bench.simulators.pkm5``) get the same reply lines,
timing fields aside: malformed input of every kind, tags of every size and sign, BUSY during a move, STOP mid-move.
Skipped, with the reason, where gcc-avr / avr-libc / simavr are not installed (.ci/run installs them)."""

import time

import pytest
import serial

from bench.robots import pkm5_wire as wire
from tests.firmware_sim import EmulatedController, build, needs_toolchain, serve_simulator
from tests.pkm5_replay import SCRIPT

pytestmark = needs_toolchain


def masked(body: str, timing: bool) -> str:
    """A reply body with its firmware version (ID, BOOT) and, for a timing step, its integer fields blanked."""
    if body.startswith("v2: "):
        return "v2: " + masked(body[4:], timing)
    fields = body.split(" ")
    if fields[:3] == ["OK", fields[1], "ID"] or fields[0] == "BOOT":
        fields[-1] = "<version>"
    if timing:
        keep = 4 if fields[0] == "ERR" else 2  # the code of an ERR stays
        fields = fields[:keep] + ["<n>" if f.lstrip("-").isdigit() else f for f in fields[keep:]]
    return " ".join(fields)


def decode(line):
    """The body of a reply line in either framing, v2 marked (every line must verify in one of them)."""
    try:
        return wire.decode_line(line, 1)
    except wire.CommandRefused:
        return "v2: " + wire.decode_line(line, 2)


def read_lines(port, count, timeout_s):
    """``count`` reply lines (wait up to ``timeout_s``), then whatever else arrives within a short quiet time."""
    data, deadline = b"", time.monotonic() + timeout_s
    while data.count(b"\n") < count and time.monotonic() < deadline:
        data += port.read(256)
    quiet = time.monotonic() + 0.1
    while time.monotonic() < quiet:
        chunk = port.read(256)
        data += chunk
        if chunk:
            quiet = time.monotonic() + 0.1
    return data.splitlines()


def replay(port, counts=None, timeout_s=1.0):
    """Replies to each step of SCRIPT, as decoded bodies (every checksum must verify)."""
    read_lines(port, 1, 0.5)  # the BOOT line, if it has not been missed
    replies = []
    for i, (raw, timing) in enumerate(SCRIPT):
        port.write(raw)
        lines = read_lines(port, 1 if counts is None else counts[i], timeout_s)
        replies.append([masked(decode(line), timing) for line in lines])
    return replies


@pytest.fixture(scope="module")
def simulator_replies():
    process, path = serve_simulator()
    try:
        with serial.serial_for_url(path, baudrate=115200, timeout=0.02) as port:
            return replay(port)
    finally:
        process.terminate()
        process.wait(timeout=10)


@pytest.mark.slow
def test_firmware_and_simulator_answer_the_script_alike(simulator_replies, tmp_path, tmp_path_factory):
    built = build(tmp_path_factory, WATCHDOG_MS=5000)  # no heartbeat in a replay: a patient watchdog
    controller = EmulatedController(built.elf, built.harness, tmp_path / "events.txt")
    try:
        with controller.open(timeout_s=0.02) as port:
            firmware = replay(port, [len(r) for r in simulator_replies], timeout_s=10.0)
    finally:
        controller.close()
    mismatches = [(SCRIPT[i][0], f, s) for i, (f, s) in enumerate(zip(firmware, simulator_replies)) if f != s]
    assert mismatches == []


def test_the_script_covers_what_the_protocol_document_promises(simulator_replies):
    flat = [line for replies in simulator_replies for line in replies]
    assert simulator_replies[0] == []  # an empty line is ignored
    assert simulator_replies[3:9] == [["ERR #0 2 CHECKSUM"]] * 3 + [
        ["ERR #0 2 CHECKSUM"],
        ["ERR #5 1 SYNTAX"],
        ["ERR #0 2 CHECKSUM"],
    ]
    assert simulator_replies[9] == ["ERR #7 1 SYNTAX"] and simulator_replies[11] == ["ERR #0 3 TOO_LONG"]
    assert simulator_replies[12][0].startswith("OK #12 POS") and simulator_replies[13] == ["ERR #0 3 TOO_LONG"]
    assert [r[0].split(" ")[1] for r in simulator_replies[15:25]] == [
        "#0",
        "#9",
        "#999999999",
        "#0",
        "#0",
        "#0",
        "#0",
        "#7",
        "#0",
        "#0",
    ]
    assert "ERR #31 7 BUSY" in flat and "ERR #30 8 STOPPED <n> <n> <n> <n> <n> <n>" in flat
    assert "OK #40 MOVE 0" in flat and "DONE #40 1000 1000 1000 1000 2000 2000" in flat
    assert simulator_replies[-13:] == [
        ["ERR #50 4 ARGUMENT"],
        ["OK #51 PROTOCOL 2"],
        ["v2: OK #52 ID bench-pkm5 3 <version>"],
        ["v2: ERR #0 2 CHECKSUM"],
        ["v2: ERR #0 2 CHECKSUM"],
        ["v2: ERR #0 2 CHECKSUM"],
        ["v2: ERR #0 2 CHECKSUM"],
        ["v2: ERR #57 1 SYNTAX"],
        ["v2: ERR #0 1 SYNTAX"],
        ["v2: ERR #0 3 TOO_LONG"],
        ["v2: ERR #0 2 CHECKSUM"],
        ["v2: ERR #61 4 ARGUMENT"],
        ["v2: OK #62 POS 1000 1000 1000 1000 2000 2000 DISABLED"],
    ]
