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

Drawing is the view's cost (a redraw of both plots is 0.2-0.3 s of the GUI thread on the 2-core bench PC, most of
it matplotlib's constrained layout and text), so the view draws only what can be seen, and not more often than it
can afford: the plots follow the samples within :data:`REDRAW_MS` of their arrival, but a redraw comes no sooner
than :data:`DRAW_GAP_FACTOR` times the last one's duration after it (the plots take at most a sixth of the GUI
thread however fast a simulator stores samples); a hidden view (another tab, a closed window) only collects the
samples and draws them when it is shown.

Start-up: matplotlib and pandas (0.5-0.6 s of imports on the 2-core bench PC) are imported by a background thread
started with the first view, and the figure is built when the first samples arrive (until then the view says that
the plots appear then), so the main window appears without waiting for them and draws no empty figure. The GUI
thread never imports them beside that thread (two threads importing matplotlib at once fail on its circular
imports): samples that arrive first are drawn once the imports have ended, and a caller that needs the figure or
the statistics at once waits for them.
"""

from __future__ import annotations

import importlib
import threading
import time
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QTimer
from PySide6.QtGui import QShowEvent
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from bench.metrology.documents import ISO9283_STABILISATION_BANDS_MM
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
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
                     "matplotlib.backends.backend_qtagg", "bench.metrology.tables")
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


def _plotting_loaded() -> bool:
    """True when the GUI thread can use the plotting modules without waiting."""
    return _preloading is None or not _preloading.is_alive()


def _condition_columns() -> tuple[str, ...]:
    return _plotting_module("bench.metrology.tables").CONDITION_COLUMNS


def _condition_groups(table: "pd.DataFrame"):
    return _plotting_module("bench.metrology.tables").condition_groups(table)


def _canvas_class() -> type:
    """Matplotlib's Qt canvas that draws only while it can be seen (a draw asked for while it is hidden happens
    when it is shown) and records when its last draw ended (``drawn_at_s``, monotonic s) and how long it took
    (``draw_s``). Defined on first use: matplotlib loads off the GUI thread."""
    global _LiveCanvas
    if _LiveCanvas is None:
        FigureCanvasQTAgg = _plotting_module("matplotlib.backends.backend_qtagg").FigureCanvasQTAgg

        class LiveCanvas(FigureCanvasQTAgg):
            drawn_at_s: float | None = None
            draw_s = 0.0
            _draw_when_shown = False

            def draw(self) -> None:
                if not self.isVisible():
                    self._draw_when_shown = True
                    return
                started_s = time.monotonic()
                super().draw()
                self.drawn_at_s = time.monotonic()
                self.draw_s = self.drawn_at_s - started_s

            def showEvent(self, event: QShowEvent) -> None:
                super().showEvent(event)
                if self._draw_when_shown:
                    self._draw_when_shown = False
                    self.draw_idle()

        _LiveCanvas = LiveCanvas
    return _LiveCanvas


_LiveCanvas: type | None = None


class LiveView(QWidget):
    """Two plots fed by :meth:`add_sample` (a dict as emitted by ``CampaignWorker.sample_stored``)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        preload_plotting()
        self._figure: Figure | None = None
        self._canvas: FigureCanvasQTAgg | None = None
        self._axes: tuple[Axes, Axes] | None = None
        self._plotted_s = 0.0  #: how long the last redraw took to make its plots (their draw comes after)
        self._placeholder = QLabel("the plots appear with the first samples of a run")
        self.summary = QLabel("no samples yet")
        self.summary.setObjectName("liveSummary")
        self.summary.setWordWrap(True)
        self._layout = QVBoxLayout(self)
        self._layout.addWidget(self._placeholder, 1)
        self._layout.addWidget(self.summary)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.timeout.connect(self._timed_redraw)
        self.clear()

    # ---- the figure, built on first use ------------------------------------------------------------------------

    def _build_figure(self) -> None:
        if self._canvas is not None:
            return
        Figure = _plotting_module("matplotlib.figure").Figure

        self._figure = Figure(figsize=(7, 4), layout="constrained")
        self._canvas = _canvas_class()(self._figure)
        self._axes = tuple(self._figure.subplots(1, 2, width_ratios=(1, 1.4)))
        self._layout.replaceWidget(self._placeholder, self._canvas)
        self._placeholder.deleteLater()

    @property
    def figure(self) -> "Figure":
        self._build_figure()
        return self._figure

    @property
    def canvas(self) -> "FigureCanvasQTAgg":
        self._build_figure()
        return self._canvas

    @property
    def pose_axes(self) -> "Axes":
        self._build_figure()
        return self._axes[0]

    @property
    def stream_axes(self) -> "Axes":
        self._build_figure()
        return self._axes[1]

    def clear(self, title: str = "", started_s: float | None = None) -> None:
        """Forget every sample (a new run starts); ``started_s`` is the run's start (Unix s), the stream's zero."""
        self.samples: dict[int, dict] = {}  #: by step index
        self.title = title
        self.started_s = started_s
        self._statistics: dict[str, dict[str, float]] | None = None
        self._plots_current = False
        if self._canvas is not None:
            self.redraw()
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
        self._statistics = None
        self._plots_current = False
        if not self._timer.isActive():
            self._timer.start(self._redraw_delay_ms())
        return True

    def _redraw_delay_ms(self) -> int:
        """:data:`REDRAW_MS`, or longer while the pause that the last redraw's duration (its plots and their draw)
        asks for lasts."""
        canvas = self._canvas
        if canvas is None or canvas.drawn_at_s is None:
            return REDRAW_MS
        quiet_until_s = canvas.drawn_at_s + DRAW_GAP_FACTOR * (self._plotted_s + canvas.draw_s)
        return max(REDRAW_MS, round((quiet_until_s - time.monotonic()) * 1000))

    # ---- figures ---------------------------------------------------------------------------------------------

    def pose_table(self) -> "pd.DataFrame":
        """The pose samples as a table with the report's columns (pose, cycle, commanded and attained, conditions)."""
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
        """Per pose and test condition (the report's labels, e.g. ``P1 (velocity_pct=50)``): ``n``, the signed
        barycentre deviations ``APx_mm``, ``APy_mm``, ``APz_mm``, ``AP_mm`` and, with two or more cycles,
        ``RP_mm``."""
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
        """Per stored value: (wall-clock s since the run started, value - commanded or the value)."""
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
        """Per streamed arrival in step order: (pose and cycle, t_s from the move's reported end, d_mm), where d is
        the distance from the series' last point (see the module docstring)."""
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

    def _timed_redraw(self) -> None:
        """The timer's redraw: none while the view is hidden (it redraws when shown), and the first one waits
        (without holding up the window) for the background imports."""
        if not self.isVisible():
            return
        if self._canvas is None and not _plotting_loaded():
            self._timer.start(50)
        else:
            self.redraw()

    def showEvent(self, event: QShowEvent) -> None:
        super().showEvent(event)
        if not self._plots_current and (self._canvas is not None or self.samples):
            self._timed_redraw()

    def redraw(self) -> None:
        """Draw both plots from the samples recorded so far, unless they show them already (a hidden view draws
        them when it is shown)."""
        self._timer.stop()  # this draw shows every sample recorded so far
        if self._plots_current and self._canvas is not None:
            return
        started_s = time.monotonic()
        self._draw_poses()
        curves = self.arrival_curves()
        if curves:
            self._draw_arrivals(curves)
        else:
            self._draw_stream()
        self._plotted_s = time.monotonic() - started_s
        self.canvas.draw_idle()
        self._plots_current = True

    def _draw_arrivals(self, curves: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
        axes = self.stream_axes
        axes.clear()
        axes.set_title(f"arrivals {self.title}: distance from the settled position".strip(), fontsize=9)
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

    def _draw_poses(self) -> None:
        axes = self.pose_axes
        axes.clear()
        axes.set_title("attained - commanded (x-y)", fontsize=9)
        axes.set_xlabel("dx (mm)")
        axes.set_ylabel("dy (mm)")
        axes.axhline(0, color="0.8", lw=0.8)
        axes.axvline(0, color="0.8", lw=0.8)
        statistics = self.pose_statistics()
        table = self.pose_table()
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
        self.summary.setText(self._summary_text(statistics))

    def _draw_stream(self) -> None:
        axes = self.stream_axes
        axes.clear()
        axes.set_title(f"sensor stream {self.title}".strip(), fontsize=9)
        axes.set_xlabel("wall-clock time since the run started (s)")
        from matplotlib.ticker import MaxNLocator

        axes.xaxis.set_major_locator(MaxNLocator(nbins=6))
        stream = self.stream()
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
