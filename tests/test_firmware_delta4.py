"""The delta4 firmware (firmware/delta4/delta4.c) built for the ATmega128 and run on an emulated MCU (simavr, through
firmware/sim/delta4_harness.c), driven by the project's own driver bench.robots.delta4.Delta4Controller. The harness
logs every servo PWM edge with its emulated time and plays the two laser-grid screens (74LS166 chains) lit from the
test; the assertions are on those pins and on the bytes the driver reads. One raw script is also replayed against
the firmware and against ``python -m bench.simulators.delta4``: the same replies, timing aside.

Skipped, with the reason, where gcc-avr / avr-libc / simavr are not installed (.ci/run installs them)."""

import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from bench.robots import delta4_wire as wire
from bench.robots.delta4 import DEFAULT_BAUDRATE, Delta4Controller
from bench.sensors.lasergrid import GridGeometry, decode_frame
from bench.simulators.lasergrid import LaserGridSimulator
from tests.firmware_sim import F_CPU_HZ, ROOT, build, needs_toolchain, start_harness

pytestmark = needs_toolchain

#: the documented PWM (reference §5.2): no prescaler, 2 ms refresh; pulse mapping of firmware/delta4/delta4.c
PERIOD_TICKS = 32000
PULSE_AT_0_DEG_US, PULSE_AT_180_DEG_US = 1000.0, 2000.0
STOPS_DEG = (30.0, 170.0)
SLEW_DEG_S = 286.0
SLOW = {"settle_timeout_s": 20.0}
#: the longest another interrupt can hold off the TOP interrupt, cycles: the UART handlers and the main loop's
#: cli() sections are a few dozen instructions (8 us at 16 MHz leaves them twice their length)
MAX_INTERRUPT_WAIT_TICKS = 128


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
        self.events = events
        self.process, self.path = start_harness(built.harness, built.elf, events, stdin=subprocess.PIPE)

    def open(self, timeout_s=0.05):
        import serial

        return serial.serial_for_url(self.path, baudrate=DEFAULT_BAUDRATE, timeout=timeout_s)

    def light(self, screen: str, indices) -> None:
        self.process.stdin.write(f"{screen} {' '.join(str(i) for i in indices)}\n")
        self.process.stdin.flush()

    def feed_pots(self, counts, timeout_s=20.0) -> None:
        """Set the four TLC548 inputs to ``counts`` and wait until a read has shifted them out to the firmware."""
        wanted = [str(int(c)) for c in counts]
        offset = self.events.stat().st_size  # reads logged from here on began after the new inputs were set
        self.process.stdin.write(f"A {' '.join(wanted)}\n")
        self.process.stdin.flush()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            with open(self.events) as log:
                log.seek(offset)
                tail = log.read()
            for line in tail[: tail.rfind("\n") + 1].splitlines()[1:]:  # complete lines; the first may be a rest
                fields = line.split()  # <cycle> ADC <clocks> <cs low> <setup> <high> <low> <c1> <c2> <c3> <c4>
                if len(fields) == 11 and fields[1] == "ADC" and fields[7:] == wanted:
                    return
            time.sleep(0.05)
        raise AssertionError(f"the harness shifted out no pot counts {counts} within {timeout_s} s")

    def close(self):
        if self.process.poll() is None:
            self.process.terminate()
            self.process.wait(timeout=10)
        text = self.events.read_text()
        rows = []
        for line in text[: text.rfind("\n") + 1].splitlines():
            cycle, kind, channel, *value = line.split()
            rows.append((int(cycle), kind, channel, value[0] if value else "", tuple(value)))
        return rows


def pulses(events, servo):
    """(rising-edge cycle, high time in cycles) of each pulse of ``servo`` (1-4)."""
    out, rise = [], None
    for cycle, kind, channel, value, _ in events:
        if kind == "PWM" and channel == str(servo):
            if value == "1":
                rise = cycle
            elif rise is not None:
                out.append((rise, cycle - rise))
    return out


def received_at(events, byte: bytes):
    return [c for c, kind, channel, *_ in events if kind == "RX" and bytes.fromhex(channel) == byte]


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    return build(tmp_path_factory, "delta4")


@pytest.fixture(scope="module")
def built_watchdog(tmp_path_factory):
    """Slow servos (20 deg/s) and a 400 ms link watchdog, so that a move outlasts the watchdog."""
    return build(tmp_path_factory, "delta4", DELTA4_SLEW_DEG_S=20, DELTA4_WATCHDOG_MS=400)


