"""Mouse backends other than evdev: the microcontroller line stream over a pseudo-terminal, and the OS-pointer
parity method (sensors.md §2: 0.2 mm/pixel at speed 4, Table A.28 fixture of cursor positions)."""

import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sensor_fixtures import pty_pair

from bench.errors import LinkError
from bench.sensors import MalformedSample
from bench.sensors.calibration import CountsCalibration
from bench.sensors.mouse_mcu import McuMouse, McuSample, parse_mcu_line
from bench.sensors.mouse_pointer import PointerMethodWarning, PointerSampler
from bench.simulators.mouse import MouseSimulator


def test_parse_mcu_lines():
    assert parse_mcu_line(b"1250,-3,17,118") == McuSample(1250, -3, 17, 118)
    assert parse_mcu_line(b" 1250 , +3 ,0") == McuSample(1250, 3, 0, None)
    for bad in (b"", b"1250,3", b"1250,3,4,5,6", b"t,dx,dy", b"1.5,3,4", b"-1,3,4"):
        with pytest.raises(MalformedSample, match="expected 't_us,dx,dy\\[,squal\\]'"):
            parse_mcu_line(bad)


@given(
    t=st.integers(0, 2**63),
    dx=st.integers(-(2**15), 2**15),
    dy=st.integers(-(2**15), 2**15),
    squal=st.one_of(st.none(), st.integers(0, 255)),
)
def test_parse_mcu_line_round_trip(t, dx, dy, squal):
    line = f"{t},{dx},{dy}" + ("" if squal is None else f",{squal}")
    assert parse_mcu_line(line.encode()) == McuSample(t, dx, dy, squal)


def test_mcu_mouse_over_a_pty_integrates_and_flags_low_squal():
    with pty_pair() as (master, port):
        sim = MouseSimulator(cpi=1600, report_rate_hz=500)
        t_s = np.array([0.0, 0.2])
        lines = sim.mcu_lines(t_s, np.array([[0.0, 0.0], [12.7, -6.35]]), squal=120)
        n = lines.count(b"\n")
        os.write(master, lines)
        mouse = McuMouse(port, CountsCalibration.from_cpi(1600), label="XY")
        reading = mouse.read(n_samples=n, timeout_s=2)
        assert reading.raw == (800, -400)  # 12.7 mm = 0.5 in = 800 counts at 1600 CPI
        assert reading.value == pytest.approx((12.7, -6.35)) and reading.valid and "squal=120" in reading.note
        os.write(master, b"999999999,1,0,12\n")
        assert not mouse.read(timeout_s=2).valid
        mouse.rezero()
        os.write(master, b"5,0,0,100\n")  # MCU clock went backwards: reset or lost data
        late = mouse.read(timeout_s=2)
        assert not late.valid and "MCU clock went from 999999999 to 5 us" in late.note


def test_pointer_method_warns_loudly_and_reproduces_table_a28(caplog):
    cursor_y = [951, 926, 902, 877, 853, 829, 805, 780, 756, 731, 706, 682, 657, 633, 608, 584, 560, 537, 513]
    positions = iter([(0, y) for y in cursor_y])
    with pytest.warns(PointerMethodWarning, match="unfit for metrology"):
        sampler = PointerSampler(position=positions.__next__, rate_hz=1000.0)
    assert "unfit for metrology" in caplog.text
    readings = list(sampler.samples(len(cursor_y)))
    steps_px = -np.diff([r.raw[1] for r in readings])
    assert steps_px.mean() == pytest.approx(24.33, abs=0.005)  # Table A.28, 5 mm increments
    assert 5 / steps_px.mean() == pytest.approx(0.2055, abs=0.0001)  # the true mm/pixel of this axis
    assert 3 * steps_px.std(ddof=1) == pytest.approx(1.78, abs=0.005)  # Table A.25, speed 4, Y, 5 mm
    assert readings[0].value == pytest.approx((0.0, 951 * 0.2)) and "unfit" in readings[0].note


def test_pointer_method_without_display_fails_clearly():
    if os.environ.get("DISPLAY"):
        pytest.skip("a display is available")
    with pytest.warns(PointerMethodWarning), pytest.raises(LinkError, match="needs a desktop session"):
        PointerSampler()
