"""The delta4 firmware (firmware/delta4/delta4.c) built for the ATmega128 and run on an emulated MCU (simavr, through
firmware/sim/delta4_harness.c), driven by the project's own driver bench.robots.delta4.Delta4Controller. The harness
logs every servo PWM edge with its emulated time and plays the two laser-grid screens (74LS166 chains) lit from the
test; the assertions are on those pins and on the bytes the driver reads. One raw script is also replayed against
the firmware and against ``python -m bench.simulators.delta4``: the same replies, timing aside.

Skipped, with the reason, where gcc-avr / avr-libc / simavr are not installed (.ci/run installs them)."""

import subprocess
import sys
import time

import numpy as np
import pytest

from bench.robots import delta4_wire as wire
from bench.robots.delta4 import DEFAULT_BAUDRATE, HOME_MM, Delta4Controller
from bench.sensors.lasergrid import GridGeometry, decode_frame
from bench.simulators.lasergrid import LaserGridSimulator
from tests.firmware_sim import F_CPU_HZ, ROOT, build, needs_toolchain

pytestmark = needs_toolchain

#: the documented PWM (reference §5.2): no prescaler, 2 ms refresh; pulse mapping of firmware/delta4/delta4.c
PERIOD_TICKS = 32000
PULSE_AT_0_DEG_US, PULSE_AT_180_DEG_US = 1000.0, 2000.0
STOPS_DEG = (30.0, 170.0)
SLEW_DEG_S = 286.0
SLOW = {"settle_timeout_s": 20.0}


def expected_pulse_ticks(mapping: wire.ServoMapping, values) -> np.ndarray:
    """Pulse width, timer ticks (1/16 us), of the reference bytes ``values``: the angle the driver's mapping gives
    them, clamped to the calibrated stops, 1.0 ms at 0 deg to 2.0 ms at 180 deg, rounded half up."""
    angle = np.clip(mapping.to_deg(np.asarray(values, float)), *STOPS_DEG)
    pulse_us = PULSE_AT_0_DEG_US + angle * (PULSE_AT_180_DEG_US - PULSE_AT_0_DEG_US) / 180.0
    return np.floor(pulse_us * 16 + 0.5).astype(int)


class EmulatedDelta4:
    """The firmware in the harness: ``.path`` is its pty, :meth:`light` sets lit sensors, :meth:`close` returns
    the events as (cycle, kind, channel, value) tuples."""

    def __init__(self, built, events):
        elf, harness = built
        self.events = events
        self.process = subprocess.Popen([str(harness), str(elf), str(events)], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        for line in self.process.stdout:
            if line.startswith("PTY "):
                self.path = line.split()[1]
                break
        else:
            raise AssertionError("harness printed no PTY line")

    def open(self, timeout_s=0.05):
        import serial
        return serial.serial_for_url(self.path, baudrate=DEFAULT_BAUDRATE, timeout=timeout_s)

    def light(self, screen: str, indices) -> None:
        self.process.stdin.write(f"{screen} {' '.join(str(i) for i in indices)}\n")
        self.process.stdin.flush()

    def close(self):
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)
        text = self.events.read_text()
        rows = []
        for line in text[:text.rfind("\n") + 1].splitlines():
            cycle, kind, channel, *value = line.split()
            rows.append((int(cycle), kind, channel, value[0] if value else ""))
        return rows


def pulses(events, servo):
    """(rising-edge cycle, high time in cycles) of each pulse of ``servo`` (1-4)."""
    out, rise = [], None
    for cycle, kind, channel, value in events:
        if kind == "PWM" and channel == str(servo):
            if value == "1":
                rise = cycle
            elif rise is not None:
                out.append((rise, cycle - rise))
    return out


def received_at(events, byte: bytes):
    return [c for c, kind, channel, _ in events if kind == "RX" and bytes.fromhex(channel) == byte]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    elf, _, output = build(tmp_path_factory.mktemp("firmware"))
    return (elf.parent / "delta4.elf", elf.parent / "delta4_harness"), output


@pytest.fixture(scope="module")
def built_watchdog(tmp_path_factory):
    """Slow servos (30 deg/s) and a 200 ms link watchdog, so that a move outlasts the watchdog."""
    elf, _, _ = build(tmp_path_factory.mktemp("firmware_wd"), DELTA4_SLEW_DEG_S=30, DELTA4_WATCHDOG_MS=200)
    return elf.parent / "delta4.elf", elf.parent / "delta4_harness"


@pytest.fixture
def mcu(built, tmp_path):
    controller = EmulatedDelta4(built[0], tmp_path / "events.txt")
    yield controller
    controller.close()


def test_build_prints_flash_and_ram_use(built):
    section = built[1].split("Device: atmega128")[1]
    program = int(section.split("Program:")[1].split()[0])
    data = int(section.split("Data:")[1].split()[0])
    assert 1000 < program < 128 * 1024 and 50 < data < 4 * 1024  # ATmega128: 128 KiB flash, 4 KiB SRAM