@pytest.fixture
def mcu(built, tmp_path):
    controller = EmulatedDelta4(built, tmp_path / "events.txt")
    yield controller
    controller.close()


def test_build_prints_flash_and_ram_use(built):
    section = built.output.split("Device: atmega128")[1]
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
    assert_pulses_at_rest(mcu.close(), b"P", [expected_pulse_ticks(mapping, values) for values in bytes_sent])


def assert_pulses_at_rest(events, first_byte, expected_ticks):
    """Each move (begun by a message starting with ``first_byte``) ends with its servos pulsing
    ``expected_ticks`` (one row per move) at a steady 2 ms period."""
    starts = received_at(events, first_byte)[:: 4 if first_byte == b"F" else 1]  # a fine move: four F messages
    ends = starts[1:] + [max(r for r, _ in pulses(events, 1)) + PERIOD_TICKS]
    assert len(ends) == len(expected_ticks)
    for values, end in zip(expected_ticks, ends):
        expected = values
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
    ramp = widths[moving[0] + 1 : moving[-1]]
    on_slew = ramp - step_ticks * np.arange(len(ramp))
    off_line = on_slew - np.median(on_slew)  # never stepped faster: every width stays on the slew-limited line
    stretched = np.flatnonzero(off_line > 3)
    assert np.all(off_line >= -3), off_line  # (the Q8 setpoint rounds each width by under 2 ticks)
    # A period whose compare latch (latch_compares, first thing in the TOP interrupt) waited for another interrupt
    # (a received byte) comes out longer in simavr, by that wait: its timer restarts from the latch, not from TOP.
    # That is the emulator's, not a step: one period, bounded by an interrupt's length, back on the line after it.
    assert np.all(off_line[stretched] <= MAX_INTERRUPT_WAIT_TICKS) and np.all(np.diff(stretched) > 1), off_line


def test_calibrated_mapping_and_a_50_hz_refresh_as_build_options(tmp_path, tmp_path_factory):
    built = build(tmp_path_factory, "delta4", DELTA4_MAPPING="calibrated", DELTA4_PERIOD_US=20000)
    mcu = EmulatedDelta4(built, tmp_path / "events.txt")
    mapping = wire.CalibratedMapping()
    angles = np.array([30.0, 71.657, 120.0, 170.0])
    try:
        with Delta4Controller(mcu.open(), mapping=mapping, **SLOW) as robot:
            robot.start(verify_timeout_s=10.0)
            values = robot.move_servos(angles, require_settled=True).command_bytes
            settled_s, fresh = time.monotonic(), 0
            while fresh < 3:  # 3 reports begun after the z: >= 160 ms of emulated time at rest
                fresh += robot.read_sensor_frame(10.0).t_first_token_s > settled_s
    finally:
        events = mcu.close()
    assert values == (0, 76, 164, 255)
    tick_cycles = 8  # prescaler 8: 0.5 us per tick
    for servo in range(4):
        rest = pulses(events, servo + 1)[-6:-1]
        expected_cycles = expected_pulse_ticks(mapping, [values[servo]])[0] / 16 * F_CPU_HZ / 1e6
        assert abs(np.median([w for _, w in rest]) - expected_cycles) <= tick_cycles, servo
        assert np.median(np.diff([r for r, _ in rest])) == pytest.approx(0.020 * F_CPU_HZ, abs=tick_cycles)


def first_frames_showing(robot, horizontal, vertical, limit=40):
    """Reports up to the first that shows this pattern, and the one after it (the pattern holds)."""
    frames = []
    while len(frames) < limit and (
        not frames or (frames[-1].horizontal, frames[-1].vertical) != (horizontal, vertical)
    ):
        frames.append(robot.read_sensor_frame(10.0))
    return frames + [robot.read_sensor_frame(10.0)]


