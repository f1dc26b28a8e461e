"""Calliper: parsing (hypothesis), prompted manual entry, keyboard-wedge decoding without a display, serial
callipers over a pseudo-terminal, and tilt from two depths (sensors.md §6; iso9283.md §8.2(d) worked example)."""

import io
import os

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sensor_fixtures import pty_pair

from bench.errors import ConfigError, InsufficientData, LinkTimeout
from bench.sensors import MalformedSample, Reading
from bench.sensors.calliper import (
    ReadingRequest,
    SerialCalliper,
    TiltBias,
    parse_length,
    prompt_reading,
    tilt_deg,
    tilt_reading,
    tilt_uncertainty_deg,
)
from bench.sensors.calliper_wedge import (
    EvdevWedge,
    WedgeDecoder,
    WedgeListener,
    encode_keystrokes,
    key_symbol,
)
from bench.simulators.calliper import CalliperSimulator, depths_for_tilt


@pytest.mark.parametrize(
    "text, mm",
    [
        ("12.34", 12.34),
        ("-0,50 mm", -0.5),
        ("+7", 7.0),
        (".25", 0.25),
        ("0.4865 in", 12.3571),
        ('1"', 25.4),
        (" 150.00MM ", 150.0),
    ],
)
def test_parse_length_accepts_calliper_formats(text, mm):
    assert parse_length(text) == pytest.approx(mm)


@pytest.mark.parametrize("text", ["", "abc", "12.3.4", "12 cm", "--1", "1e3", "12,3,4"])
def test_parse_length_rejects_naming_the_text(text):
    with pytest.raises(MalformedSample, match="is not a length"):
        parse_length(text)


@given(
    st.decimals(min_value=-1000, max_value=1000, places=2, allow_nan=False, allow_infinity=False),
    st.sampled_from([".", ","]),
    st.sampled_from(["", " mm", "mm"]),
)
def test_parse_length_round_trips_displayed_values(value, separator, unit):
    text = f"{value:.2f}".replace(".", separator) + unit
    assert parse_length(text) == pytest.approx(float(value), abs=1e-9)


@given(st.text(max_size=12))
def test_parse_length_never_raises_anything_but_malformed(text):
    try:
        assert np.isfinite(parse_length(text))
    except MalformedSample:
        pass


def test_prompted_entry_retries_confirms_and_stores_immediately():
    answers = iter(["twelve", "300", "14.9", "n", "14.90", "y", "14.9"])
    stored, out = [], io.StringIO()
    request = ReadingRequest("actuator 3, 20 mm, repeat 4, final depth", expected_mm=12.0, tolerance_mm=2.0)
    reading = prompt_reading(request, stored.append, ask=lambda prompt: next(answers), out=out, double_entry=True)
    assert stored == [reading] and reading.value == 14.9 and reading.raw == "14.90"
    assert "confirmed outside the expected range" in reading.note
    assert "is not a length" in out.getvalue() and "300 mm, expected 0 to 150 mm" in out.getvalue()


def test_wedge_keystrokes_become_readings_without_a_display():
    sim = CalliperSimulator(noise_mm=0.004, seed=2)
    readings, rejects = [], []
    decoder = WedgeDecoder(readings.append, on_reject=rejects.append, clock=iter(np.arange(0, 10, 0.01)).__next__)
    for key in sim.keystrokes([12.345, 5.0]) + ["1", "x", "enter"]:
        decoder.feed(key)
    assert [r.value for r in readings] == pytest.approx(sim.values([12.345, 5.0]).tolist())
    assert all(r.unit == "mm" for r in readings) and len(rejects) == 1 and "'1<x>'" in str(rejects[0])


def test_wedge_discards_stale_characters_and_maps_pynput_keys():
    class KeyCode:  # stand-ins for pynput's KeyCode / Key objects
        def __init__(self, char=None, name=None):
            self.char, self.name = char, name

    times = iter([0.0, 5.0, 5.01, 5.02, 5.03])
    got = []
    decoder = WedgeDecoder(got.append, clock=times.__next__)
    for key in [KeyCode("9"), KeyCode("1"), KeyCode("."), KeyCode("5"), KeyCode(name="enter")]:
        decoder.feed(key_symbol(key))
    assert got[0].value == 1.5 and got[0].raw == "1.5"


def test_wedge_listener_fails_clearly_without_a_display():
    if os.environ.get("DISPLAY"):
        pytest.skip("a display is available")
    with pytest.raises(Exception, match="cannot start a keyboard listener"):
        WedgeListener(WedgeDecoder(print)).start()


