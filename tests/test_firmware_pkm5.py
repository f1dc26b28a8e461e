"""The pkm5 firmware (firmware/pkm5/pkm5.c) built for the ATmega2560 and run on an emulated MCU (simavr, through
firmware/sim/harness.c), driven by the project's own driver bench.robots.pkm5.Pkm5Controller. The harness logs
every STEP / DIR / EN edge with its emulated time; the assertions are on those pins.

Skipped, with the reason, where gcc-avr / avr-libc / simavr are not installed (.ci/run installs them)."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from bench.robots import pkm5_kinematics as kinematics
from bench.robots.pkm5 import ControllerError, Identity, Pkm5Controller
from bench.simulators.pkm5 import HOME_STEPS
from motion import pkm5
from tests.firmware_sim import (
    ACCEL_STEPS_S2,
    DRIVERS_ENABLED_LEVEL,
    ROOT,
    EmulatedController,
    build,
    needs_toolchain,
    read_events,
    step_times,
)

pytestmark = needs_toolchain
#: the emulator keeps real time only while it gets about a fifth of a core (a loaded machine slows it several times)
#: and the driver's timeouts and heartbeat are wall-clock: a heartbeat of 1 s (the motion tests' build has a 5 s link
#: watchdog) never has the driver send beats faster than the emulated firmware answers them, which overflowed its
#: 256-byte receive ring under load (ERR #0 CHECKSUM)
SLOW = {"reply_timeout_s": 10.0, "move_margin_s": 60.0, "heartbeat_s": 1.0}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The firmware as shipped (default build options)."""
    return build(tmp_path_factory)


@pytest.fixture(scope="module")
def built_patient(tmp_path_factory):
    """The motion tests' build: a 5 s link watchdog, so that a host stalled by a loaded test machine cannot trip it
    (the watchdog test runs the shipped build)."""
    return build(tmp_path_factory, WATCHDOG_MS=5000)


def _run(built, tmp_path):
    controller = EmulatedController(built.elf, built.harness, tmp_path / "events.txt")
    yield controller
    controller.close()


@pytest.fixture
def mcu(built_patient, tmp_path):
    yield from _run(built_patient, tmp_path)


@pytest.fixture
def shipped_mcu(built, tmp_path):
    yield from _run(built, tmp_path)


def home_pose_deg():
    lengths = pkm5.steps_to_lengths(np.asarray(HOME_STEPS)[None, :], pkm5.DEFAULT_GEOMETRY)
    return np.asarray(kinematics.pose_deg_from_rad(pkm5.forward_kinematics(lengths, pkm5.DEFAULT_GEOMETRY).pose[0]))


def segments(edges):
    """Rising STEP edges of each move: those between the arrival of its MOVE line and the next one's."""
    starts = [e.t_s for e in edges if e.kind == "RX" and e.line.startswith(b"MOVE ")] + [np.inf]
    steps = [e for e in edges if e.kind == "STEP" and e.level == 1]
    return [[e for e in steps if begin <= e.t_s < end] for begin, end in zip(starts, starts[1:])]


def test_build_prints_flash_and_ram_use(built):
    output = built.output
    program = int(output.split("Program:")[1].split()[0])
    data = int(output.split("Data:")[1].split()[0])
    assert 2000 < program < 256 * 1024 and 100 < data < 8 * 1024  # ATmega2560: 256 KiB flash, 8 KiB SRAM


@pytest.mark.slow
def test_identify_enable_and_move_through_the_driver(mcu):
    with Pkm5Controller(mcu.open(), **SLOW) as robot:
        assert robot.identify() == Identity("bench-pkm5", 3, "3.0.0")  # CRC-16 lines and MOVE retransmission negotiated
        assert robot.position().state == "DISABLED"
        robot.enable()
        target = robot.steps_for_pose(home_pose_deg() + [0.0, 0.0, 2.0, 0.0, 0.0])
        assert robot.move_steps(target, speed_steps_s=500) == target
        where = robot.position()
        assert (where.steps, where.state) == (target, "IDLE")
    edges = mcu.close()
    enable_levels = [e.level for e in edges if e.kind == "EN" and e.t_s > 0.001]
    assert enable_levels == [DRIVERS_ENABLED_LEVEL] * 6  # ENABLE drives the six pins to the powering level
    assert [len(step_times(edges, axis)) for axis in range(1, 7)] == list(np.abs(np.subtract(target, HOME_STEPS)))


