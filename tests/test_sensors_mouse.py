"""Optical mouse: input_event codec, frame assembly, evdev-style reader, simulator and calibration object.

Real values from sensors.md: §1.1 (count sizes per CPI), §1.3 (ADNS-2610 on a 61.86 cm sphere: 9391
counts/revolution = 151.81 counts/cm, about 385.6 CPI against 400 nominal), §4.2 (24-byte record).
"""

import errno
import fcntl
import itertools
import os
import struct
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, LinkError
from bench.sensors import Reading, Sensor
from bench.sensors.calibration import CountsCalibration
from bench.sensors.event_device import EVIOCGRAB, EVIOCSCLOCKID, eviocg
from bench.sensors.input_event import (
    EV_KEY,
    EV_REL,
    EV_SYN,
    EVENT,
    EVENT_DTYPE,
    REL_X,
    REL_Y,
    SYN_DROPPED,
    SYN_REPORT,
    FrameAssembler,
    encode_frames,
)
from bench.sensors.mouse import EvdevMouse, MouseGroup, list_mice
from bench.simulators.mouse import (
    MouseSimulator,
    MouseStream,
    circle_motion,
    write_stream,
)

PACK = struct.Struct("llHHi").pack
CAL_800 = CountsCalibration.from_cpi(800)


def test_input_event_is_24_bytes_on_64_bit_linux():
    assert EVENT.size == 24 == struct.calcsize("llHHi")


@pytest.mark.parametrize("cpi, mm_per_count", [(400, 0.0635), (800, 0.03175), (1600, 0.015875)])
def test_nominal_count_size(cpi, mm_per_count):  # sensors.md §1.1
    cal = CountsCalibration.from_cpi(cpi)
    assert cal.counts_to_mm([1, 1]) == pytest.approx([mm_per_count, mm_per_count])
    assert cal.nominal and cal.effective_cpi == pytest.approx((cpi, cpi))


def test_effective_cpi_of_the_adns2610_characterisation():  # sensors.md §1.3: 151.81 counts/cm -> 385.6 CPI
    cal = CountsCalibration.from_scales(10 / 151.81, 10 / 151.81, calibration_id="rpm", date="2026-11-23")
    assert cal.effective_cpi[0] == pytest.approx(385.6, abs=0.05)
    assert not cal.nominal


def test_matrix_calibration_round_trip_and_hash():
    cal = CountsCalibration([[0.0320, 0.0004], [-0.0003, 0.0315]], "ocm-xy-1", "2026-11-23", notes="mirror back")
    again = CountsCalibration.from_dict(cal.to_dict())
    assert again == cal and again.content_hash() == cal.content_hash()
    np.testing.assert_allclose(cal.mm_to_counts(cal.counts_to_mm([[100, -50]])), [[100, -50]])
    assert (
        cal.content_hash()
        != CountsCalibration.from_scales(0.032, 0.0315, calibration_id="ocm-xy-1", date="2026-11-23").content_hash()
    )


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"matrix_mm_per_count": [[1, 2], [2, 4]]}, "singular"),
        ({"matrix_mm_per_count": [1, 2]}, "finite 2x2"),
        ({"date": "23/11/2026"}, "ISO date"),
    ],
)
def test_bad_calibration_is_refused_naming_the_field(kwargs, match):
    args = {"matrix_mm_per_count": np.eye(2) * 0.03, "calibration_id": "c1", "date": "2026-11-23"} | kwargs
    with pytest.raises(ConfigError, match=match):
        CountsCalibration(**args)
    with pytest.raises(ConfigError, match="unknown keys"):
        CountsCalibration.from_dict(
            {"calibration_id": "c", "date": "2026-11-23", "matrix_mm_per_count": [[1, 0], [0, 1]], "cpi": 800}
        )


def test_frames_sum_rel_between_syn_reports_and_skip_dropped_events():
    stream = b"".join(
        [
            PACK(10, 500, EV_REL, REL_X, 5),
            PACK(10, 500, EV_REL, REL_Y, -3),
            PACK(10, 500, EV_SYN, SYN_REPORT, 0),
            PACK(10, 1500, EV_REL, REL_Y, 2),
            PACK(10, 1500, EV_KEY, 0x110, 1),
            PACK(10, 1500, EV_SYN, SYN_REPORT, 0),
            PACK(10, 2500, EV_SYN, SYN_DROPPED, 0),
            PACK(10, 2500, EV_REL, REL_X, 100),
            PACK(10, 2500, EV_SYN, SYN_REPORT, 0),
            PACK(11, 0, EV_REL, REL_X, 1),
            PACK(11, 0, EV_REL, REL_X, 1),
            PACK(11, 0, EV_SYN, SYN_REPORT, 0),
            PACK(11, 1000, EV_REL, REL_X, 7),  # incomplete frame: carried, not emitted
        ]
    )
    frames = FrameAssembler().feed(stream)
    assert frames.dx.tolist() == [5, 0, 0, 2]
    assert frames.dy.tolist() == [-3, 2, 0, 0]
    assert frames.valid.tolist() == [True, True, False, True]
    assert frames.t_s.tolist() == pytest.approx([10.0005, 10.0015, 10.0025, 11.0])