# TV4 as the GUI sent it (whole-degree angles, reference §5.6: P081X Q072X R122X S128X) and TV1's exact angles
TEST_ANGLES_DEG = [(60.0, 54.0, 91.0, 95.0), (129.3, 126.6058, 73.7283, 78.5895)]


def test_pulse_widths_and_period_follow_the_documented_mapping_through_the_driver(mcu):
    mapping = wire.LegacyVbMapping()
    with Delta4Controller(mcu.open(), mapping=mapping, **SLOW) as robot:
        first = robot.start(verify_timeout_s=10.0)
        bytes_sent = [robot.move_servos(angles, require_settled=True).command_bytes for angles in TEST_ANGLES_DEG]
        frame = robot.read_sensor_frame(10.0)
    assert bytes_sent[0] == (81, 72, 122, 128)
    assert (first.horizontal, first.vertical, first.raw) == ((), (), b"hv")  # no laser lit: h then v
    assert (frame.horizontal, frame.vertical) == ((), ())
    events = mcu.close()
    ends = received_at(events, b"P")[1:] + [max(r for r, _ in pulses(events, 1)) + PERIOD_TICKS]
    assert len(ends) == 2
    for values, end in zip(bytes_sent, ends):
        expected = expected_pulse_ticks(mapping, values)
        for servo in range(4):
            at_rest = [p for p in pulses(events, servo + 1) if end - 8 * PERIOD_TICKS <= p[0] < end - PERIOD_TICKS]
            assert len(at_rest) >= 6  # z came after 10 periods at rest
            widths = np.array([w for _, w in at_rest])
            assert abs(np.median(widths) - expected[servo]) <= 1, (values, servo, widths)
            periods = np.diff([r for r, _ in at_rest])
            assert abs(np.median(periods) - PERIOD_TICKS) <= 1 and np.all(np.abs(periods - PERIOD_TICKS) <= 4)


def test_moves_are_slew_limited_and_z_follows_the_end(mcu):
    mapping = wire.LegacyVbMapping()
    with Delta4Controller(mcu.open(), mapping=mapping, **SLOW) as robot:
        robot.start(verify_timeout_s=10.0)
        low, high = np.array([40.0, 60.0, 60.0, 60.0]), np.array([150.0, 60.0, 60.0, 60.0])
        robot.move_servos(low, require_settled=True)
        robot.move_servos(high, require_settled=True)  # servo 1 only: 110 deg
    events = mcu.close()
    second = received_at(events, b"P")[1]
    start, end = (expected_pulse_ticks(mapping, mapping.to_bytes(a))[0] for a in (low, high))
    step_ticks = SLEW_DEG_S * 2e-3 * 16000 / 180  # 50.8 ticks per 2 ms period
    widths = np.array([w for r, w in pulses(events, 1) if r > second])
    moving = np.flatnonzero(np.abs(np.diff(widths)) > 4)
    assert widths[0] == pytest.approx(start, abs=2) and widths[-1] == pytest.approx(end, abs=2)
    assert abs(moving[-1] - moving[0] - (end - start) / step_ticks) <= 2  # it took travel / slew limit
    steps = np.diff(widths[moving[0] + 1:moving[-1]])
    assert np.all(np.abs(steps - step_ticks) <= 2), steps  # and never stepped faster


def test_laser_grid_hits_on_the_screen_inputs_are_reported_and_decode_as_the_document(mcu):
    geometry = GridGeometry()
    pose_mm = np.array([5.0, 5.0, -150.0])
    horizontal, vertical = LaserGridSimulator(geometry).observer()(pose_mm)
    assert horizontal and vertical
    with Delta4Controller(mcu.open(), **SLOW) as robot:
        robot.start(verify_timeout_s=10.0)
        mcu.light("H", [121])  # Fig. 10 a: BE over sensor (7, 7), moved 5 mm in +x: G5-a on (9, 7)
        mcu.light("V", [])
        time.sleep(0.3)
        frames = [robot.read_sensor_frame(10.0) for _ in range(6)]
        mcu.light("H", horizontal + (200, 17))
        mcu.light("V", vertical)
        time.sleep(0.3)
        later = [robot.read_sensor_frame(10.0) for _ in range(6)]
    assert (frames[-1].horizontal, frames[-1].vertical) == ((121,), ())
    decoded = decode_frame(geometry, frames[-1].horizontal, [], np.array([0.0, -5.0, -150.0]))
    assert decoded.position_mm[:2] == (0.0, -5.0) and decoded.horizontal.lasers == ("G5-a",)
    assert later[-1].horizontal == tuple(sorted(horizontal + (200, 17))) and later[-1].vertical == vertical
    decoded = decode_frame(geometry, [i for i in later[-1].horizontal if i in horizontal], later[-1].vertical,
                           pose_mm + [1.0, -1.0, 1.0])
    assert decoded.position_mm == tuple(pose_mm)
    events = mcu.close()
    on = [c for c, kind, channel, value in events if kind == "LASER" and channel == "1" and value == "1"]
    off = [c for c, kind, channel, value in events if kind == "LASER" and channel == "1" and value == "0"]
    assert len(on) >= 10
    assert np.all(np.array(off[:len(on)]) - np.array(on[:len(off)]) >= 1e-3 * F_CPU_HZ)  # 1 ms on before the load
    assert abs(np.median(np.diff(on)) / F_CPU_HZ - 0.080) < 0.003  # one frame per 80 ms (§5.5)


