"""The ISO 230-2 bidirectional positioning figure: per axis, the mean deviation of each approach direction with
its ±2s band and the reversal B_i at every target (the figures come from
:func:`bench.metrology.bidirectional_tables.analyze_bidirectional`; nothing is computed here)."""

from __future__ import annotations

import numpy as np

from bench.reports.plots import Plot, panels

__all__ = ["bidirectional_plot"]


def bidirectional_plot(results) -> Plot:
    """One panel per axis (each with its own travel), one legend for the figure."""
    figure, axes_list = panels(len(results), max_columns=2, size=(3.6, 2.8))
    handles = None
    for axes, r in zip(axes_list, results):
        f = r.result
        up, down = np.array(f.mean_deviation_forward_mm), np.array(f.mean_deviation_backward_mm)
        s_up = (r.forward_mm - r.targets_mm).std(axis=0, ddof=1)
        s_down = (r.backward_mm - r.targets_mm).std(axis=0, ddof=1)
        axes.axhline(0.0, color="0.6", lw=0.8)
        for mean, s, colour, name in ((up, s_up, "tab:blue", "↑ approach"), (down, s_down, "tab:orange", "↓ approach")):
            axes.fill_between(
                r.targets_mm, mean - 2 * s, mean + 2 * s, color=colour, alpha=0.2, lw=0, label=f"{name}: x̄ ± 2s"
            )
            axes.plot(r.targets_mm, mean, "o-", color=colour, ms=3, lw=1, label=f"{name}: mean deviation x̄")
        axes.vlines(r.targets_mm, down, up, color="0.2", lw=1.2, label="reversal B_i = x̄↑ − x̄↓")
        axes.set_title(
            f"axis {r.axis}: B = {f.reversal_max_mm:.3g} mm, R = {f.repeatability_mm:.3g} mm, "
            f"A = {f.accuracy_mm:.3g} mm",
            fontsize=8,
        )
        axes.set_xlabel("target position (mm)", fontsize=8)
        axes.set_ylabel("reading − target (mm)", fontsize=8)
        handles = axes.get_legend_handles_labels()
    figure.legend(*handles, loc="outside upper center", ncols=3, fontsize=7, frameon=False)
    return Plot(
        "Bidirectional positioning (ISO 230-2): mean deviation from the target for each approach direction "
        "with its ±2s band, and the reversal B_i between them at every target.",
        figure,
    )