_event = st.one_of(
    st.tuples(st.just(EV_REL), st.sampled_from([REL_X, REL_Y]), st.integers(-(2**31), 2**31 - 1)),
    st.tuples(st.just(EV_SYN), st.sampled_from([SYN_REPORT, SYN_REPORT, SYN_DROPPED]), st.just(0)),
    st.tuples(st.just(EV_KEY), st.just(0x110), st.integers(0, 1)),
)


@settings(max_examples=150, deadline=None)
@given(events=st.lists(_event, max_size=60), cuts=st.lists(st.integers(0, 60 * 24), max_size=5))
def test_assembly_is_independent_of_chunking(events, cuts):
    stream = b"".join(PACK(1, k, t, c, v) for k, (t, c, v) in enumerate(events))
    reference = FrameAssembler()._feed_events_loop(np.frombuffer(stream, EVENT_DTYPE))[0]
    assembler = FrameAssembler()
    bounds = [0, *sorted(min(c, len(stream)) for c in cuts), len(stream)]
    parts = [assembler.feed(stream[a:b]) for a, b in itertools.pairwise(bounds)]
    got = {f: np.concatenate([getattr(p, f) for p in parts]) for f in ("t_s", "dx", "dy", "valid")}
    for field in ("t_s", "dx", "dy", "valid"):
        np.testing.assert_array_equal(got[field], getattr(reference, field))


@settings(max_examples=100, deadline=None)
@given(dx=st.lists(st.integers(-127, 127), min_size=1, max_size=50), data=st.data())
def test_encode_then_assemble_round_trip(dx, data):
    dy = data.draw(st.lists(st.integers(-127, 127), min_size=len(dx), max_size=len(dx)))
    t_s = 100.0 + np.arange(len(dx)) / 8000
    frames = FrameAssembler().feed(encode_frames(t_s, dx, dy))
    assert frames.dx.tolist() == dx and frames.dy.tolist() == dy
    np.testing.assert_allclose(frames.t_s, t_s, atol=1e-6)


def test_simulator_reproduces_the_adns2610_count_per_revolution():
    # sensors.md §1.3: 61.86 cm per revolution, 9391 counts at -3.6 % of 400 CPI.
    scale_error = 151.81 / (400 / 2.54) - 1
    sim = MouseSimulator(cpi=400, scale_error=(scale_error, scale_error), report_rate_hz=1000)
    t_s = np.linspace(0, 6.186, 200)
    rep = sim.reports(t_s, np.column_stack([t_s * 100, np.zeros_like(t_s)]))
    assert abs(int(rep.dx.sum()) - 9391) <= 1 and rep.dy.sum() == 0
    assert scale_error == pytest.approx(-0.036, abs=0.001)


def test_simulator_quantises_with_carry_and_clips_per_report_field():
    sim = MouseSimulator(cpi=800, report_rate_hz=1000, report_idle=True)
    t_s, xy = circle_motion(2.0, radius_mm=20, period_s=2.0)
    rep = sim.reports(t_s, xy)
    # a closed circle returns to its start: the counts sum to zero exactly, no drift from rounding
    assert rep.dx.sum() == 0 and rep.dy.sum() == 0
    assert len(rep.t_s) == 2000 and rep.t_s[0] == pytest.approx(0.001)
    fast = MouseSimulator(cpi=1600, report_rate_hz=125, max_delta=127)
    t_s = np.array([0.0, 1.0])
    rep = fast.reports(t_s, np.array([[0.0, 0.0], [3000.0, 0.0]]))  # 3 m/s > 2016 mm/s limit (§4.9)
    assert rep.dx.max() == 127 and rep.dx.sum() * 25.4 / 1600 < 2016.1


