"""A streamed capture whose reports cannot be a mouse's trace is refused at capture (issue 32 follow-up): a mouse
stamps its reports with the kernel's monotonic clock, so report times that run backwards (as the simulated mice's
backdated motion gave on a path run, stored as good and refused only by the analysis) fail the capture with one line
naming the mouse and what was wrong.

The mice are real :class:`bench.sensors.mouse.EvdevMouse` readers on FIFOs, written ``input_event`` records as a
kernel event device gives them.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from test_mice_liveness import CPI, PLANES, _fifo_mice

from bench.rigs.mice import PATH, MiceInstrument
from bench.sensors.calibration import MM_PER_INCH
from bench.sensors.input_event import encode_frames
from bench.sensors.reading import SensorStalled
from bench.steps import Capture


@pytest.fixture()
def fifo_mice(tmp_path):
    """Two 800 cpi mice on FIFOs and the FIFOs' write ends: (mice, writers, calibration)."""
    with _fifo_mice(tmp_path) as opened:
        yield opened


def _segment_capture(dx_mm: float) -> Capture:
    """A path segment along x of ``dx_mm`` from the origin, its window reaching 1 s back."""
    commanded = {"cmd_x_mm": dx_mm, "cmd_y_mm": 0.0, "cmd_z_mm": 0.0}
    return Capture("line", 1, kind=PATH, commanded=commanded, conditions={"lead_s": 1.0, "hold_s": 0.0})


def _write_motion(writers, t_s: np.ndarray, dx_counts: int) -> None:
    """Both mice see ``dx_counts`` along x over the reports at ``t_s`` (both mice ride the platform)."""
    split = np.diff(np.round(np.linspace(0, dx_counts, len(t_s) + 1)).astype(np.int64))
    for plane in PLANES:
        os.write(writers[plane], encode_frames(t_s, split, np.zeros_like(split), skip_zero=False))


def _measure(fifo_mice, t_s: np.ndarray, dx_mm: float):
    mice, writers, calibration = fifo_mice
    instrument = MiceInstrument(mice, (0.0, 0.0, 0.0), calibration)
    try:
        _write_motion(writers, t_s, round(dx_mm * CPI / MM_PER_INCH))
        return instrument.measure(_segment_capture(dx_mm))
    finally:
        instrument.close()


def test_a_monotonic_stream_gives_the_segments_series(fifo_mice):
    t_s = time.monotonic() - 0.5 + 0.002 * np.arange(50)
    measured = _measure(fifo_mice, t_s, 4.0)
    series = measured.raw["series"]
    assert np.all(np.diff(series["t_s"]) > 0)
    assert np.all(np.diff(series["x_mm"]) >= 0)  # a move along +x only: the position never goes back
    assert measured.values["x_mm"] == pytest.approx(4.0, abs=MM_PER_INCH / CPI)


def test_report_times_that_run_backwards_are_refused_at_capture_naming_the_mouse(fifo_mice):
    """Two bursts of reports, the second stamped before the first ended (the simulated mice's backdated motion of
    two rests in quick succession): the capture fails with the mouse and the first backwards report named."""
    now = time.monotonic()
    first = now - 0.5 + 0.002 * np.arange(25)
    second = first[-1] - 0.03 + 0.002 * np.arange(1, 26)  # starts 30 ms before the first burst's end
    with pytest.raises(SensorStalled) as refused:
        _measure(fifo_mice, np.concatenate([first, second]), 4.0)
    message = str(refused.value)
    assert message.startswith("mouse_xy (")
    assert "report times run backwards" in message
    assert f"after one at {first[-1]:.6f} s" in message
    assert "pose 'line', cycle 1" in message
    assert "\n" not in message


def test_a_segment_whose_move_came_before_its_window_is_refused_naming_the_mouse(fifo_mice):
    """The move's reports all older than the window (the segment's duration back from the request): the series
    would hold the robot still through its move, so the capture is refused."""
    t_s = time.monotonic() - 3.0 + 0.002 * np.arange(50)  # 3 s before the request; the window reaches 1 s back
    with pytest.raises(SensorStalled) as refused:
        _measure(fifo_mice, t_s, 4.0)
    message = str(refused.value)
    assert message.startswith("mouse_xy (")
    assert "reported motion since the last capture but none in the move's window" in message
    assert "speed factor" not in message  # the instrument's clock is the kernel's: no rehearsal to blame
