"""The live view: attained points per pose and test condition with their barycentre and RP circle, and the
sensor stream, as samples are stored.

Statistics are the report's: the samples are grouped by :func:`bench.metrology.tables.condition_groups` (pose x
velocity x load, where they vary) and each group goes to :func:`bench.metrology.iso9283.pose_accuracy` (AP_P, the
distance of the barycentre from the command, ISO 9283 7.2.1) and :func:`~bench.metrology.iso9283.pose_repeatability`
(RP_l = l̄ + 3 S_l, 7.2.2) on the position axes the report uses (x, y, z); at the end of a run every figure equals
the report's. This module only draws: the pose plot shows the x-y plane as deviations from the commanded position
(mm), one colour per group; the stream plot shows every stored value's deviation from its commanded value (or the
value itself) against the wall-clock time since the run started, so a pause shows as a gap of its real length.
A stabilisation run's streamed arrivals (``arrival`` samples with their series) replace the stream plot: each
arrival's distance from its settled position, d(t) = |p(t) - p(t_end)| (ISO 9283 7.4, the settled position is the
series' last point as in :func:`bench.metrology.iso9283_dynamics.position_stabilisation`), against the time from
the move's reported end, with the comparison bands of clause 7.4 (A.4) drawn as lines.
Samples are kept by step index: a sample seen twice (a resumed run's stored samples, then its live signals) counts
once.

Drawing is the view's cost (a redraw of both plots is 0.2-0.3 s of matplotlib on the 2-core bench PC, most of it
constrained layout and text), so it happens on a render thread of the view's own, never on the window's thread: the
window hands a copy of the samples to that thread (:meth:`LiveView.schedule_redraw`) and returns at once; the thread
draws them on a matplotlib figure of its own (Agg) and sends the picture back, which the window shows (a pixmap swap).
The window's thread thus stays free for the emergency stop, dialogs and input while a redraw runs (issue 31: the
e-stop waited 0.66-0.92 s behind redraws). The plots follow the samples within :data:`REDRAW_MS` of their arrival,
but a redraw comes no sooner than :data:`DRAW_GAP_FACTOR` times the last one's duration after it (the render thread
takes at most a sixth of the interpreter however fast a simulator stores samples); a hidden view (another tab, a
closed window) only collects the samples and draws them when it is shown.

Start-up: matplotlib and pandas (0.5-0.6 s of imports on the 2-core bench PC) are imported by a background thread
started with the first view; the render thread waits for those imports (two threads importing matplotlib at once
fail on its circular imports), and the window's thread never imports them for drawing.
"""

from __future__ import annotations

import importlib
import threading
import time
from typing import TYPE_CHECKING

import logging

import numpy as np
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtGui import QImage, QPixmap, QShowEvent
from PySide6.QtWidgets import QLabel, QSizePolicy, QVBoxLayout, QWidget

from bench.metrology.documents import ISO9283_STABILISATION_BANDS_MM
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["DRAW_GAP_FACTOR", "REDRAW_MS", "LiveView"]

#: Shortest interval between two redraws, ms (samples can arrive much faster with a simulator).
REDRAW_MS = 200
#: After a redraw, the next waits at least this many times its duration (the view's share of the GUI thread stays
#: under 1 / (1 + DRAW_GAP_FACTOR) on any PC and under any load).
DRAW_GAP_FACTOR = 5.0
_ATTAINED = ("x_mm", "y_mm", "z_mm")
#: Values that describe the test conditions (a capture's lead and hold times included), not a measurement: never
#: drawn as a stream.
_NOT_MEASURED = ("velocity_pct", "load_kg", "leg", "lead_s", "hold_s")
#: What the figures need, imported off the GUI thread by :func:`preload_plotting`.
_PLOTTING_MODULES = ("pandas", "matplotlib.figure", "matplotlib.patches", "matplotlib.ticker",
                     "matplotlib.backends.backend_agg", "bench.metrology.tables")
#: The pictures' resolution, pixels per inch (their size is the view's, in device pixels).
_DPI = 100
_log = logging.getLogger(__name__)
_preloading: threading.Thread | None = None


def preload_plotting() -> None:
    """Start importing the plotting modules in a daemon thread (once per process); returns at once."""
    global _preloading
    if _preloading is None:
        _preloading = threading.Thread(target=lambda: [importlib.import_module(m) for m in _PLOTTING_MODULES],
                                       name="bench-live-view-imports", daemon=True)
        _preloading.start()