def test_reader_integrates_a_file_written_by_the_simulator(tmp_path):
    sim = MouseSimulator(cpi=800, scale_error=(0.01, -0.02), noise_counts=0.3, report_rate_hz=8000, seed=3)
    t_s = np.array([0.0, 0.5, 1.0])
    xy = np.array([[0.0, 0.0], [20.0, -10.0], [40.0, 5.0]])
    path = tmp_path / "event-mouse.bin"
    path.write_bytes(sim.input_events(t_s, xy, t0_s=1000.0))
    with EvdevMouse(str(path), CAL_800, label="XY", grab=True) as mouse:
        assert isinstance(mouse, Sensor)
        reading = mouse.read()
    assert isinstance(reading, Reading) and reading.unit == "mm" and reading.valid
    assert reading.calibration_id == "nominal-800cpi" and "XY" in reading.source
    # nominal calibration reads the true 40 mm / 5 mm scaled by the sensor's own scale error (1 %, -2 %)
    assert reading.value[0] == pytest.approx(40 * 1.01, abs=0.1)
    assert reading.value[1] == pytest.approx(5 * 0.98, abs=0.1)


def test_two_mice_over_fifos_are_told_apart(tmp_path):
    sim = MouseSimulator(cpi=800, report_rate_hz=2000, report_idle=True)
    t_s = np.array([0.0, 0.25])
    streams = {
        "XY": sim.input_events(t_s, np.array([[0, 0], [10.0, 0]])),
        "Z": sim.input_events(t_s, np.array([[0, 0], [0, -5.0]])),
    }
    paths = {}
    for label in streams:
        paths[label] = str(tmp_path / label)
        os.mkfifo(paths[label])

    def writer(label):
        fd = os.open(paths[label], os.O_WRONLY)
        write_stream(fd, streams[label])
        os.close(fd)

    threads = [threading.Thread(target=writer, args=(label,)) for label in streams]
    for thread in threads:
        thread.start()
    group = MouseGroup([EvdevMouse(paths[label], CAL_800, label=label) for label in streams])
    frames = group.collect(5.0)
    group.close()
    for thread in threads:
        thread.join()
    assert len(frames["XY"]) == len(frames["Z"]) == 500
    assert (frames["XY"].dx.sum(), frames["XY"].dy.sum()) == (315, 0)  # 10 mm * 800/25.4 = 314.96
    assert (frames["Z"].dx.sum(), frames["Z"].dy.sum()) == (0, -157)


def test_lost_counts_invalidate_the_segment_until_rezero(tmp_path):
    path = tmp_path / "dropped.bin"
    path.write_bytes(
        encode_frames([1.0], [10], [0])
        + PACK(1, 10, EV_SYN, SYN_DROPPED, 0)
        + encode_frames([1.01, 1.02], [5, 3], [0, 0])
    )
    with EvdevMouse(str(path), CAL_800, label="XY") as mouse:
        first = mouse.read()
        mouse.rezero()
        assert mouse.read().valid
    assert not first.valid and "SYN_DROPPED" in first.note and first.raw == (13, 0)


def test_missing_device_and_permission_denied_name_the_device(tmp_path, monkeypatch):
    with pytest.raises(LinkError, match=r"mouse 'XY': /nonexistent/event7 does not exist; is the mouse plugged"):
        EvdevMouse("/nonexistent/event7", CAL_800, label="XY")
    locked = tmp_path / "event9"
    locked.write_bytes(b"")

    def denied(path, flags, *args):  # the suite may run as root, where mode 0 does not deny
        raise PermissionError(13, "Permission denied", path)

    monkeypatch.setattr(os, "open", denied)
    with pytest.raises(LinkError, match="permission denied on .*event9; add a udev rule"):
        EvdevMouse(str(locked), CAL_800, label="XY")


def test_simulator_refuses_bad_rate_and_motion():
    with pytest.raises(ConfigError, match="report_rate_hz = 9000"):
        MouseSimulator(report_rate_hz=9000)
    with pytest.raises(ConfigError, match="expected increasing times"):
        MouseSimulator().reports(np.array([0.0, 0.0]), np.zeros((2, 2)))


def test_eviocgname_request_number():  # include/uapi/linux/input.h: EVIOCGNAME(len) = _IOC(_IOC_READ, 'E', 0x06, len)
    assert eviocg(0x06, 256) == 0x81004506 and eviocg(0x07, 256) == 0x81004507