def test_laser_grid_hits_on_the_screen_inputs_are_reported_and_decode_as_the_document(mcu):
    geometry = GridGeometry()
    pose_mm = np.array([5.0, 5.0, -150.0])
    horizontal, vertical = LaserGridSimulator(geometry).observer()(pose_mm)
    assert horizontal and vertical
    with Delta4Controller(mcu.open(), **SLOW) as robot:
        robot.start(verify_timeout_s=10.0)
        mcu.light("H", [121])  # Fig. 10 a: BE over sensor (7, 7), moved 5 mm in +x: G5-a on (9, 7)
        mcu.light("V", [])
        frames = first_frames_showing(robot, (121,), ())
        mcu.light("H", horizontal + (200, 17))
        mcu.light("V", vertical)
        later = first_frames_showing(robot, tuple(sorted(horizontal + (200, 17))), vertical)
        mcu.light("H", range(0, 256, 2))  # 128 hits: a 0.67 s report at 9600 baud, longer than the receive buffer
        crowded = first_frames_showing(robot, tuple(range(0, 256, 2)), vertical)
        robot.move_servos(TEST_ANGLES_DEG[0], wait=False)  # 40 bytes back to back while a long report goes out
        last = robot.move_servos(TEST_ANGLES_DEG[1], require_settled=True)
        fresh_s, fresh = time.monotonic(), 0
        while fresh < 2:
            fresh += robot.read_sensor_frame(10.0).t_first_token_s > fresh_s
    assert [(f.horizontal, f.vertical) for f in frames[-2:]] == [((121,), ())] * 2
    decoded = decode_frame(geometry, frames[-1].horizontal, [], np.array([0.0, -5.0, -150.0]))
    assert decoded.position_mm[:2] == (0.0, -5.0) and decoded.horizontal.lasers == ("G5-a",)
    assert [(f.horizontal, f.vertical) for f in later[-2:]] == [(tuple(sorted(horizontal + (200, 17))), vertical)] * 2
    assert crowded[-1].horizontal == tuple(range(0, 256, 2))
    decoded = decode_frame(
        geometry, [i for i in later[-1].horizontal if i in horizontal], later[-1].vertical, pose_mm + [1.0, -1.0, 1.0]
    )
    assert decoded.position_mm == tuple(pose_mm)
    events = mcu.close()
    final = [pulses(events, servo + 1)[-2][1] for servo in range(4)]
    expected = expected_pulse_ticks(wire.LegacyVbMapping(), last.command_bytes)
    assert np.all(np.abs(np.array(final) - expected) <= 3), (final, expected)  # no command byte was lost
    on = [c for c, kind, channel, value, _ in events if kind == "LASER" and channel == "1" and value == "1"]
    off = [c for c, kind, channel, value, _ in events if kind == "LASER" and channel == "1" and value == "0"]
    assert len(on) >= 4
    assert np.all(np.array(off[: len(on)]) - np.array(on[: len(off)]) >= 1e-3 * F_CPU_HZ)  # 1 ms on before the load
    assert abs(np.median(np.diff(on[:5])) / F_CPU_HZ - 0.080) < 0.003  # one frame per 80 ms (§5.5), few hits


def pot_reads(events):
    """The harness's TLC548 reads: (cycle CS rose, clocks, CS low, setup, min high, min low cycles, counts)."""
    return [
        (c, int(clocks), *map(int, v[:4]), tuple(map(int, v[4:]))) for c, kind, clocks, _, v in events if kind == "ADC"
    ]


def documented_pot_count(servo_deg):
    """The TLC548 count of theta_R (reference §5.8 b, direction +1): references trimmed to the calibrated stops,
    0-255 over exactly their 140 deg, round half up, clamped to 0-255."""
    low, high = STOPS_DEG
    count = np.floor(255.0 * (np.asarray(servo_deg, float) - low) / (high - low) + 0.5).astype(int)
    return np.clip(count, 0, 255)  # the pots cannot leave the stops


#: TV4's and TV1's angles, the two stops, and one count's width above the low stop
POT_TEST_ANGLES_DEG = TEST_ANGLES_DEG + [(30.0, 170.0, 100.0, 30.0 + 140.0 / 255.0)]


