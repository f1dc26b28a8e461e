"""The live view: attained points per pose with their barycentre and RP circle, and the sensor stream, as samples
are stored.

Statistics come from :mod:`bench.metrology.iso9283` (``pose_accuracy`` for the barycentre, ``pose_repeatability``
for RP_l = l̄ + 3 S_l); this module only draws. The pose plot shows the x-y plane as deviations from the commanded
position (mm), one colour per pose label; the stream plot shows every stored value's deviation from its commanded
value (or the value itself) against the run time. Plots are redrawn at most every :data:`REDRAW_MS`.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

from bench.metrology.iso9283 import pose_accuracy, pose_repeatability

__all__ = ["REDRAW_MS", "LiveView"]

#: Shortest interval between two redraws, ms (samples can arrive much faster with a simulator).
REDRAW_MS = 200
_XY = ("x_mm", "y_mm")


class LiveView(QWidget):
    """Two plots fed by :meth:`add_sample` (a dict as emitted by ``CampaignWorker.sample_stored``)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.figure = Figure(figsize=(7, 4), layout="constrained")
        self.canvas = FigureCanvasQTAgg(self.figure)
        self.pose_axes, self.stream_axes = self.figure.subplots(1, 2, width_ratios=(1, 1.4))
        self.summary = QLabel("no samples yet")
        self.summary.setObjectName("liveSummary")
        self.summary.setWordWrap(True)
        layout = QVBoxLayout(self)
        layout.addWidget(self.canvas, 1)
        layout.addWidget(self.summary)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.timeout.connect(self.redraw)
        self.clear()

    def clear(self, title: str = "", time_base: str = "s") -> None:
        """Forget every sample (a new run starts); ``time_base`` is what the run's ``t_s`` counts (its settings'
        ``time_base``, e.g. ``simulated s (wall x speed factor 10000)``)."""
        self.points: dict[str, list[np.ndarray]] = defaultdict(list)
        self.commanded: dict[str, np.ndarray] = {}
        self.stream: dict[str, tuple[list[float], list[float]]] = defaultdict(lambda: ([], []))
        self.title = title
        self.time_base = time_base
        self.redraw()

    def add_sample(self, sample: dict) -> None:
        """Record one stored sample; the plots follow within :data:`REDRAW_MS`."""
        values = sample["values"]
        t_s = float(sample.get("t_s") or 0.0)
        for key, value in values.items():
            if key.startswith("cmd_") or key in ("velocity_pct", "load_kg", "leg"):
                continue
            commanded = values.get(f"cmd_{key}")
            name = f"{key} - cmd" if commanded is not None else key
            times, series = self.stream[name]
            times.append(t_s)
            series.append(value - commanded if commanded is not None else value)
        if sample.get("kind") == "pose" and sample.get("pose") and all(k in values for k in _XY):
            label = str(sample["pose"])
            self.points[label].append(np.array([values[k] for k in _XY], dtype=float))
            if all(f"cmd_{k}" in values for k in _XY):
                self.commanded[label] = np.array([values[f"cmd_{k}"] for k in _XY], dtype=float)
        if not self._timer.isActive():
            self._timer.start(REDRAW_MS)

    def pose_statistics(self) -> dict[str, dict[str, float]]:
        """Per pose label: ``n``, barycentre deviation (mm) and, with two or more points, ``RP_mm`` (x-y plane)."""
        out = {}
        for label, points in self.points.items():
            attained = np.vstack(points)
            commanded = self.commanded.get(label, attained.mean(axis=0))
            accuracy = pose_accuracy(attained, commanded)
            stats = {"n": len(points), "APx_mm": accuracy.ap_axes_mm[0], "APy_mm": accuracy.ap_axes_mm[1],
                     "AP_mm": accuracy.ap_mm}
            if len(points) >= 2:
                stats["RP_mm"] = pose_repeatability(attained).rp_mm
            out[label] = stats
        return out

    def redraw(self) -> None:
        """Draw both plots from the samples recorded so far."""
        self._draw_poses()
        self._draw_stream()
        self.canvas.draw_idle()

    def _draw_poses(self) -> None:
        axes = self.pose_axes
        axes.clear()
        axes.set_title("attained - commanded (x-y)", fontsize=9)
        axes.set_xlabel("dx (mm)")
        axes.set_ylabel("dy (mm)")
        axes.axhline(0, color="0.8", lw=0.8)
        axes.axvline(0, color="0.8", lw=0.8)
        statistics = self.pose_statistics()
        for index, (label, points) in enumerate(sorted(self.points.items())):
            colour = f"C{index % 10}"
            origin = self.commanded.get(label, np.zeros(2))
            deviation = np.vstack(points) - origin
            axes.plot(deviation[:, 0], deviation[:, 1], ".", color=colour, ms=4, label=label)
            stats = statistics[label]
            centre = (stats["APx_mm"], stats["APy_mm"])
            axes.plot(*centre, "+", color=colour, ms=12, mew=2)
            if "RP_mm" in stats:
                axes.add_patch(Circle(centre, stats["RP_mm"], fill=False, color=colour, lw=1))
        if self.points:
            axes.legend(fontsize=7, loc="upper right")
            axes.set_aspect("equal", adjustable="datalim")
        self.summary.setText(self._summary_text(statistics))

    def _draw_stream(self) -> None:
        axes = self.stream_axes
        axes.clear()
        axes.set_title(f"sensor stream {self.title}".strip(), fontsize=9)
        axes.set_xlabel(f"run time ({self.time_base})")
        for name, (times, series) in sorted(self.stream.items()):
            axes.plot(times, series, ".-", ms=3, lw=0.6, label=name)
        if self.stream:
            axes.legend(fontsize=7, loc="upper left")

    @staticmethod
    def _summary_text(statistics: dict[str, dict[str, float]]) -> str:
        if not statistics:
            return "no pose samples yet"
        parts = [f"{label}: n={s['n']} AP={s['AP_mm']:.3f} mm" + (f" RP={s['RP_mm']:.3f} mm" if "RP_mm" in s else "")
                 for label, s in sorted(statistics.items())]
        return "x-y plane, + barycentre, circle RP  |  " + "; ".join(parts)
