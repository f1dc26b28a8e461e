"""Metrology core of bench: the figures a test report prints, as pure functions over raw samples.

ISO 9283 pose characteristics (`iso9283`), time-series and path characteristics (`iso9283_dynamics`),
cornering, path velocity and minimum positioning time (`iso9283_path`), actuator
accuracy after Groover and ISO 230-2 (`actuator`) with its per-actuator table path (`actuator_tables`),
optical-mouse calibration (`mouse_calibration`; what scatters a move and the weighted fit: `mouse_variance`), the
project's payload error (`payload`), GUM uncertainty
(`uncertainty`, with its measurement-model Monte Carlo in `uncertainty_model`; RD, RV, AV and the path figures' U
in `uncertainty_figures`), pose statistics of partial readings and detection rates with their Wilson interval
(`partial_pose`), the laser grid's hit rates (`hit_rate`) and the tidy-table interface (`tables`).
Units: mm, degrees, s, kg, N. Results are frozen dataclasses; too few samples raise
``bench.errors.InsufficientData``, malformed input ``bench.errors.ConfigError``; a result is never a silent NaN.
bench/reports imports from here.

The package's names are resolved on first use (PEP 562): importing one submodule, e.g. ``bench.metrology.documents``
for a constant, no longer imports pandas and scipy with every other one (the desktop app's start-up, the CLI's).
``from bench.metrology import pose_accuracy`` and ``bench.metrology.__all__`` work as before.
"""

from __future__ import annotations

import importlib
from typing import Any

#: The submodules whose public names the package re-exports; the pandas-based table paths come last, so that
#: resolving a plain function never imports pandas.
_SUBMODULES = (
    "iso9283",
    "iso9283_dynamics",
    "iso9283_path",
    "actuator",
    "mouse_calibration",
    "mouse_variance",
    "payload",
    "uncertainty",
    "uncertainty_figures",
    "partial_pose",
    "actuator_tables",
    "hit_rate",
)


def __getattr__(name: str) -> Any:
    if name == "__all__":
        names = [n for sub in _SUBMODULES for n in importlib.import_module(f"{__name__}.{sub}").__all__]
        globals()["__all__"] = names
        return names
    if name.startswith("__"):
        raise AttributeError(name)
    for sub in _SUBMODULES:
        module = importlib.import_module(f"{__name__}.{sub}")
        if name in module.__all__:
            value = getattr(module, name)
            globals()[name] = value
            return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__getattr__("__all__")))