def test_pot_angles_fed_to_the_tlc548_inputs_come_back_through_the_driver_within_one_count(mcu):
    one_count_deg = (STOPS_DEG[1] - STOPS_DEG[0]) / 255.0
    readings = []
    with Delta4Controller(mcu.open(), **SLOW) as robot:
        home = documented_pot_count(np.full(4, 71.657))
        mcu.feed_pots(home)
        readings.append(robot.read_pots(5.0))  # stopped: the pots are read before E too
        robot.start(verify_timeout_s=10.0)
        for angles in POT_TEST_ANGLES_DEG:
            mcu.feed_pots(documented_pot_count(angles))
            readings.append(robot.read_pots(5.0))
        mcu.feed_pots(documented_pot_count(TEST_ANGLES_DEG[0]))  # the servos reach TV4 (as the test says)
        moved = robot.move_servos(TEST_ANGLES_DEG[0], require_settled=True, read_back=True)
    assert readings[0].counts == (76, 76, 76, 76)
    assert moved.measured.counts == (55, 44, 111, 118) and moved.command_bytes == (81, 72, 122, 128)
    for angles, reading in zip(POT_TEST_ANGLES_DEG, readings[1:]):
        assert reading.counts == tuple(documented_pot_count(angles))
        assert np.all(np.abs(np.array(reading.servo_deg) - angles) <= one_count_deg / 2 + 1e-9), (angles, reading)
    assert readings[1].counts == (55, 44, 111, 118) and readings[3].counts == (0, 255, 128, 1)
    events = mcu.close()
    reads = pot_reads(events)
    cycles = np.array([r[0] for r in reads])
    gaps = np.diff(cycles)  # every 2 ms (§7.3.5); a read waits at most for a UART interrupt or a setpoint latch
    assert len(reads) > 100 and abs(np.median(gaps) - PERIOD_TICKS) <= 1, gaps
    assert np.all(np.abs(gaps - PERIOD_TICKS) <= 200), gaps[np.abs(gaps - PERIOD_TICKS) > 200]
    clocks, low, setup, high, low_time = (np.array([r[k] for r in reads]) for k in range(1, 6))
    assert np.all(clocks == 8)
    # TLC548 (SLAS066): CS low >= 1.425 us before the first clock, I/O CLOCK high and low >= 404 ns (<= 2.048 MHz)
    assert setup.min() >= 1.425e-6 * F_CPU_HZ and min(high.min(), low_time.min()) >= 404e-9 * F_CPU_HZ
    assert low.max() < 50e-6 * F_CPU_HZ  # the read holds the PWM tick's interrupt for under 50 us of every 2 ms


def test_a_driver_heartbeat_keeps_a_move_longer_than_the_watchdog_going(built_watchdog, tmp_path):
    mcu = EmulatedDelta4(built_watchdog, tmp_path / "events.txt")
    try:
        # 71.5 -> 120 deg at 20 deg/s: 2.4 s, six times the 400 ms watchdog of this build
        with Delta4Controller(mcu.open(), heartbeat_s=0.1, settle_timeout_s=30.0) as robot:
            robot.start(verify_timeout_s=10.0)
            move = robot.move_servos((120.0, 71.5, 71.5, 71.5))
            beats = robot.last_pots
    finally:
        events = mcu.close()
    assert move.settled and beats is not None
    queries = received_at(events, b"A")
    assert len(queries) >= 15
    assert np.max(np.diff(queries)) < 0.4 * F_CPU_HZ  # no gap the watchdog would take for a silent host
    final = pulses(events, 1)[-2][1]
    assert abs(final - expected_pulse_ticks(wire.LegacyVbMapping(), [move.command_bytes[0]])[0]) <= 3


def test_watchdog_holds_the_servos_when_the_host_falls_silent(built_watchdog, tmp_path):
    mcu = EmulatedDelta4(built_watchdog, tmp_path / "events.txt")
    try:
        port = mcu.open()
        port.write(b"E" + wire.format_servo_command(0, 200))  # 96 -> 200: 77 deg at 20 deg/s, 3.9 s
        silent = read_for(port, 2.0)
        port.write(wire.format_servo_command(1, 60))  # servo 2: 96 -> 60, 27 deg in 1.3 s, with heartbeats
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
    # stopped by the 400 ms watchdog: it counts whole 2 ms periods from the one the last byte arrived in (up to
    # one period of phase), and a frozen width shows on the pin through the double-buffered compare registers and the
    # pulse measurement, a few periods later (measured up to 0.4089 s under load): 400 ms + 5 periods at most
    assert 0.4 - 0.002 <= held_s <= 0.4 + 5 * 0.002, held_s
    home = expected_pulse_ticks(wire.LegacyVbMapping(), [96])[0]
    moved_deg = (widths[-1][1] - home) / (16000 / 180)
    assert 6.0 < moved_deg < 8.6, moved_deg  # 0.4 s at 20 deg/s, then it stayed where it stopped


def expected_fine_pulse_ticks(values) -> np.ndarray:
    """Pulse width, ticks, of fine references ``values`` (0.01 deg), docs/protocol-delta4.md: the angle clamped
    to the stops, 1.0 ms at 0 deg to 2.0 ms at 180 deg, rounded half up to a tick (no byte mapping)."""
    angle = np.clip(np.asarray(values, float) / 100.0, *STOPS_DEG)
    return np.floor(16000 + angle * 16000 / 180.0 + 0.5).astype(int)