def _plotting_module(name: str):
    """``name``, one of :data:`_PLOTTING_MODULES` (or a module of their packages), once the background imports have
    ended: the GUI thread waits for them rather than import beside them (two threads importing matplotlib's
    circular modules at once fail: "cannot import name ... from partially initialized module")."""
    if _preloading is not None:
        _preloading.join()
    return importlib.import_module(name)


def _condition_columns() -> tuple[str, ...]:
    return _plotting_module("bench.metrology.tables").CONDITION_COLUMNS


def _condition_groups(table: "pd.DataFrame"):
    return _plotting_module("bench.metrology.tables").condition_groups(table)


class _Samples:
    """The samples of one run as the view has them (by step index), and what the plots show of them. The view keeps
    one; each redraw gets a copy (:meth:`snapshot`) that only the render thread reads."""

    def __init__(self, samples: dict[int, dict], title: str, started_s: float | None) -> None:
        self.samples = samples
        self.title = title
        self.started_s = started_s
        self._statistics: dict[str, dict[str, float]] | None = None

    def snapshot(self) -> "_Samples":
        return _Samples(dict(self.samples), self.title, self.started_s)

    def changed(self) -> None:
        self._statistics = None

    def pose_table(self) -> "pd.DataFrame":
        rows = []
        for index, sample in sorted(self.samples.items()):
            values = sample["values"]
            if sample.get("kind") != "pose" or not sample.get("pose") or any(k not in values for k in _ATTAINED):
                continue
            row = {"step_index": index, "pose": str(sample["pose"]), "cycle": sample.get("cycle")}
            row.update({k: v for k, v in values.items() if k in _ATTAINED or k[4:] in _ATTAINED
                        or k in _condition_columns()})
            rows.append(row)
        return _plotting_module("pandas").DataFrame(rows)

    def pose_statistics(self) -> dict[str, dict[str, float]]:
        if self._statistics is not None:
            return self._statistics
        table = self.pose_table()
        out: dict[str, dict[str, float]] = {}
        if not table.empty:
            for label, _pose, _conditions, rows in _condition_groups(table):
                attained = rows[list(_ATTAINED)].to_numpy(dtype=float)
                commanded_columns = [f"cmd_{k}" for k in _ATTAINED]
                commanded = (rows[commanded_columns].to_numpy(dtype=float)[0]
                             if all(c in rows and rows[c].notna().all() for c in commanded_columns)
                             else attained.mean(axis=0))
                accuracy = pose_accuracy(attained, commanded)
                stats = {"n": len(attained), "APx_mm": accuracy.ap_axes_mm[0], "APy_mm": accuracy.ap_axes_mm[1],
                         "APz_mm": accuracy.ap_axes_mm[2], "AP_mm": accuracy.ap_mm,
                         "cmd_x_mm": commanded[0], "cmd_y_mm": commanded[1]}
                if len(attained) >= 2:
                    stats["RP_mm"] = pose_repeatability(attained).rp_mm
                out[label] = stats
        self._statistics = out
        return out

    def stream(self) -> dict[str, tuple[list[float], list[float]]]:
        out: dict[str, tuple[list[float], list[float]]] = {}
        for _, sample in sorted(self.samples.items()):
            values = sample["values"]
            wall_s = sample.get("wall_s")
            if wall_s is not None and self.started_s is not None:
                t_s = float(wall_s) - self.started_s
            else:
                t_s = float(sample.get("t_s") or 0.0)
            for key, value in values.items():
                if key.startswith("cmd_") or key in _NOT_MEASURED:
                    continue
                commanded = values.get(f"cmd_{key}")
                name = f"{key} - cmd" if commanded is not None else key
                times, series = out.setdefault(name, ([], []))
                times.append(t_s)
                series.append(value - commanded if commanded is not None else value)
        return out

    def arrival_curves(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        curves = []
        for _, sample in sorted(self.samples.items()):
            raw = sample.get("raw")
            series = raw.get("series") if sample.get("kind") == "arrival" and isinstance(raw, dict) else None
            if not series or any(len(series.get(k) or ()) < 2 for k in ("t_s", *_ATTAINED)):
                continue
            position = np.column_stack([np.asarray(series[k], dtype=float) for k in _ATTAINED])
            distance = np.linalg.norm(position - position[-1], axis=1)
            curves.append((f"{sample.get('pose')} cycle {sample.get('cycle')}",
                           np.asarray(series["t_s"], dtype=float), distance))
        return curves


class _Job:
    """One redraw: the samples as they were when it was asked for and the picture's size in device pixels."""

    def __init__(self, data: _Samples, width_px: int, height_px: int, number: int) -> None:
        self.data, self.width_px, self.height_px, self.number = data, width_px, height_px, number


class _Rendered(QObject):
    """Carries a finished picture from the render thread to the window's thread (a queued signal)."""

    done = Signal(object, str, float, int)  #: QImage, summary text, seconds the render took, job number


class _Renderer:
    """The render thread: draws the newest job on a matplotlib figure of its own (Agg) and sends the picture.

    The figure, its axes and the Agg canvas belong to this thread only; a newer job replaces one not yet started."""

    def __init__(self, rendered: _Rendered) -> None:
        self._rendered = rendered
        self._jobs = threading.Condition()
        self._job: _Job | None = None
        self.finished_number = 0  #: the last job whose picture was sent
        self._finished = threading.Condition()
        self.figure: Figure | None = None
        self.axes: tuple[Axes, Axes] | None = None
        threading.Thread(target=self._serve, name="bench-live-view-render", daemon=True).start()

    def submit(self, job: _Job) -> None:
        with self._jobs:
            self._job = job
            self._jobs.notify()

    def wait_for(self, number: int, timeout_s: float = 60.0) -> bool:
        with self._finished:
            return self._finished.wait_for(lambda: self.finished_number >= number, timeout_s)

    def _serve(self) -> None:
        while True:
            with self._jobs:
                self._jobs.wait_for(lambda: self._job is not None)
                job, self._job = self._job, None
            try:
                self._render(job)
            except Exception:  # noqa: BLE001 - a failed picture is logged; the window and the run go on
                _log.exception("live view: the redraw failed")
            with self._finished:
                self.finished_number = job.number
                self._finished.notify_all()

    def _render(self, job: _Job) -> None:
        started_s = time.monotonic()
        if self.figure is None:
            Figure = _plotting_module("matplotlib.figure").Figure
            FigureCanvasAgg = _plotting_module("matplotlib.backends.backend_agg").FigureCanvasAgg
            self.figure = Figure(figsize=(7, 4), dpi=_DPI, layout="constrained")
            FigureCanvasAgg(self.figure)
            self.axes = tuple(self.figure.subplots(1, 2, width_ratios=(1, 1.4)))
        self.figure.set_size_inches(max(job.width_px, 200) / _DPI, max(job.height_px, 150) / _DPI)
        pose_axes, stream_axes = self.axes
        summary = LiveView._draw_poses(pose_axes, job.data)
        curves = job.data.arrival_curves()
        if curves:
            LiveView._draw_arrivals(stream_axes, job.data, curves)
        else:
            LiveView._draw_stream(stream_axes, job.data)
        canvas = self.figure.canvas
        canvas.draw()
        width, height = canvas.get_width_height(physical=True)
        image = QImage(bytes(canvas.buffer_rgba()), width, height, QImage.Format.Format_RGBA8888).copy()
        self._rendered.done.emit(image, summary, time.monotonic() - started_s, job.number)


class LiveView(QWidget):
    """Two plots fed by :meth:`add_sample` (a dict as emitted by ``CampaignWorker.sample_stored``)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        preload_plotting()
        self.picture = QLabel("the plots appear with the first samples of a run")
        self.picture.setObjectName("livePlots")
        self.picture.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.picture.setMinimumSize(200, 150)
        self.picture.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)
        self.summary = QLabel("no samples yet")
        self.summary.setObjectName("liveSummary")
        self.summary.setWordWrap(True)
        layout = QVBoxLayout(self)
        layout.addWidget(self.picture, 1)
        layout.addWidget(self.summary)
        self._rendered = _Rendered(self)
        self._rendered.done.connect(self._show_picture)
        self._renderer = _Renderer(self._rendered)
        self._asked = 0  #: the number of the last redraw asked for
        self.renders = 0  #: pictures shown so far
        self.drawn_at_s: float | None = None  #: when the last picture arrived (monotonic s)
        self.render_s = 0.0  #: how long the render thread took for it
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.timeout.connect(self._timed_redraw)
        self.clear()

    # ---- the samples -----------------------------------------------------------------------------------------

    @property
    def samples(self) -> dict[int, dict]:
        return self._data.samples

    @property
    def title(self) -> str:
        return self._data.title

    @property
    def started_s(self) -> float | None:
        return self._data.started_s

    def clear(self, title: str = "", started_s: float | None = None) -> None:
        """Forget every sample (a new run starts); ``started_s`` is the run's start (Unix s), the stream's zero."""
        self._data = _Samples({}, title, started_s)
        self._plots_current = False
        if self.renders:
            self.schedule_redraw()
        else:
            self.summary.setText(self._summary_text({}))

    def load(self, title: str, started_s: float, samples: list[dict]) -> None:
        """Start afresh on a run that began at ``started_s`` (Unix s) and holds ``samples`` already."""
        self.clear(title, started_s)
        for sample in samples:
            self.add_sample(sample)

    def add_sample(self, sample: dict) -> bool:
        """Record one stored sample (once per step index); the plots follow within :data:`REDRAW_MS` (or once the
        pause after the last redraw has passed, or once a hidden view is shown).

        Returns False for a sample already recorded."""
        index = sample.get("step_index")
        key = int(index) if index is not None else -1 - len(self.samples)
        if key in self.samples:
            return False
        self.samples[key] = sample
        self._data.changed()
        self._plots_current = False
        if not self._timer.isActive():
            self._timer.start(self._redraw_delay_ms())
        return True

    def _redraw_delay_ms(self) -> int:
        """:data:`REDRAW_MS`, or longer while the pause that the last redraw's duration asks for lasts."""
        if self.drawn_at_s is None:
            return REDRAW_MS
        quiet_until_s = self.drawn_at_s + DRAW_GAP_FACTOR * self.render_s
        return max(REDRAW_MS, round((quiet_until_s - time.monotonic()) * 1000))

    def pose_table(self) -> "pd.DataFrame":
        """The pose samples as a table with the report's columns (pose, cycle, commanded and attained, conditions)."""
        return self._data.pose_table()

    def pose_statistics(self) -> dict[str, dict[str, float]]:
        """Per pose and test condition (the report's labels, e.g. ``P1 (velocity_pct=50)``): ``n``, the signed
        barycentre deviations ``APx_mm``, ``APy_mm``, ``APz_mm``, ``AP_mm`` and, with two or more cycles,
        ``RP_mm``."""
        return self._data.pose_statistics()

    def stream(self) -> dict[str, tuple[list[float], list[float]]]:
        """Per stored value: (wall-clock s since the run started, value - commanded or the value)."""
        return self._data.stream()

    def arrival_curves(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Per streamed arrival in step order: (pose and cycle, t_s from the move's reported end, d_mm), where d is
        the distance from the series' last point (see the module docstring)."""
        return self._data.arrival_curves()

    # ---- the figure (the render thread's; read it only after :meth:`redraw`) ----------------------------------

    @property
    def figure(self) -> "Figure":
        self.redraw()
        return self._renderer.figure

    @property
    def pose_axes(self) -> "Axes":
        return self.figure.axes[0]

    @property
    def stream_axes(self) -> "Axes":
        return self.figure.axes[1]

    # ---- redraws -----------------------------------------------------------------------------------------------

    def _timed_redraw(self) -> None:
        """The timer's redraw: none while the view is hidden (it redraws when shown)."""
        if self.isVisible():
            self.schedule_redraw()

    def showEvent(self, event: QShowEvent) -> None:
        super().showEvent(event)
        if not self._plots_current and (self.renders or self.samples):
            self._timed_redraw()

    def schedule_redraw(self) -> int:
        """Hand the samples recorded so far to the render thread and return at once (its number); the picture
        replaces the shown one when it is ready."""
        self._timer.stop()  # this redraw shows every sample recorded so far
        self._plots_current = True
        ratio = self.picture.devicePixelRatioF()
        self._asked += 1
        self._renderer.submit(_Job(self._data.snapshot(), round(self.picture.width() * ratio),
                                   round(self.picture.height() * ratio), self._asked))
        return self._asked

    def redraw(self, timeout_s: float = 60.0) -> None:
        """Draw both plots from the samples recorded so far and wait until the render thread has (for a caller
        that reads the figure, and for screenshots; the window itself uses :meth:`schedule_redraw`)."""
        number = self._asked if self._plots_current and self._asked else self.schedule_redraw()
        self._renderer.wait_for(number, timeout_s)

    def _show_picture(self, image: QImage, summary: str, render_s: float, number: int) -> None:
        """The window's thread: show a finished picture (a QPixmap is made here, never on another thread)."""
        self.picture.setPixmap(QPixmap.fromImage(image))
        self.picture.pixmap().setDevicePixelRatio(self.picture.devicePixelRatioF())
        self.summary.setText(summary)
        self.renders += 1
        self.drawn_at_s = time.monotonic()
        self.render_s = render_s

    @staticmethod
    def _draw_arrivals(axes: "Axes", data: _Samples, curves: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
        axes.clear()
        axes.set_title(f"arrivals {data.title}: distance from the settled position".strip(), fontsize=9)
        axes.set_xlabel("time from the move's reported end (s)")
        axes.set_ylabel("d (mm)")
        for index, (label, t_s, distance) in enumerate(curves):
            # the latest ten arrivals carry their label; older ones stay as thin grey context
            recent = index >= len(curves) - 10
            axes.plot(t_s, distance, lw=1.0 if recent else 0.6, color=f"C{index % 10}" if recent else "0.75",
                      label=label if recent else None)
        for band_mm in ISO9283_STABILISATION_BANDS_MM:
            axes.axhline(band_mm, color="k", lw=0.7, ls="--")
            axes.annotate(f"{band_mm:g} mm band", (1.0, band_mm), xycoords=("axes fraction", "data"), ha="right",
                          va="bottom", fontsize=7)
        axes.set_ylim(0, max(2 * max(ISO9283_STABILISATION_BANDS_MM), min(10.0, max(d.max() for *_, d in curves))))
        axes.legend(fontsize=7, loc="upper right")

    @staticmethod
    def _draw_poses(axes: "Axes", data: _Samples) -> str:
        """The pose plot; returns the summary line (the window's thread shows it with the picture)."""
        axes.clear()
        axes.set_title("attained - commanded (x-y)", fontsize=9)
        axes.set_xlabel("dx (mm)")
        axes.set_ylabel("dy (mm)")
        axes.axhline(0, color="0.8", lw=0.8)
        axes.axvline(0, color="0.8", lw=0.8)
        statistics = data.pose_statistics()
        table = data.pose_table()
        if not table.empty:
            for index, (label, _pose, _conditions, rows) in enumerate(_condition_groups(table)):
                colour = f"C{index % 10}"
                stats = statistics[label]
                dx = rows["x_mm"].to_numpy(dtype=float) - stats["cmd_x_mm"]
                dy = rows["y_mm"].to_numpy(dtype=float) - stats["cmd_y_mm"]
                axes.plot(dx, dy, ".", color=colour, ms=4, label=label)
                centre = (stats["APx_mm"], stats["APy_mm"])
                axes.plot(*centre, "+", color=colour, ms=12, mew=2)
                if "RP_mm" in stats:
                    from matplotlib.patches import Circle

                    axes.add_patch(Circle(centre, stats["RP_mm"], fill=False, color=colour, lw=1))
            axes.legend(fontsize=7, loc="upper right")
            axes.set_aspect("equal", adjustable="datalim")
        return LiveView._summary_text(statistics)

    @staticmethod
    def _draw_stream(axes: "Axes", data: _Samples) -> None:
        axes.clear()
        axes.set_title(f"sensor stream {data.title}".strip(), fontsize=9)
        axes.set_xlabel("wall-clock time since the run started (s)")
        from matplotlib.ticker import MaxNLocator

        axes.xaxis.set_major_locator(MaxNLocator(nbins=6))
        stream = data.stream()
        for name, (times, series) in sorted(stream.items()):
            axes.plot(times, series, ".", ms=3, label=name)
        if stream:
            axes.legend(fontsize=7, loc="upper left")

    @staticmethod
    def _summary_text(statistics: dict[str, dict[str, float]]) -> str:
        if not statistics:
            return "no pose samples yet"
        parts = [f"{label}: n={s['n']} AP={s['AP_mm']:.3f} mm" + (f" RP={s['RP_mm']:.3f} mm" if "RP_mm" in s else "")
                 for label, s in statistics.items()]
        return "ISO 9283 (x, y, z; as the report)  |  + barycentre, circle RP in the x-y plot  |  " + "; ".join(parts)