def test_list_mice_reads_sysfs_and_prefers_by_path_links(tmp_path):
    sysfs, dev = tmp_path / "sys", tmp_path / "dev"
    devices = {
        "event3": ("Logitech USB Optical Mouse", "usb-0000:00:14.0-2/input0", "3"),
        "event4": ("Logitech USB Optical Mouse", "usb-0000:00:14.0-3/input0", "1943"),
        "event5": ("AT Translated Set 2 keyboard", "isa0060/serio0/input0", "0"),
    }
    for node, (name, phys, rel) in devices.items():
        folder = sysfs / node / "device"
        (folder / "capabilities").mkdir(parents=True)
        (folder / "name").write_text(name + "\n")
        (folder / "phys").write_text(phys + "\n")
        (folder / "capabilities" / "rel").write_text(rel + "\n")
    (dev / "by-path").mkdir(parents=True)
    (dev / "by-path" / "pci-0000:00:14.0-usb-0:2:1.0-event-mouse").symlink_to("../event3")
    (dev / "by-id").mkdir()
    (dev / "by-id" / "usb-Logitech_USB_Optical_Mouse-event-mouse").symlink_to("../event3")
    mice = list_mice(dev_root=str(dev), sysfs_root=str(sysfs))
    assert [m.label for m in mice] == ["event3", "event4"]  # the keyboard has no REL_X/REL_Y
    assert mice[0].path.endswith("by-path/pci-0000:00:14.0-usb-0:2:1.0-event-mouse")
    assert mice[1].path == str(dev / "event4")  # identical mouse told apart by phys
    assert mice[0].name == mice[1].name and mice[0].phys != mice[1].phys


@settings(max_examples=40, deadline=None)
@given(cuts=st.lists(st.integers(2, 1999), max_size=6, unique=True), noise=st.sampled_from([0.0, 0.4]))
def test_stream_in_chunks_equals_the_whole_motion(cuts, noise):
    sim = MouseSimulator(
        cpi=1000,
        scale_error=(0.02, -0.01),
        rotation_deg=3.0,
        noise_counts=noise,
        report_rate_hz=4000,
        report_idle=True,
        seed=9,
    )
    t_s, xy = circle_motion(2.0, radius_mm=15, period_s=1.5, rate_hz=1000)
    whole = sim.reports(t_s, xy)
    stream = MouseStream(sim, origin_mm=xy[0], t0_s=t_s[0])
    bounds = [1, *sorted(cuts), len(t_s)]
    parts = [stream.advance(t_s[a:b], xy[a:b]) for a, b in itertools.pairwise(bounds)]
    np.testing.assert_array_equal(np.concatenate([p.dx for p in parts]), whole.dx)
    np.testing.assert_array_equal(np.concatenate([p.dy for p in parts]), whole.dy)
    np.testing.assert_allclose(np.concatenate([p.t_s for p in parts]), whole.t_s, atol=1e-9)
    with pytest.raises(ConfigError, match="after 2 s"):
        stream.advance([1.0], [[0.0, 0.0]])


def test_grab_is_attempted_only_on_character_devices_and_fails_clearly(tmp_path, monkeypatch):
    # /dev/null is a character device but not an input device: the grab ioctl fails and says so
    with pytest.raises(LinkError, match=r"mouse 'XY' \(/dev/null\): exclusive grab failed"):
        EvdevMouse("/dev/null", CAL_800, label="XY", grab=True)
    calls = []

    def busy(fd, request, arg):
        calls.append(request)
        if request == EVIOCGRAB:
            raise OSError(errno.EBUSY, "Device or resource busy")
        return arg

    monkeypatch.setattr(fcntl, "ioctl", busy)
    with pytest.raises(LinkError, match=r"\(another program holds it\); close that program or run without grab"):
        EvdevMouse("/dev/null", CAL_800, label="XY", grab=True)
    assert calls[-2:] == [EVIOCSCLOCKID, EVIOCGRAB]  # monotonic clock first, then the grab
    assert EVIOCGRAB == 0x40044590 and EVIOCSCLOCKID == 0x400445A0  # sensors.md §4.5, §4.6
    calls.clear()
    path = tmp_path / "recorded.bin"
    path.write_bytes(b"")
    EvdevMouse(str(path), CAL_800, label="XY", grab=True).close()
    assert calls == []  # a file is never grabbed


def test_unplugged_device_fails_the_segment_with_a_clear_error(tmp_path, monkeypatch):
    path = tmp_path / "event3"
    path.write_bytes(encode_frames([1.0], [1], [0]))
    mouse = EvdevMouse(str(path), CAL_800, label="XY")

    def gone(fd, size):
        raise OSError(errno.ENODEV, "No such device")

    monkeypatch.setattr(os, "read", gone)
    with pytest.raises(
        LinkError,
        match=r"mouse 'XY' .*read failed \(No such device\); the device was probably "
        "unplugged: the run segment is invalid",
    ):
        mouse.read()
    monkeypatch.undo()
    mouse.close()
