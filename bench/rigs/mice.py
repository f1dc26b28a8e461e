"""The dissertation's instrument: two optical mice, one in the x-y plane and one in the x-z plane, as an Instrument.

Each mouse integrates raw counts since the instrument was registered; counts become mm through the calibration in
force (its id travels with every sample). The instrument frame is registered once, at a known pose of the robot
(its home), so a reading is ``registration + displacement``. The rig builder (:mod:`bench.rigs.builder`) makes it from a
station's ``[mice]``.

A capture of kind ``arrival`` (ISO 9283 7.4 stabilisation time, 7.5 overshoot) is asked right after the controller
reported the move done, and stores the streamed position from ``lead_s`` before that moment to ``hold_s`` after
it: the mice report every motion with a kernel timestamp (``CLOCK_MONOTONIC``), and the reports read since the last
capture (by the reader processes on hardware) hold the end of the move; the instrument then listens for ``hold_s``.
The sample keeps the raw reports of both mice in the window and the counts at its start (the raw data), the
position series they give (times relative to the request), and, as its values, the position at the end of the
window.

A mouse reports only when it moves, so a mouse that stops reporting, closes or freezes would leave its last counts
in place and every later reading stale. Each capture is therefore checked against the robot's commanded motion
since the previous one (:meth:`MiceInstrument._check_alive`): a mouse whose stream ended, which reported no motion
in a commanded move of at least :data:`LIVENESS_MIN_MOVE_MM` in its plane, or fell short of it by more than a
robot's own error and its scale can explain (:data:`LIVENESS_ROBOT_ERROR_MM`, :func:`scale_share`), fails that
capture with
:class:`bench.sensors.reading.SensorStalled` naming the mouse and what it did (no report, reports without motion,
or how far it moved); the run then ends ``failed`` with that reason and nothing of the capture is stored. A mouse
that slips (reads a share of its motion) is caught by the other mouse: both see x, so their x motions since the
previous capture must agree to within what their counts and scales allow (:func:`x_disagreement_tolerance_mm`),
whatever the robot did; the one that saw less is named. An x-z mouse on vertical guides (``xz_mount = "guided"``,
the dissertation's Z mouse) sees z only: it is judged on the commanded z alone, and the x cross-check is off.
"""

from __future__ import annotations

import math
import selectors
import threading
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from bench.errors import LinkError
from bench.rigs.interfaces import Measurement
from bench.rigs.mice_liveness import (
    LIVENESS_MIN_MOVE_MM,
    LIVENESS_ROBOT_ERROR_MM,
    XZ_GUIDED,
    XZ_PLATFORM,
    calibrated_robot_error_mm,
    guided_hint,
    plane_axes,
    scale_share,
    x_disagreement_tolerance_mm,
)
from bench.rigs.mice_series import S_DECIMALS, arrival_series, moved
from bench.sensors.calibration import MM_PER_INCH
from bench.sensors.reading import Reading, SensorStalled
from bench.steps import Capture

__all__ = [
    "ARRIVAL",
    "LIVENESS_MIN_MOVE_MM",
    "LIVENESS_ROBOT_ERROR_MM",
    "PATH",
    "POSITIONING",
    "STREAMED_KINDS",
    "MiceInstrument",
    "arrival_series",
]

#: Capture kind of a streamed arrival at a pose; ``conditions`` give ``lead_s`` and ``hold_s``.
ARRIVAL = "arrival"
#: Capture kind of one streamed segment of a continuous path (ISO 9283 clause 8), captured like an arrival.
PATH = "path"
#: Capture kind of one streamed step of the minimum positioning time sequence (ISO 9283 clause 9), rest to rest.
POSITIONING = "positioning"
#: The capture kinds whose sample keeps the streamed series (in ``raw["series"]``, with ``raw["t_request_s"]``).
STREAMED_KINDS = frozenset({ARRIVAL, PATH, POSITIONING})
#: What a run's settings say of slips along x when the x-z mouse is on vertical guides (no x cross-check).
_GUIDED_NOTE = (
    "the x-z mouse is on vertical guides and sees z only: no x cross-check, so a slip along x is caught by the "
    "commanded-move rule only (a shortfall beyond liveness_robot_error_mm plus the scale's share of the move)"
)


