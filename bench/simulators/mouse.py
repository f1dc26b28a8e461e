"""Simulated optical mouse: a true motion in mm -> the ``input_event`` records (or MCU lines) the sensor would send.

Models what makes a mouse imperfect (``sensors.md`` §1.3, §4.9): an integer count quantisation with carry, a scale
(CPI) error per axis, a mounting rotation, white position noise, a fixed report rate (up to 8 kHz) and the
per-report field width. Also a program: ``python -m bench.simulators.mouse --out FIFO`` writes a stream into a
pipe or file that :class:`bench.sensors.mouse.EvdevMouse` opens like a device.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

from bench.errors import ConfigError
from bench.sensors.calibration import DEFAULT_CPI, MM_PER_INCH
from bench.sensors.input_event import EVENT, encode_frames

__all__ = [
    "MouseReports",
    "MouseSimulator",
    "add_stream_arguments",
    "circle_motion",
    "main",
    "write_circle_stream",
    "write_stream",
    "write_stream_from_args",
]

MAX_REPORT_RATE_HZ = 8000.0


@dataclass(frozen=True)
class MouseReports:
    """Reports of a simulated mouse: times (s) and per-report counts (int64), all of shape (n,)."""

    t_s: np.ndarray
    dx: np.ndarray
    dy: np.ndarray


@dataclass(frozen=True)
class MouseSimulator:
    """A mouse observing a true planar motion.

    Parameters
    ----------
    cpi : float
        Nominal counts per inch.
    scale_error : tuple of float
        Relative error of the true scale per sensor axis, e.g. ``(-0.036, 0.01)`` (the ADNS-2610 read 3.6 % low,
        ``sensors.md`` §1.3).
    rotation_deg : float
        Mounting rotation of the sensor axes relative to the motion axes (deg).
    noise_counts : float
        Standard deviation of white noise on the sensed position (counts).
    report_rate_hz : float
        Report rate, at most 8000 Hz.
    max_delta : int or None
        Largest count per report per axis (127 for 8-bit HID fields); larger motion is clipped and lost.
    report_idle : bool
        Send reports with zero motion too (a real HID mouse stays silent when still).
    seed : int
        Seed of the noise generator; the same inputs give the same bytes.
    """

    cpi: float = DEFAULT_CPI
    scale_error: tuple[float, float] = (0.0, 0.0)
    rotation_deg: float = 0.0
    noise_counts: float = 0.0
    report_rate_hz: float = 1000.0
    max_delta: int | None = None
    report_idle: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0 < self.report_rate_hz <= MAX_REPORT_RATE_HZ:
            raise ConfigError(
                f"mouse simulator: report_rate_hz = {self.report_rate_hz!r}, "
                f"expected 0 < rate <= {MAX_REPORT_RATE_HZ:g}"
            )
        if not self.cpi > 0:
            raise ConfigError(f"mouse simulator: cpi = {self.cpi!r}, expected a positive number")

    def counts_per_mm(self) -> np.ndarray:
        """True 2x2 map from motion (mm) to sensor counts, including scale error and rotation."""
        c, s = np.cos(np.radians(self.rotation_deg)), np.sin(np.radians(self.rotation_deg))
        rotation = np.array([[c, s], [-s, c]])
        return np.diag(1.0 + np.asarray(self.scale_error)) @ rotation * (self.cpi / MM_PER_INCH)

    def reports(self, t_s: np.ndarray, xy_mm: np.ndarray) -> MouseReports:
        """Sample the true motion at the report rate and quantise it to integer counts.

        Parameters
        ----------
        t_s : array_like, shape (N,)
            Increasing times of the true motion (s).
        xy_mm : array_like, shape (N, 2)
            True positions of the sensor spot (mm), in the motion frame.
        """
        t_s, xy_mm = _checked_motion(t_s, xy_mm, min_points=2)
        return MouseStream(self, origin_mm=xy_mm[0], t0_s=t_s[0]).advance(t_s[1:], xy_mm[1:])

    def input_events(self, t_s: np.ndarray, xy_mm: np.ndarray, *, t0_s: float = 0.0) -> bytes:
        """The motion as kernel ``input_event`` records, timestamps offset by ``t0_s`` (s)."""
        rep = self.reports(t_s, xy_mm)
        return encode_frames(rep.t_s + t0_s, rep.dx, rep.dy)

    def mcu_lines(self, t_s: np.ndarray, xy_mm: np.ndarray, *, squal: int | None = 120) -> bytes:
        """The motion as a microcontroller stream, one ``t_us,dx,dy[,squal]`` line per report."""
        rep = self.reports(t_s, xy_mm)
        t_us = np.round((rep.t_s - rep.t_s[0]) * 1e6).astype(np.int64) if len(rep.t_s) else rep.t_s
        tail = "" if squal is None else f",{squal}"
        return "".join(f"{t},{x},{y}{tail}\n" for t, x, y in zip(t_us, rep.dx, rep.dy)).encode()


def _checked_motion(
    t_s: np.ndarray, xy_mm: np.ndarray, *, min_points: int, after_s: float = -np.inf
) -> tuple[np.ndarray, np.ndarray]:
    t_s, xy_mm = np.asarray(t_s, float), np.asarray(xy_mm, float)
    if (
        t_s.ndim != 1
        or xy_mm.shape != (len(t_s), 2)
        or len(t_s) < min_points
        or (len(t_s) > 1 and not (t_s[1:] > t_s[:-1]).all())
        or (len(t_s) and t_s[0] <= after_s)
        or not np.isfinite(xy_mm).all()
    ):
        after = f" after {after_s:g} s" if np.isfinite(after_s) else ""
        raise ConfigError(
            f"mouse simulator: t_s {t_s.shape} and xy_mm {xy_mm.shape}, expected increasing "
            f"times of shape (N,){after} and finite positions of shape (N, 2) with N >= {min_points}"
        )
    return t_s, xy_mm


class MouseStream:
    """A :class:`MouseSimulator` followed through time: feed the true motion chunk by chunk as a robot moves.

    The sensor's sub-count remainder, its report clock and its noise generator carry over between chunks, so
    quantisation never accumulates and the bytes are the same as for the whole motion at once.

    Parameters
    ----------
    simulator : MouseSimulator
        The sensor model.
    origin_mm : array_like, shape (2,)
        True position (mm) at which the sensor starts (its counts are zero there).
    t0_s : float
        Time of ``origin_mm`` (s) on the simulated clock; the first report follows one report period later.
    """

    def __init__(self, simulator: MouseSimulator, *, origin_mm: np.ndarray, t0_s: float = 0.0) -> None:
        self.simulator = simulator
        self.origin_mm = np.asarray(origin_mm, float).reshape(2)
        self._counts_per_mm = simulator.counts_per_mm()
        self._rng = np.random.default_rng(simulator.seed)
        self._anchor_t_s, self._anchor_mm = float(t0_s), self.origin_mm.copy()
        self._last_report_t_s = float(t0_s)
        self._whole = np.zeros(2, np.int64)

    def advance(self, t_s: np.ndarray, xy_mm: np.ndarray) -> MouseReports:
        """Reports for the true motion from the last given point to ``(t_s, xy_mm)`` (shapes (N,), (N, 2))."""
        # (called after every move of a simulated campaign with a few tens of reports: numpy's per-call cost is
        # most of it, so each step is the cheapest call that gives the same numbers)
        t_s, xy_mm = _checked_motion(t_s, xy_mm, min_points=1, after_s=self._anchor_t_s)
        period = 1.0 / self.simulator.report_rate_hz
        n_reports = max(0, math.floor((float(t_s[-1]) - self._last_report_t_s) / period + 1e-9))
        report_t = self._last_report_t_s + period * np.arange(1, n_reports + 1)
        knots_t = np.concatenate(([self._anchor_t_s], t_s))
        knots_mm = np.concatenate((self._anchor_mm[None, :], xy_mm))
        true_xy = np.empty((n_reports, 2))
        for k in (0, 1):
            true_xy[:, k] = np.interp(report_t, knots_t, knots_mm[:, k])
        sensed = (true_xy - self.origin_mm) @ self._counts_per_mm.T
        if self.simulator.noise_counts > 0:
            sensed += self._rng.normal(0.0, self.simulator.noise_counts, sensed.shape)
        # The sensor accumulates motion and reports whole counts, carrying the remainder.
        whole = np.floor(sensed + 0.5).astype(np.int64)
        deltas = whole.copy()
        deltas[1:] -= whole[:-1]
        deltas[:1] -= self._whole
        if self.simulator.max_delta is not None:  # counts beyond the report field are lost for good
            deltas = np.clip(deltas, -self.simulator.max_delta, self.simulator.max_delta)
        if n_reports:
            self._whole, self._last_report_t_s = whole[-1], float(report_t[-1])
        self._anchor_t_s, self._anchor_mm = float(t_s[-1]), xy_mm[-1].copy()
        if self.simulator.report_idle:
            return MouseReports(report_t, deltas[:, 0], deltas[:, 1])
        keep = (deltas[:, 0] != 0) | (deltas[:, 1] != 0)
        return MouseReports(report_t[keep], deltas[keep, 0], deltas[keep, 1])

    def idle_until(self, t_s: float) -> None:
        """The sensor sat still at its last position until ``t_s``: it sent nothing meanwhile, and its report clock
        resumes there (a long rest costs no report slots to compute)."""
        if t_s > self._anchor_t_s:
            self._anchor_t_s = self._last_report_t_s = float(t_s)

    def input_events(self, t_s: np.ndarray, xy_mm: np.ndarray, *, clock_offset_s: float = 0.0) -> bytes:
        """:meth:`advance` encoded as kernel ``input_event`` records, timestamps shifted by ``clock_offset_s``."""
        reports = self.advance(t_s, xy_mm)
        return encode_frames(reports.t_s + clock_offset_s, reports.dx, reports.dy)


def circle_motion(
    duration_s: float, radius_mm: float = 20.0, period_s: float = 4.0, rate_hz: float = 1000.0
) -> tuple[np.ndarray, np.ndarray]:
    """A circle traced at constant speed from (radius, 0): times (N,) in s and positions (N, 2) in mm."""
    t_s = np.arange(0.0, duration_s + 0.5 / rate_hz, 1.0 / rate_hz)
    phase = 2 * np.pi * t_s / period_s
    return t_s, radius_mm * np.column_stack([np.cos(phase), np.sin(phase)])


def write_stream(fd: int, data: bytes, *, realtime_rate_bytes_s: float | None = None, chunk: int = 24 * 3 * 64) -> None:
    """Write ``data`` to ``fd``, optionally paced to a byte rate so that the reader sees a live stream."""
    start = time.monotonic()
    for offset in range(0, len(data), chunk):
        if realtime_rate_bytes_s:
            delay = start + offset / realtime_rate_bytes_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        view = memoryview(data)[offset : offset + chunk]
        while view:
            view = view[os.write(fd, view) :]


def write_circle_stream(
    out: str,
    *,
    duration_s: float = 10.0,
    rate_hz: float = 1000.0,
    cpi: float = DEFAULT_CPI,
    radius_mm: float = 20.0,
    period_s: float = 4.0,
    realtime: bool = False,
) -> int:
    """Simulate a circle and write its ``input_event`` records to the FIFO or file ``out``; return the event count.

    Timestamps start at ``time.monotonic()`` so that a reader on the same machine sees a live clock.
    """
    sim = MouseSimulator(cpi=cpi, report_rate_hz=rate_hz, report_idle=True)
    data = sim.input_events(*circle_motion(duration_s, radius_mm, period_s, rate_hz), t0_s=time.monotonic())
    fd = os.open(out, os.O_WRONLY | os.O_CREAT, 0o644)
    try:
        write_stream(fd, data, realtime_rate_bytes_s=len(data) / duration_s if realtime else None)
    finally:
        os.close(fd)
    return len(data) // EVENT.size


def add_stream_arguments(parser: argparse.ArgumentParser) -> None:
    """The simulated stream's options, shared by this program and ``bench sensors mouse-sim``."""
    parser.add_argument("--duration-s", type=float, default=10.0)
    parser.add_argument("--rate-hz", type=float, default=1000.0, help="report rate, at most 8000")
    parser.add_argument("--cpi", type=float, default=DEFAULT_CPI)
    parser.add_argument("--radius-mm", type=float, default=20.0)
    parser.add_argument("--period-s", type=float, default=4.0)
    parser.add_argument("--realtime", action="store_true", help="pace the stream to real time")


def write_stream_from_args(args: argparse.Namespace) -> int:
    """:func:`write_circle_stream` with the options of :func:`add_stream_arguments` (and ``args.out``)."""
    return write_circle_stream(
        args.out,
        duration_s=args.duration_s,
        rate_hz=args.rate_hz,
        cpi=args.cpi,
        radius_mm=args.radius_mm,
        period_s=args.period_s,
        realtime=args.realtime,
    )


def main(argv: list[str] | None = None) -> int:
    """Program entry: ``python -m bench.simulators.mouse --out FIFO [options]``."""
    parser = argparse.ArgumentParser(
        prog="python -m bench.simulators.mouse",
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--out", required=True, help="FIFO or file to write input_event records into")
    add_stream_arguments(parser)
    args = parser.parse_args(argv)
    try:
        count = write_stream_from_args(args)
    except ConfigError as exc:
        print(f"mouse_sim: error: {exc}", file=sys.stderr)
        return 2
    print(f"{count} events written to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