@pytest.mark.slow
def test_random_moves_emit_exactly_the_commanded_steps_with_dir_first(mcu):
    rng = np.random.default_rng(16)
    home = home_pose_deg()
    reached = [tuple(HOME_STEPS)]
    with Pkm5Controller(mcu.open(), speed_steps_s=800, **SLOW) as robot:
        robot.identify()
        robot.enable()
        for _ in range(20):
            pose = home + np.r_[rng.uniform(-0.4, 0.4, 3), 0.0, 0.0]
            speed = int(rng.integers(300, 1001))
            reached.append(robot.move_to_pose(pose, speed_steps_s=speed))
    edges = mcu.close()
    moves = segments(edges)
    assert len(moves) == 20
    for before, after, move in zip(reached, reached[1:], moves):
        start, end = (move[0].t_s, move[-1].t_s) if move else (np.inf, np.inf)
        for axis in range(1, 7):
            count = sum(1 for e in move if e.axis == axis)
            assert count == abs(after[axis - 1] - before[axis - 1]), (axis, before, after)
            dir_edges = [e for e in edges if e.kind == "DIR" and e.axis == axis and e.t_s <= end]
            level = dir_edges[-1].level if dir_edges else 0
            if count:
                assert not [e for e in dir_edges if start <= e.t_s]  # DIR settled before the first STEP edge
                assert level == (after[axis - 1] < before[axis - 1])  # DIR high = shorten (DIR_INVERTED off)


@pytest.mark.slow
def test_step_rate_holds_the_command_and_the_ramp_the_acceleration(mcu):
    pose = home_pose_deg() + [0.0, 0.0, 3.0, 0.0, 0.0]
    with Pkm5Controller(mcu.open(), **SLOW) as robot:
        robot.identify()
        robot.enable()
        out = robot.move_to_pose(pose, speed_steps_s=1000)
        robot.move_steps(HOME_STEPS, speed_steps_s=600)
    edges = mcu.close()
    lead = int(np.argmax(np.abs(np.subtract(out, HOME_STEPS)))) + 1
    times = step_times(edges, lead)
    n = abs(out[lead - 1] - HOME_STEPS[lead - 1])
    assert n > 900 and len(times) == 2 * n
    for t, speed in ((times[:n], 1000), (times[n:], 600)):
        ramp = int(speed**2 / (2 * ACCEL_STEPS_S2)) + 20
        cruise = t[ramp : n - ramp]
        rate = (len(cruise) - 1) / (cruise[-1] - cruise[0])
        assert abs(rate / speed - 1) < 0.01, rate
        # the ramps: a quadratic fitted to step number against time over each ramp gives its acceleration
        ramp_steps = int(0.8 * (speed**2 - 20**2) / (2 * ACCEL_STEPS_S2))
        for part in (t[:ramp_steps], t[-ramp_steps:]):
            accel = 2 * np.polyfit(part - part[0], np.arange(len(part)), 2)[0]
            assert 0.9 * ACCEL_STEPS_S2 < abs(accel) < 1.02 * ACCEL_STEPS_S2, accel
        v = 10 / (t[10:] - t[:-10])  # mean velocity over 10 steps
        assert v.max() < 1.01 * speed and v[-1] < speed / 2  # no overshoot; it ramps down


HOST = textwrap.dedent("""
    import sys, serial
    from bench.robots.pkm5 import Pkm5Controller
    robot = Pkm5Controller(serial.serial_for_url(sys.argv[1], baudrate=115200, timeout=0.05))
    robot.identify(); robot.enable()
    print("moving", flush=True)
    robot.move_to_pose((88.649, 0.0, 312.0, 0.0, 0.0), speed_steps_s=1000)
""")


def disabled_after_enable(edges):
    """The EN edges to the disabled level after the drivers were first enabled."""
    enabled_at = min((e.t_s for e in edges if e.kind == "EN" and e.level == DRIVERS_ENABLED_LEVEL), default=np.inf)
    return [e for e in edges if e.kind == "EN" and e.level != DRIVERS_ENABLED_LEVEL and e.t_s > enabled_at]


def test_killed_host_mid_move_disables_the_drivers_and_the_next_driver_gets_the_fault(shipped_mcu):
    mcu = shipped_mcu
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    host = subprocess.Popen([sys.executable, "-c", HOST, mcu.path], stdout=subprocess.PIPE, text=True, env=env)
    assert host.stdout.readline().strip() == "moving"
    time.sleep(0.5)
    host.send_signal(signal.SIGKILL)
    host.wait()
    deadline = time.monotonic() + 60
    while not disabled_after_enable(read_events(mcu.events)) and time.monotonic() < deadline:  # flushed every 100 ms
        time.sleep(0.1)
    robot = Pkm5Controller(mcu.open(), **SLOW)
    with pytest.raises(ControllerError, match="error 9 WATCHDOG") as caught:
        robot.identify()  # a new host starts with ID (v1, which resets the link); the latched fault answers it
    assert caught.value.code == 9
    robot.identify()
    where = robot.position()
    assert (
        where.state == "DISABLED"
        and where.steps[0] != HOME_STEPS[0]
        and where.steps != kinematics.steps_for_pose((88.649, 0.0, 312.0, 0.0, 0.0))
    )  # stopped part way
    edges = mcu.close()
    disabled = disabled_after_enable(edges)
    assert sorted(e.axis for e in disabled) == [1, 2, 3, 4, 5, 6]
    disabled_at = max(e.t_s for e in disabled)
    last_line_s = max(e.t_s for e in edges if e.kind == "RX" and e.t_s < disabled_at)
    assert disabled_at - last_line_s < 0.250
    assert not [e for e in edges if e.kind == "STEP" and e.t_s > disabled_at]