class MiceInstrument:
    """Position (x, y, z) in mm from an x-y mouse and an x-z mouse.

    Parameters
    ----------
    mice : dict
        ``{"xy": EvdevMouse, "xz": EvdevMouse}``: open mice reading raw counts.
    origin_mm : array_like, shape (3,)
        Position of the measuring point when the counts were zero (the registration), mm.
    calibration : bench.sensors.calibration.CountsCalibration
        Counts -> mm, applied by the mice.
    xz_mount : str
        How the x-z mouse is mounted (:data:`bench.rigs.mice_liveness.XZ_MOUNTS`): on the platform, seeing x and
        z, or on vertical guides, seeing z only.
    time_scale : float
        The mice's clock in wall seconds: ``CLOCK_MONOTONIC`` x ``time_scale`` (1 on hardware; a rehearsal's speed
        factor), so a window's ``lead_s`` and ``hold_s`` count the rig's seconds.
    """

    def __init__(
        self,
        mice: dict[str, Any],
        origin_mm: ArrayLike,
        calibration: Any,
        *,
        follow: bool = False,
        noise_counts: float | None = None,
        calibration_record: Mapping[str, Any] | None = None,
        xz_mount: str = XZ_PLATFORM,
        time_scale: float = 1.0,
    ) -> None:
        self.mice = mice
        #: seconds of the mice's report times per wall second: 1 on hardware (the kernel's CLOCK_MONOTONIC); a
        #: rehearsal's speed factor, whose simulated mice stamp reports in the rig's own seconds
        self.time_scale = float(time_scale)
        #: the commanded axes each mouse sees, by how the x-z mouse is mounted (:func:`plane_axes`)
        self.xz_mount, self._plane_axes = xz_mount, plane_axes(xz_mount)
        self.noise_counts = noise_counts
        #: the stored calibration in force (version, nominal, scales and their u): the report's budget reads it
        self.calibration_record = dict(calibration_record) if calibration_record is not None else None
        #: the shortfall a robot's own error may give a commanded move (mm): narrower under a kinematic calibration
        #: in force (:meth:`expect_calibrated_robot`)
        self.robot_error_mm = LIVENESS_ROBOT_ERROR_MM
        for mouse in mice.values():  # registration is now: reports from before it are motion to somewhere else
            mouse.read_frames()
            mouse.rezero()
        self.origin = np.asarray(origin_mm, dtype=float)[:3].copy()
        self.calibration = calibration
        # the liveness check's reference: the registration pose with zero counts, then each checked capture
        self._last_commanded = dict(zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), (float(v) for v in self.origin)))
        self._counts_at_last = {plane: np.zeros(2, np.int64) for plane in mice}
        self._reports_since = {plane: 0 for plane in mice}
        self._lock = threading.Lock()  # every read of a mouse holds it: the reader thread's and the captures'
        self._pending: dict[str, list[Any]] = {plane: [] for plane in mice}
        self._closing = threading.Event()
        self._reader = None
        if follow:
            # a reader process per mouse keeps the kernel's buffers empty: an evdev client buffer holds only some
            # tens of reports (~7 ms at 8 kHz), and an overflow loses counts (SYN_DROPPED); a thread of this
            # process could not, the runner's Python work holds the GIL for longer (bench_mouse_ingest --realtime).
            # The reader thread takes their decoded frames, which wait in the reader processes meanwhile.
            for mouse in mice.values():
                mouse.start_reader_process()
            self._reader = threading.Thread(target=self._listen, name="mice-reader", daemon=True)
            self._reader.start()

    def _drain_locked(self, *, up_to_now: bool = False) -> None:
        """Read what every mouse has now into the pending reports (the caller holds the lock); ``up_to_now``
        includes what a reader process is still sending (a capture's read)."""
        for plane, mouse in self.mice.items():
            frames = mouse.read_frames(up_to_now=up_to_now)
            if len(frames):
                self._pending[plane].append(frames)
                self._reports_since[plane] += len(frames)

    def _take_pending(self) -> dict[str, Any]:
        """Every report read since the last capture (counts already integrated), and forget them."""
        from bench.sensors.input_event import MotionFrames

        with self._lock:
            self._drain_locked(up_to_now=True)
            taken, self._pending = self._pending, {plane: [] for plane in self.mice}
        for mouse in self.mice.values():
            if mouse.exhausted:  # a device never ends: its stream closed, and every later count would be missing
                raise SensorStalled(
                    f"{mouse.name} ({mouse.binding}): the device closed (end of stream); its "
                    "counts stopped there, so this sample is refused; check the mouse's cable "
                    "and reader, then resume the run"
                )
        return {plane: MotionFrames.concatenate(parts) for plane, parts in taken.items()}

    def _check_alive(self, capture: Capture) -> None:
        """Refuse the capture when a mouse did not see a commanded move in its plane since the last capture, or the
        two mice disagree on the x motion they both see.

        The net commanded displacement between two captures (whatever path the robot took between them) against
        the net counts, as mm: no motion in a move of at least :data:`LIVENESS_MIN_MOVE_MM`, or short of it by
        more than the robot's error allows (:attr:`robot_error_mm`) plus the mouse's :func:`scale_share` of it, the
        mouse stopped reporting (no report), froze (reports without motion) or lost the move; :class:`SensorStalled`
        names which. A streamed capture (its window may close before the commanded end) is refused only without any
        motion. Then the two mice's x motions are compared (:meth:`_check_common_axis`): a slip the robot's error
        allowance hides shows there. Captures without commanded positions are not judged and do not move the
        reference.
        """
        commanded = {
            axis: float(capture.commanded[axis])
            for axis in ("cmd_x_mm", "cmd_y_mm", "cmd_z_mm")
            if axis in capture.commanded
        }
        if len(commanded) < 3:
            return
        previous, self._last_commanded = self._last_commanded, commanded
        counts_then = self._counts_at_last
        self._counts_at_last = {plane: mouse.counts.copy() for plane, mouse in self.mice.items()}
        reports, self._reports_since = self._reports_since, {plane: 0 for plane in self.mice}
        moved_counts = {plane: self._counts_at_last[plane] - counts_then[plane] for plane in self.mice}
        moved_mm = {plane: self.calibration.counts_to_mm(counts) for plane, counts in moved_counts.items()}
        hint = self._mount_hint(moved_counts, moved_mm, commanded["cmd_x_mm"] - previous["cmd_x_mm"])
        for plane, axes in self._plane_axes.items():
            expected_mm = math.hypot(*(commanded[a] - previous[a] for a in axes))
            if plane not in self.mice or expected_mm < LIVENESS_MIN_MOVE_MM:
                continue
            counts = moved_counts[plane]
            reported_mm = float(np.linalg.norm(moved_mm[plane]))
            # a streamed capture (a path segment) may end its window before the commanded end: only no motion at
            # all is judged there
            allowed_mm = self.robot_error_mm + scale_share(self.calibration) * expected_mm
            if counts.any() and (capture.kind in STREAMED_KINDS or expected_mm - reported_mm <= allowed_mm):
                continue
            if not counts.any():
                what = (
                    f"sent {reports[plane]} reports without motion (a frozen counter)"
                    if reports[plane]
                    else "sent no report"
                )
            else:
                what = f"reported {reported_mm:.3f} mm"
            mouse = self.mice[plane]
            raise SensorStalled(
                f"{mouse.name} ({mouse.binding}): {what} while the robot was commanded "
                f"{expected_mm:.3f} mm in its plane since the last capture (pose {capture.pose!r}, "
                f"cycle {capture.cycle}); the mouse stopped, froze or lost the surface (or the "
                f"robot did not move), so this sample is refused{hint if plane == 'xz' else ''}"
            )
        if set(moved_mm) == {"xy", "xz"} and self.xz_mount != XZ_GUIDED:
            self._check_common_axis(moved_mm, capture, hint)

    def _mount_hint(
        self, moved_counts: Mapping[str, np.ndarray], moved_mm: Mapping[str, np.ndarray], commanded_x_mm: float
    ) -> str:
        """:func:`guided_hint` for an x-z mouse taken to ride the platform, over the larger of the commanded x
        motion and the x-y mouse's (an erring robot moves in x where none was commanded); empty otherwise."""
        if self.xz_mount != XZ_PLATFORM or "xz" not in moved_counts:
            return ""
        seen_x_mm = float(moved_mm["xy"][0]) if "xy" in moved_mm else 0.0
        return guided_hint(moved_counts["xz"], max(abs(commanded_x_mm), abs(seen_x_mm)))

    def expect_calibrated_robot(self, ap_after_mm: float) -> None:
        """A kinematic calibration whose own mean error at its poses is ``ap_after_mm`` is in force: a commanded
        move may fall short by :func:`calibrated_robot_error_mm` only (called by
        :func:`bench.calibration.compensate.put_in_force`)."""
        self.robot_error_mm = calibrated_robot_error_mm(ap_after_mm)

    def _check_common_axis(self, moved_mm: Mapping[str, np.ndarray], capture: Capture, hint: str = "") -> None:
        """Refuse the capture when the two mice's x motions since the last capture differ by more than
        :func:`x_disagreement_tolerance_mm` allows, naming the mouse that saw less (a slipping or lifted mouse loses
        motion; none invents it); ``hint`` (:meth:`_mount_hint`) is added when that is the x-z mouse.

        Not called for an x-z mouse on vertical guides (``xz_mount = "guided"``), which sees no x.

        [choice] Both mice ride the one platform and see its x: whatever pose the robot attained, off its command
        by its geometry (an uncalibrated pkm5 by up to 19 mm) or its play, it moved both alike, so this check needs
        no allowance for the robot's error, which the commanded-move rule above must grant (and which hides a mouse
        reading 30 % of every move). It sees a slip in a move with x motion; a move along y or z alone is judged by
        the rule above only, and the slip is caught at the next move with x.
        """
        xy_mm, xz_mm = (np.asarray(moved_mm[plane], dtype=float) for plane in ("xy", "xz"))
        disagreement_mm = abs(float(xy_mm[0] - xz_mm[0]))
        tolerance_mm = x_disagreement_tolerance_mm(xy_mm, xz_mm, self.calibration)
        if disagreement_mm <= tolerance_mm:
            return
        less, more = ("xy", "xz") if abs(xy_mm[0]) < abs(xz_mm[0]) else ("xz", "xy")
        mouse, other = self.mice[less], self.mice[more]
        raise SensorStalled(
            f"{mouse.name} ({mouse.binding}): saw {float(moved_mm[less][0]):.3f} mm in x since the last capture "
            f"where {other.name} saw {float(moved_mm[more][0]):.3f} mm (pose {capture.pose!r}, cycle "
            f"{capture.cycle}); both ride the platform, and they differ by {disagreement_mm:.3f} mm, more than the "
            f"{tolerance_mm:.3f} mm their counts and scales allow: the mouse slipped or lost the surface, so this "
            f"sample is refused{hint if less == 'xz' else ''}"
        )

    def _read(self) -> tuple[Any, Any]:
        """The integrated readings of both mice now."""
        self._take_pending()
        with self._lock:
            return self.mice["xy"].reading(), self.mice["xz"].reading()

    def position_mm(self) -> np.ndarray:
        """The position (x, y, z) the mice read now, mm (the registration's check, :mod:`bench.rigs.registration`)."""
        return self._position_mm(*self._read())

    def _position_mm(self, xy: Reading, xz: Reading) -> np.ndarray:
        """x and y from the x-y mouse, z from the x-z mouse, in the registered frame, mm."""
        x_z = np.asarray(xz.value, dtype=float)
        return np.array([*(self.origin[:2] + np.asarray(xy.value)), self.origin[2] + x_z[1]], dtype=float)

    def shift_origin(self, shift_mm: ArrayLike) -> None:
        """Move the frame by ``shift_mm`` (x, y, z): every later reading is ``shift_mm`` smaller (the registration
        re-referenced to the mean return home)."""
        self.origin = self.origin - np.asarray(shift_mm, dtype=float)[:3]

    def measure(self, capture: Capture) -> Measurement:
        if capture.kind in STREAMED_KINDS:
            return self._measure_arrival(capture)
        xy, xz = self._read()
        self._check_alive(capture)
        if capture.kind == "mouse":  # calibration runs store the raw counts themselves
            counts = {
                "mouse_xy_x_counts": xy.raw[0],
                "mouse_xy_y_counts": xy.raw[1],
                "mouse_xz_x_counts": xz.raw[0],
                "mouse_xz_z_counts": xz.raw[1],
            }
            return Measurement(
                {k: float(v) for k, v in counts.items()}, raw={"calibration": self.calibration.calibration_id}
            )
        x_mm, y_mm, z_mm = self._position_mm(xy, xz)
        return Measurement(
            {"x_mm": float(x_mm), "y_mm": float(y_mm), "z_mm": float(z_mm)},
            raw={
                "counts_xy": list(xy.raw),
                "counts_xz": list(xz.raw),
                "valid": bool(xy.valid and xz.valid),
                "calibration": self.calibration.calibration_id,
            },
        )

    def _measure_arrival(self, capture: Capture) -> Measurement:
        from bench.sensors.input_event import MotionFrames

        lead_s, hold_s = float(capture.conditions["lead_s"]), float(capture.conditions["hold_s"])
        streamed, t_request = self._stream(lead_s, hold_s)
        self._check_trace(streamed, capture, window_start_s=t_request - lead_s)
        self._check_alive(capture)
        frames = {}  # the window only: older reports (the rest of the move) are in the counts already
        for plane, f in streamed.items():
            keep = f.t_s >= t_request - lead_s
            frames[plane] = MotionFrames(f.t_s[keep], f.dx[keep], f.dy[keep], f.valid[keep])
        counts_before = {
            plane: self.mice[plane].counts - np.array([f.dx.sum(), f.dy.sum()], np.int64) for plane, f in frames.items()
        }
        series, raw = arrival_series(
            frames, counts_before, self.calibration, self.origin, t_request=t_request, lead_s=lead_s, hold_s=hold_s
        )
        values = {axis: float(series[axis][-1]) for axis in ("x_mm", "y_mm", "z_mm")}
        valid = all(mouse.segment_valid for mouse in self.mice.values())
        return Measurement(
            values,
            raw={
                **raw,
                "series": series,
                "valid": valid,
                "t_request_s": round(t_request, S_DECIMALS),
                "calibration": self.calibration.calibration_id,
            },
        )

    def _check_trace(self, streamed: Mapping[str, Any], capture: Capture, *, window_start_s: float) -> None:
        """Refuse a streamed capture whose reports cannot be a trace of the move, naming the mouse
        (:class:`SensorStalled`; nothing of the capture is stored).

        A mouse stamps each report with the kernel's ``CLOCK_MONOTONIC`` as it sends it, so its report times never
        decrease: reports out of time order (a reader or device stamping wrongly, a feed replaying motion into the
        past) would place the robot wherever the later-stamped counts fall. A streamed capture (its window reaches
        back over the move's end: a path segment's or positioning step's duration, an arrival's approach) whose
        mouse moved since the last capture but reported none of it in the window would store the robot still
        through its move.
        """
        for plane, frames in streamed.items():
            mouse = self.mice[plane]
            backwards = np.flatnonzero(np.diff(frames.t_s) < 0)
            if len(backwards):
                first = int(backwards[0])
                what = (
                    f"its report times run backwards ({len(backwards)} of {len(frames)} reports earlier than the "
                    f"one before; the first at {frames.t_s[first + 1]:.6f} s after one at {frames.t_s[first]:.6f} "
                    "s); a mouse's kernel timestamps never decrease"
                )
            elif moved(frames) and not moved(frames, window_start_s):
                what = (
                    f"it reported motion since the last capture but none in the move's window (from "
                    f"{window_start_s:.6f} s on); the move came before it{self._turnaround_hint()}"
                )
            else:
                continue
            raise SensorStalled(
                f"{mouse.name} ({mouse.binding}): {what}, in the streamed capture at pose {capture.pose!r}, cycle "
                f"{capture.cycle}: no trace of the robot's motion, so this sample is refused; check the mouse's "
                "reader and device, then resume the run"
            )

    def _turnaround_hint(self) -> str:
        """Why a rehearsal's window misses the move: the host's turnaround lasts ``time_scale`` times longer."""
        if self.time_scale == 1:
            return ""
        return (
            f" (a rehearsal at speed factor {self.time_scale:g}: the host's turnaround after each move lasts that many "
            "times longer in the rig's seconds; rehearse streamed captures slower, e.g. --speed-factor 5)"
        )

    def _stream(self, lead_s: float, hold_s: float) -> tuple[dict[str, Any], float]:
        """The reports of both mice since the last capture up to ``hold_s`` after now, and now, on the mice's clock
        (``CLOCK_MONOTONIC`` x :attr:`time_scale`). ``lead_s`` is how far back the caller looks (simulated mice generate only that)."""
        t_request = time.monotonic() * self.time_scale
        if self._reader is not None:
            self._closing.wait(hold_s / self.time_scale)  # the reader thread collects meanwhile
        else:
            self._listen(time.monotonic() + hold_s / self.time_scale)
        return self._take_pending(), t_request

    def _listen(self, until_s: float = float("inf")) -> None:
        """Read both mice as their reports come until ``until_s`` (monotonic) or :meth:`close`."""
        with selectors.PollSelector() as selector:
            for mouse in self.mice.values():
                selector.register(mouse.fileno(), selectors.EVENT_READ, mouse)
            while selector.get_map() and not self._closing.is_set() and (remaining := until_s - time.monotonic()) > 0:
                if selector.select(min(remaining, 0.05)):
                    try:
                        with self._lock:
                            self._drain_locked()
                    except LinkError:  # a failed reader raises again at the next capture, which ends the segment
                        if self._reader is None:
                            raise
                        return
                    for key in list(selector.get_map().values()):
                        if key.data.exhausted:  # an ended pipe stays readable: watching it would spin
                            selector.unregister(key.fd)

    def settings(self) -> dict[str, Any]:
        """What the report needs, on hardware and in simulation alike: the counts' resolution (``cpi``, from the
        calibration in force), the noise when it was measured, the calibration and the registration."""
        cpi = np.asarray(self.calibration.effective_cpi)
        out = {
            "instrument": "optical mice (x-y, x-z)",
            "calibration_id": self.calibration.calibration_id,
            "mice": {plane: str(mouse.binding) for plane, mouse in self.mice.items()},
            "registration_mm": [float(v) for v in self.origin],
            "cpi": round(float(cpi.mean()), 3),
            "resolution_mm": round(float(MM_PER_INCH / cpi.min()), 6),
            # the shortfall of a commanded move the liveness check grants the robot (narrower under a kinematic
            # calibration in force)
            "liveness_robot_error_mm": round(self.robot_error_mm, 3),
            # how the x-z mouse is mounted, and so whether the two mice's x motions are cross-checked
            "xz_mount": self.xz_mount,
            "liveness_x_cross_check": self.xz_mount != XZ_GUIDED,
        }
        if self.xz_mount == XZ_GUIDED:
            out["liveness_note"] = _GUIDED_NOTE
        if self.noise_counts is not None:
            out["noise_counts"] = self.noise_counts
        if self.calibration_record is not None:
            # its own key: a camera's settings carry its plane calibration under "calibration"
            out["scale_calibration"] = self.calibration_record
        return out

    def close(self) -> None:
        self._closing.set()
        if self._reader is not None:
            self._reader.join(1.0)
        for mouse in self.mice.values():
            mouse.close()