def test_fine_references_position_the_pulses_on_the_tick_and_bytes_stay_as_before(mcu):
    """The driver probes (C -> c01125X: one tick, 0.01125 deg), then sends F1..X F2..X F3..X F4..X; each pulse is the
    tick nearest the angle, not the byte's 0.745 deg step. The byte test above is the unchanged byte path."""
    mapping = wire.LegacyVbMapping()
    with Delta4Controller(mcu.open(), mapping=mapping, **SLOW) as robot:
        robot.start(verify_timeout_s=10.0)
        fine = robot.probe_fine_references(timeout_s=10.0)
        moves = [robot.move_servos(angles, require_settled=True) for angles in TEST_ANGLES_DEG]
    assert fine is not None and fine.controller_step_deg == pytest.approx(180 / 16000)
    assert moves[0].fine_values == (6000, 5400, 9100, 9500) and moves[0].command_bytes == ()
    assert moves[1].fine_values == (12930, 12661, 7373, 7859)
    expected = [expected_fine_pulse_ticks(move.fine_values) for move in moves]
    # the byte of 60 deg (81: 60.35 deg) would pulse 32 ticks wider than the fine reference: the test can tell
    assert expected_pulse_ticks(mapping, [81])[0] - expected[0][0] == 32
    np.testing.assert_allclose(expected[1] * 180 / 16000 - 180, TEST_ANGLES_DEG[1], atol=180 / 16000 / 2 + 0.005)
    assert_pulses_at_rest(mcu.close(), b"F", expected)


def read_for(port, seconds):
    data, deadline = b"", time.monotonic() + seconds
    while time.monotonic() < deadline:
        data += port.read(256)
    return data


def replies(port, steps, quiet_s=0.3, timeout_s=10.0, feed_pots=None):
    """Replies to each step, sensor reports taken out (no grid here: `h` and `v`): wait for the step's expected
    reply (up to ``timeout_s``), then for ``quiet_s`` more, so that a missing or an extra reply shows in its step.
    Before a step with pot counts, ``feed_pots(counts)`` (the firmware's harness) sets the TLC548 inputs."""
    out = []
    for raw, expected, _, counts in steps:
        if counts is not None and feed_pots is not None:
            feed_pots(counts)
        port.write(raw)
        data, deadline = b"", time.monotonic() + timeout_s
        while data.replace(b"h", b"").replace(b"v", b"") != expected and time.monotonic() < deadline:
            data += port.read(256)
        data += read_for(port, quiet_s)
        out.append(data.replace(b"h", b"").replace(b"v", b""))
    return out


def pot_query(raw, servo_bytes, why, answers=1):
    """A replay step sending the pot query ``raw`` with the servos at rest on the references ``servo_bytes``
    (legacy_vb): the counts the test feeds the firmware's TLC548 inputs, and ``answers`` times the answer expected
    (the simulator's pots see the same angles)."""
    counts = tuple(int(c) for c in documented_pot_count(wire.LegacyVbMapping().to_deg(np.asarray(servo_bytes, float))))
    answer = b"".join(b"%c%03dX" % (letter, c) for letter, c in zip(b"pqrs", counts))
    return raw, answer * answers, why, counts


