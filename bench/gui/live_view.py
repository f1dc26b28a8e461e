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
constrained layout and text, and seconds under load), so it happens in a render process (:mod:`bench.gui.live_plots`
draws there), never on the window's thread nor under its interpreter lock: the window hands a copy of the samples to
a render thread (:meth:`LiveView.schedule_redraw`) and returns at once; that thread sends them to the process, waits
for the picture and passes it back, and the window shows it (a pixmap swap). The window's thread thus stays free for
the emergency stop, dialogs and input while a redraw runs (issue 31: the e-stop waited 0.66-0.92 s behind redraws,
and the thread froze 1.1-1.9 s every few seconds during runs). A render thread drawing in this process was not
enough: on a loaded 2-core PC the operating system deschedules a thread that holds the interpreter lock, and the
window's thread waited up to 0.7 s for it. The plots follow the samples within :data:`REDRAW_MS` of their arrival,
but a redraw comes no sooner than :data:`DRAW_GAP_FACTOR` times the last one's duration after it (the render
process takes at most a sixth of a core however fast a simulator stores samples); a hidden view (another tab, a
closed window) only collects the samples and draws them when it is shown.

Start-up: matplotlib and pandas (0.5-0.6 s of imports on the 2-core bench PC) are imported by a background thread
started with the first view; the render thread waits for those imports (two threads importing matplotlib at once
fail on its circular imports), and the window's thread never imports them for drawing.
"""

from __future__ import annotations

import importlib
import logging
import threading
import time
from typing import TYPE_CHECKING

import numpy as np
from PySide6.QtCore import QObject, Qt, QTimer, Signal
from PySide6.QtGui import QImage, QPixmap, QShowEvent
from PySide6.QtWidgets import QLabel, QSizePolicy, QVBoxLayout, QWidget

from bench.gui import live_plots
from bench.gui.live_plots import Picture, Samples, render, summary_text
from bench.gui.offload import WorkerProcess

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
#: What the figures need, imported off the GUI thread by :func:`preload_plotting`.
_PLOTTING_MODULES = (
    "pandas",
    "matplotlib.figure",
    "matplotlib.patches",
    "matplotlib.ticker",
    "matplotlib.backends.backend_agg",
    "bench.metrology.tables",
)
_log = logging.getLogger(__name__)
_preloading: threading.Thread | None = None


def preload_plotting() -> None:
    """Start importing the plotting modules in a daemon thread (once per process); returns at once."""
    global _preloading
    if _preloading is None:
        _preloading = threading.Thread(
            target=lambda: [importlib.import_module(m) for m in _PLOTTING_MODULES],
            name="bench-live-view-imports",
            daemon=True,
        )
        _preloading.start()


def _plotting_module(name: str):
    """``name``, one of :data:`_PLOTTING_MODULES` (or a module of their packages), once the background imports have
    ended: the GUI thread waits for them rather than import beside them (two threads importing matplotlib's
    circular modules at once fail: "cannot import name ... from partially initialized module")."""
    if _preloading is not None:
        _preloading.join()
    return importlib.import_module(name)


live_plots.importer = _plotting_module  # this process's samples and in-process figure wait for the imports


class _Job:
    """One redraw: the samples as they were when it was asked for and the picture's size in device pixels."""

    def __init__(self, data: Samples, width_px: int, height_px: int, number: int) -> None:
        self.data, self.width_px, self.height_px, self.number = data, width_px, height_px, number


class _Rendered(QObject):
    """Carries a finished picture from the render thread to the window's thread (a queued signal)."""

    done = Signal(object, str, float, int)  #: QImage, summary text, seconds the render took, job number


#: The render process (one, started on first use and kept).
_render_process = WorkerProcess("live view's render process")


def _render_picture(job: _Job) -> Picture:
    """Both plots of ``job``, drawn in the render process."""
    return _render_process.call(render, job.data, job.width_px, job.height_px)


class _Renderer:
    """The render thread: hands the newest job to the render process, waits for its picture and sends it to the
    window's thread. A newer job replaces one not yet started."""

    def __init__(self, rendered: _Rendered) -> None:
        self._rendered = rendered
        self._jobs = threading.Condition()
        self._job: _Job | None = None
        self._closed = False
        self.finished_number = 0  #: the last job whose picture was sent
        self._finished = threading.Condition()
        self.thread = threading.Thread(target=self._serve, name="bench-live-view-render", daemon=True)
        self.thread.start()

    def submit(self, job: _Job) -> None:
        with self._jobs:
            self._job = job
            self._jobs.notify()

    def close(self) -> None:
        """End the render thread and its process (the window closes): a job not yet started is dropped. Without it
        the thread could hand a last job to the process pool while the interpreter shuts it down, which logged
        'cannot schedule new futures after interpreter shutdown' at exit."""
        with self._jobs:
            self._closed, self._job = True, None
            self._jobs.notify()
        _render_process.shutdown()

    def wait_for(self, number: int, timeout_s: float = 60.0) -> bool:
        with self._finished:
            return self._finished.wait_for(lambda: self.finished_number >= number, timeout_s)

    def _serve(self) -> None:
        while True:
            with self._jobs:
                self._jobs.wait_for(lambda: self._job is not None or self._closed)
                if self._closed:
                    return
                job, self._job = self._job, None
            try:
                picture = _render_picture(job)
                image = QImage(picture.rgba, picture.width, picture.height, QImage.Format.Format_RGBA8888).copy()
                self._rendered.done.emit(image, picture.summary, picture.render_s, job.number)
            except Exception:  # noqa: BLE001 - a failed picture is logged; the window and the run go on
                _log.exception("live view: the redraw failed")
            with self._finished:
                self.finished_number = job.number
                self._finished.notify_all()


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
        self.render_s = 0.0  #: how long the render process took for it
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
        self._data = Samples({}, title, started_s)
        self._plots_current = False
        if self.renders:
            self.schedule_redraw()
        else:
            self.summary.setText(summary_text({}))

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

    def pose_table(self) -> pd.DataFrame:
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

    # ---- the figure, drawn in this process on demand (for a caller that reads it; the window never does) -------

    @property
    def figure(self) -> Figure:
        """Both plots of the samples recorded so far, drawn here, on the calling thread, as the render process draws
        them (the window shows the render process's pictures)."""
        ratio = self.picture.devicePixelRatioF()
        render(self._data.snapshot(), round(self.picture.width() * ratio), round(self.picture.height() * ratio))
        return live_plots.figure()

    @property
    def pose_axes(self) -> Axes:
        return self.figure.axes[0]

    @property
    def stream_axes(self) -> Axes:
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
        self._renderer.submit(
            _Job(
                self._data.snapshot(),
                round(self.picture.width() * ratio),
                round(self.picture.height() * ratio),
                self._asked,
            )
        )
        return self._asked

    def close_renderer(self) -> None:
        """Stop drawing for good (the window closes): see :meth:`_Renderer.close`."""
        self._timer.stop()
        self._renderer.close()

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