def test_watchdog_holds_the_servos_when_the_host_falls_silent(built_watchdog, tmp_path):
    mcu = EmulatedDelta4(built_watchdog, tmp_path / "events.txt")
    try:
        port = mcu.open()
        port.write(b"E" + wire.format_servo_command(0, 200))  # 96 -> 200: 77 deg at 30 deg/s, 2.6 s
        silent = read_for(port, 1.5)
        port.write(wire.format_servo_command(1, 60))  # servo 2: 96 -> 60, 27 deg in 0.9 s, with heartbeats
        beaten, deadline = b"", time.monotonic() + 20.0
        while b"z" not in beaten and time.monotonic() < deadline:
            beaten += read_for(port, 0.05)
            port.write(b"z")
        port.close()
    finally:
        events = mcu.close()
    assert b"z" not in silent  # the move was not confirmed
    assert b"z" in beaten  # heartbeats ('z', the ack byte) keep a move going to its end
    logged, second_move = received_at(events, b"X")[:2]
    # the harness logs a burst as it hands it to the UART, which delivers one byte per 10 bit times: X is 6th
    last_byte = logged + 6 * 10 / DEFAULT_BAUDRATE * F_CPU_HZ
    widths = pulses(events, 1)
    changes = [r for (_, w0), (r, w) in zip(widths, widths[1:]) if abs(w - w0) > 4 and last_byte < r < second_move]
    held_s = (changes[-1] - last_byte) / F_CPU_HZ
    assert 0.2 <= held_s <= 0.2 + 4 * 0.002, held_s  # stopped by the 200 ms watchdog (+ 4 PWM periods)
    home = expected_pulse_ticks(wire.LegacyVbMapping(), [96])[0]
    moved_deg = (widths[-1][1] - home) / (16000 / 180)
    assert 3.0 < moved_deg < 6.5, moved_deg  # 0.2 s at 30 deg/s, then it stayed where it stopped


def read_for(port, seconds):
    data, deadline = b"", time.monotonic() + seconds
    while time.monotonic() < deadline:
        data += port.read(256)
    return data


def replies(port, script, waits):
    """Non-report replies (the `z`s) to each step; a report is `h`/`H..X` then `v`/`V..X`, no grid here."""
    out = []
    for raw, wait_s in zip(script, waits):
        port.write(raw)
        data = read_for(port, wait_s)
        out.append(data.replace(b"h", b"").replace(b"v", b""))
    return out


REPLAY = [
    (b"P100X", "stored while stopped: nothing until E"),
    (b"E", "start: the stored reference is applied, one z"),
    (b"E", "start again: nothing"),
    (b"P080XQ075XR110XS090X", "four references: one z"),
    (b"P1234X", "four digits: discarded"),
    (b"P256X", "value over 255: discarded"),
    (b"PX", "no digit: discarded"),
    (b"Q12E", "broken by E: discarded, then E (already started)"),
    (b"T", "undocumented T: ignored"),
    (b"\x00\xff*#zzX17", "garbage and acks: ignored"),
    (b"R5X", "one digit: accepted, z"),
    (b"G", "stop: no reports, no z"),
    (b"S070X", "stored while stopped"),
    (b"E", "start: z"),
    (b"G", "stop"),
]


def test_one_script_gets_the_same_replies_from_firmware_and_simulator(mcu):
    script = [raw for raw, _ in REPLAY]
    simulator = subprocess.Popen([sys.executable, "-m", "bench.simulators.delta4", "--ideal", "--no-grid",
                                  "--speed-factor", "4"], cwd=ROOT, stdout=subprocess.PIPE,
                                 stderr=subprocess.DEVNULL, text=True)
    try:
        import serial
        path = simulator.stdout.readline().strip()
        with serial.serial_for_url(path, timeout=0.05) as port:
            from_simulator = replies(port, script, [1.0] * len(script))
    finally:
        simulator.terminate()
        simulator.wait(timeout=10)
    with mcu.open() as port:
        from_firmware = replies(port, script, [1.5] * len(script))
    assert from_simulator == [b"", b"z", b"", b"z", b"", b"", b"", b"", b"", b"", b"z", b"", b"", b"z", b""]
    assert from_firmware == from_simulator
