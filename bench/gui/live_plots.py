"""The live view's plots, without Qt: the samples of a run as the view holds them (:class:`Samples`), the two plots
drawn from them, and :func:`render`, which draws both on this process's figure (Agg) and returns the picture's
pixels. The window calls :func:`render` in a render process of its own (:mod:`bench.gui.live_view`), so a redraw
holds neither the window's thread nor its interpreter lock.

The statistics are the report's: :func:`bench.metrology.tables.condition_groups`,
:func:`bench.metrology.iso9283.pose_accuracy` and :func:`~bench.metrology.iso9283.pose_repeatability` (see
:mod:`bench.gui.live_view`).
"""

from __future__ import annotations

import importlib
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from bench.metrology.documents import ISO9283_STABILISATION_BANDS_MM
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["Picture", "Samples", "draw_arrivals", "draw_poses", "draw_stream", "figure", "render", "summary_text"]

_ATTAINED = ("x_mm", "y_mm", "z_mm")
#: Values that describe the test conditions (a capture's lead and hold times included), not a measurement: never
#: drawn as a stream.
_NOT_MEASURED = ("velocity_pct", "load_kg", "leg", "lead_s", "hold_s")
#: The pictures' resolution, pixels per inch (their size is the view's, in device pixels).
DPI = 100
#: How this module imports pandas and the metrology tables: the window's process replaces it with one that waits for
#: its background imports (two threads importing matplotlib at once fail on its circular imports).
importer = importlib.import_module


def _condition_columns() -> tuple[str, ...]:
    return importer("bench.metrology.tables").CONDITION_COLUMNS


def _condition_groups(table: pd.DataFrame):
    return importer("bench.metrology.tables").condition_groups(table)


class Samples:
    """The samples of one run as the view has them (by step index), and what the plots show of them. The view keeps
    one; each redraw gets a copy (:meth:`snapshot`) that only the render thread reads."""

    def __init__(self, samples: dict[int, dict], title: str, started_s: float | None) -> None:
        self.samples = samples
        self.title = title
        self.started_s = started_s
        self._statistics: dict[str, dict[str, float]] | None = None

    def snapshot(self) -> Samples:
        return Samples(dict(self.samples), self.title, self.started_s)

    def changed(self) -> None:
        self._statistics = None

    def pose_table(self) -> pd.DataFrame:
        rows = []
        for index, sample in sorted(self.samples.items()):
            values = sample["values"]
            if sample.get("kind") != "pose" or not sample.get("pose") or any(k not in values for k in _ATTAINED):
                continue
            row = {"step_index": index, "pose": str(sample["pose"]), "cycle": sample.get("cycle")}
            row.update(
                {k: v for k, v in values.items() if k in _ATTAINED or k[4:] in _ATTAINED or k in _condition_columns()}
            )
            rows.append(row)
        return importer("pandas").DataFrame(rows)

    def pose_statistics(self) -> dict[str, dict[str, float]]:
        if self._statistics is not None:
            return self._statistics
        table = self.pose_table()
        out: dict[str, dict[str, float]] = {}
        if not table.empty:
            for label, _pose, _conditions, rows in _condition_groups(table):
                attained = rows[list(_ATTAINED)].to_numpy(dtype=float)
                commanded_columns = [f"cmd_{k}" for k in _ATTAINED]
                commanded = (
                    rows[commanded_columns].to_numpy(dtype=float)[0]
                    if all(c in rows and rows[c].notna().all() for c in commanded_columns)
                    else attained.mean(axis=0)
                )
                accuracy = pose_accuracy(attained, commanded)
                stats = {
                    "n": len(attained),
                    "APx_mm": accuracy.ap_axes_mm[0],
                    "APy_mm": accuracy.ap_axes_mm[1],
                    "APz_mm": accuracy.ap_axes_mm[2],
                    "AP_mm": accuracy.ap_mm,
                    "cmd_x_mm": commanded[0],
                    "cmd_y_mm": commanded[1],
                }
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
            curves.append(
                (f"{sample.get('pose')} cycle {sample.get('cycle')}", np.asarray(series["t_s"], dtype=float), distance)
            )
        return curves


def draw_arrivals(axes: Axes, data: Samples, curves: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    axes.clear()
    axes.set_title(f"arrivals {data.title}: distance from the settled position".strip(), fontsize=9)
    axes.set_xlabel("time from the move's reported end (s)")
    axes.set_ylabel("d (mm)")
    for index, (label, t_s, distance) in enumerate(curves):
        # the latest ten arrivals carry their label; older ones stay as thin grey context
        recent = index >= len(curves) - 10
        axes.plot(
            t_s,
            distance,
            lw=1.0 if recent else 0.6,
            color=f"C{index % 10}" if recent else "0.75",
            label=label if recent else None,
        )
    for band_mm in ISO9283_STABILISATION_BANDS_MM:
        axes.axhline(band_mm, color="k", lw=0.7, ls="--")
        axes.annotate(
            f"{band_mm:g} mm band",
            (1.0, band_mm),
            xycoords=("axes fraction", "data"),
            ha="right",
            va="bottom",
            fontsize=7,
        )
    axes.set_ylim(0, max(2 * max(ISO9283_STABILISATION_BANDS_MM), min(10.0, max(d.max() for *_, d in curves))))
    axes.legend(fontsize=7, loc="upper right")


def draw_poses(axes: Axes, data: Samples) -> str:
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
    return summary_text(statistics)


def draw_stream(axes: Axes, data: Samples) -> None:
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


def summary_text(statistics: dict[str, dict[str, float]]) -> str:
    if not statistics:
        return "no pose samples yet"
    from bench.metrology.formatting import format_length  # the one rounding rule: no U live, so to 1 µm

    parts = [
        f"{label}: n={s['n']} AP={format_length(s['AP_mm'])} mm"
        + (f" RP={format_length(s['RP_mm'])} mm" if "RP_mm" in s else "")
        for label, s in statistics.items()
    ]
    return "ISO 9283 (x, y, z; as the report)  |  + barycentre, circle RP in the x-y plot  |  " + "; ".join(parts)


@dataclass(frozen=True)
class Picture:
    """Both plots as RGBA pixels (``width`` x ``height``), the summary line, and the seconds the render took."""

    rgba: bytes
    width: int
    height: int
    summary: str
    render_s: float


_figure: Figure | None = None


def figure() -> Figure:
    """This process's figure (built on first use): the pose plot and the stream plot."""
    global _figure
    if _figure is None:
        Figure = importer("matplotlib.figure").Figure
        FigureCanvasAgg = importer("matplotlib.backends.backend_agg").FigureCanvasAgg
        _figure = Figure(figsize=(7, 4), dpi=DPI, layout="constrained")
        FigureCanvasAgg(_figure)
        _figure.subplots(1, 2, width_ratios=(1, 1.4))
    return _figure


def render(data: Samples, width_px: int, height_px: int) -> Picture:
    """Draw both plots of ``data`` on this process's figure at ``width_px`` x ``height_px``; the picture."""
    started_s = time.monotonic()
    drawn = figure()
    drawn.set_size_inches(max(width_px, 200) / DPI, max(height_px, 150) / DPI)
    pose_axes, stream_axes = drawn.axes
    summary = draw_poses(pose_axes, data)
    curves = data.arrival_curves()
    if curves:
        draw_arrivals(stream_axes, data, curves)
    else:
        draw_stream(stream_axes, data)
    drawn.canvas.draw()
    width, height = drawn.canvas.get_width_height(physical=True)
    return Picture(bytes(drawn.canvas.buffer_rgba()), width, height, summary, time.monotonic() - started_s)