#: (bytes sent, the reply expected once sensor reports are taken out, why[, pot counts fed before the step])
REPLAY = [
    (b"A", b"p076Xq076Xr076Xs076X", "pot query before E: the home pose, 71.657 deg", (76, 76, 76, 76)),
    (b"P100X", b"", "stored while stopped: nothing until E"),
    (b"E", b"z", "start: the stored reference is applied, one z"),
    pot_query(b"A", (100, 96, 96, 96), "pot query: servo 1 on 100"),
    (b"E", b"", "start again: nothing"),
    (b"P080XQ075XR110XS092X", b"z", "four references: one z"),
    pot_query(b"AA", (80, 75, 110, 92), "two queries, two answers", answers=2),
    pot_query(b"Q12A", (80, 75, 110, 92), "a query breaks a message: discarded, then answered"),
    (b"P1234X", b"", "four digits: discarded"),
    (b"P256X", b"", "value over 255: discarded"),
    (b"PX", b"", "no digit: discarded"),
    (b"Q12E", b"", "broken by E: discarded, then E (already started)"),
    (b"T", b"", "undocumented T: ignored"),
    (b"\x00\xff*#zzX17", b"", "garbage and acks: ignored"),
    (b"R5X", b"z", "one digit: accepted, z"),
    (b"PP100X", b"z", "a letter restarts the message: P100X accepted, z"),
    (b"P0100X", b"", "four digits with a leading zero: discarded"),
    (b"p100x", b"", "lower case: ignored"),
    (b"P200XG", b"", "stopped mid-move: no z while stopped"),
    (b"E", b"z", "restarted: the move goes on, z"),
    (b"G", b"", "stop: no reports, no z"),
    (b"E", b"", "start with nothing stored: no z"),
    (b"G", b"", "stop"),
    (b"S070X", b"", "stored while stopped"),
    pot_query(b"A", (200, 75, 5, 92), "stopped: the pots still answer (S070X not applied yet)"),
    (b"E", b"z", "start: z"),
    (b"G", b"", "stop"),
    (b"C", b"c01125X", "capability query, stopped: the fine step, one tick (1e-5 deg)"),
    (b"E", b"", "start with nothing stored: no z"),
    (b"F107166X", b"z", "fine reference, servo 1 to 71.66 deg: z"),
    (b"F112000XF212000XF312000XF412000X", b"z", "four fine references: one z"),
    pot_query(b"A", (161, 161, 161, 161), "pot query after fine references of 120 deg (byte 161: 119.96 deg)"),
    (b"F512000X", b"", "servo 5: discarded"),
    (b"F0X", b"", "servo 0: discarded"),
    (b"F1X", b"", "no value digit: discarded"),
    (b"F118001X", b"", "value over 18000: discarded"),
    (b"F1120000X", b"", "six value digits: discarded"),
    (b"F1120E", b"", "broken by E: discarded, then E (already started)"),
    (b"F1 12000X", b"", "a space breaks it: discarded"),
    (b"F1CX", b"c01125X", "C breaks a fine message: discarded, then answered"),
    (b"FP100X", b"z", "a byte letter restarts the message: P100X accepted, z"),
    (b"F309000X", b"z", "servo 3 to 90 deg: z"),
    (b"G", b"", "stop"),
]
REPLAY = [step if len(step) == 4 else (*step, None) for step in REPLAY]


def simulator_replies(steps):
    """:func:`replies` to ``steps`` from ``python -m bench.simulators.delta4`` started as a user starts it."""
    simulator = subprocess.Popen(
        [sys.executable, "-m", "bench.simulators.delta4", "--ideal", "--no-grid", "--speed-factor", "8"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        import serial

        path = simulator.stdout.readline().strip()
        with serial.serial_for_url(path, timeout=0.05) as port:
            return replies(port, steps)
    finally:
        simulator.terminate()
        simulator.wait(timeout=10)


@pytest.mark.slow
def test_one_script_gets_the_same_replies_from_firmware_and_simulator(mcu):
    # The two replays share nothing and each is mostly its quiet waits: the simulator's runs alongside the firmware's
    # (one after the other, the emulated MCU sat idle through the simulator's 15 s).
    with ThreadPoolExecutor(1) as pool:
        from_simulator = pool.submit(simulator_replies, REPLAY)
        with mcu.open() as port:
            from_firmware = replies(port, REPLAY, feed_pots=mcu.feed_pots)
        from_simulator = from_simulator.result()
    assert from_simulator == [expected for _, expected, _, _ in REPLAY]
    assert from_firmware == from_simulator


def test_queries_that_arrive_together_get_one_answer_each(mcu):
    """Eight ``A`` in one write while the firmware is started: 160 bytes of answers overflow its 64-byte transmit
    buffer, so the later queries are read while it waits to send (``put`` -> ``service_rx``). Each is counted and
    answered, as the simulator answers them (a flag answered one of several: found as a rare mismatch of the
    replay script under CPU load, where two queued ``A`` gave one answer)."""
    counts = (80, 75, 110, 92)
    answer = b"".join(b"%c%03dX" % (letter, c) for letter, c in zip(b"pqrs", counts))
    mcu.feed_pots(counts)
    with mcu.open() as port:
        assert replies(port, [(b"P100X", b"", "stored", None), (b"E", b"z", "start", None)]) == [b"", b"z"]
        port.write(b"A" * 8 + b"C" * 3)
        data, deadline = b"", time.monotonic() + 30.0
        while (data.count(answer), data.count(b"c01125X")) != (8, 3) and time.monotonic() < deadline:
            data += port.read(256)
        data += read_for(port, 0.5)
        port.write(b"G")
    cleaned = data.replace(b"h", b"").replace(b"v", b"")
    assert (cleaned.count(answer), cleaned.count(b"c01125X")) == (8, 3)
    assert len(cleaned) == 8 * len(answer) + 3 * len(b"c01125X")  # nothing else, no partial answer