def test_serial_calliper_over_a_pty():
    with pty_pair() as (master, port):
        sim = CalliperSimulator()
        os.write(master, sim.serial_lines([10.004, 24.996]) + b"12,3,4\r\n")
        calliper = SerialCalliper(port, name="calliper")
        first, second = calliper.read(timeout_s=2), calliper.read(timeout_s=2)
        assert isinstance(first, Reading) and (first.value, second.value) == (10.0, 25.0) and first.raw == "10.00"
        with pytest.raises(MalformedSample, match=r"'12,3,4' is not a length"):
            calliper.read(timeout_s=2)
        os.write(master, b"13.0")
        with pytest.raises(
            LinkTimeout, match=r"calliper .*no complete line after 0\.\d+ s \(received so far: b'13.0'\)"
        ):
            calliper.read(timeout_s=0.2)


def test_tilt_from_two_depths():
    assert tilt_deg(10.0, 10.0 + 40 * np.tan(np.radians(20)), 40.0) == pytest.approx(20.0)
    h1, h2 = depths_for_tilt(np.array([-4.0, 0.0, 7.5]), 40.0, 25.0)
    np.testing.assert_allclose(tilt_deg(h1, h2, 40.0), [-4.0, 0.0, 7.5])
    with pytest.raises(ConfigError, match="spacing_mm = 0"):
        tilt_deg(1, 2, 0)


@pytest.mark.parametrize("theta_deg, u_deg", [(0.0, 0.024), (20.0, 0.034)])
def test_tilt_uncertainty_worked_example(theta_deg, u_deg):  # iso9283.md §8.2(d): s = 40, u(h) = 0.0119, u(s) = 0.058
    dh = 40 * np.tan(np.radians(theta_deg))
    assert tilt_uncertainty_deg(0.0, dh, 40.0, 0.0119, 0.058) == pytest.approx(u_deg, abs=0.0005)


def test_play_bias_is_a_measured_correction():
    # the dissertation's -4 deg bias about y (§8.6.6), measured 5 times at home with the actuators locked
    sim = CalliperSimulator(noise_mm=0.003, seed=4)
    h1, h2 = depths_for_tilt(np.full(5, -4.0), 40.0, 25.0)
    repeats = tilt_deg(sim.values(h1), CalliperSimulator(noise_mm=0.003, seed=5).values(h2), 40.0)
    bias = TiltBias.from_repeats(list(repeats), calibration_id="beta-bias-2026-11-23")
    assert bias.mean_deg == pytest.approx(-4.0, abs=0.03)
    t1, t2 = depths_for_tilt(6.0, 40.0, 25.0)  # a true -4 + 10 deg -> measured 6, corrected 10
    stamp = {"unit": "mm", "t_monotonic_s": 1.0, "t_wall_s": 1.0, "source": "calliper"}
    reading = tilt_reading(Reading(float(t1), **stamp), Reading(float(t2), **stamp), 40.0, bias)
    assert reading.unit == "deg" and reading.value == pytest.approx(10.0, abs=0.03)
    assert reading.calibration_id == "beta-bias-2026-11-23"
    assert TiltBias(-3.0, 0.02, 5, "next-day").changed_since(bias)
    assert not TiltBias(bias.mean_deg + 0.001, 0.02, 5, "next-day").changed_since(bias)
    with pytest.raises(InsufficientData, match="4 repeats, expected at least 5"):
        TiltBias.from_repeats([-4.0] * 4, calibration_id="x")


def test_evdev_wedge_decodes_keyboard_events_with_shift(tmp_path):
    sim = CalliperSimulator(noise_mm=0.01, seed=8)
    true_mm = [12.345, 0.5, 149.99]
    path = tmp_path / "usb-Sylvac_wedge-event-kbd"
    extra = encode_keystrokes(["+", "7", ",", "2", "5", "space", "m", "m", "enter"], t0_s=1.0)
    path.write_bytes(sim.wedge_input_events(true_mm) + extra)
    got, rejects = [], []
    wedge = EvdevWedge(
        str(path),
        WedgeDecoder(got.append, on_reject=rejects.append, name="wedge", clock=iter(np.arange(0, 100, 0.001)).__next__),
    )
    readings = wedge.poll(timeout_s=0.5)
    wedge.close()
    assert readings == got and not rejects
    assert [r.value for r in readings] == pytest.approx([*sim.values(true_mm).tolist(), 7.25])
    assert readings[-1].raw == "+7,25 mm"  # '+' typed with Shift, ',' decimal, unit suffix


def test_wedge_events_split_anywhere_give_the_same_readings(tmp_path):
    data = CalliperSimulator().wedge_input_events([3.14, 2.72])
    fifo = tmp_path / "wedge.fifo"
    os.mkfifo(fifo)
    writer = os.open(fifo, os.O_RDWR)  # keeps the FIFO open, as a device stays open
    got = []
    wedge = EvdevWedge(str(fifo), WedgeDecoder(got.append, clock=iter(np.arange(0, 100, 0.001)).__next__))
    for start in range(0, len(data), 37):  # 37 bytes: records cut in the middle
        os.write(writer, data[start : start + 37])
        wedge.poll(timeout_s=0.2)
    os.close(writer)
    wedge.close()
    assert [r.value for r in got] == [3.14, 2.72]
