"""What differs between two runs a comparison puts side by side: every configuration key, every stored setting
(robot, instrument, station) and the calibrations in force, so a comparison never says "identical" when the
calibration differs."""

from __future__ import annotations

from typing import Any

from bench.reports.signature import PLACEHOLDER_SHOWN, is_placeholder

__all__ = ["NO_DIFFERENCE", "configuration_differences"]

#: What the comparison prints when nothing differs.
NO_DIFFERENCE = "same configuration, settings and calibrations in force"


def _flat(mapping: Any, prefix: str = "") -> dict[str, str]:
    if not isinstance(mapping, dict):
        return {prefix.rstrip("."): str(mapping)}
    out: dict[str, str] = {}
    for key, value in mapping.items():
        out.update(_flat(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}": str(value)})
    return out


def _calibrations(report) -> dict[str, str]:
    records = getattr(report.instrument, "calibrations", ()) or ()
    named = ", ".join(f"{c.name} v{c.version} (id {c.id})" for c in records) or "none"
    return {"calibrations in force": named, "calibration parameters SHA-256": report.calibration_sha256[:16]}


def configuration_differences(first, second) -> tuple[tuple[str, str, str], ...]:
    """Rows (what, A, B) for every configuration key, setting and calibration-in-force item that differs between
    the reports ``first`` and ``second`` (absent on one side: "—"); empty when they agree on all of them."""
    sides = []
    for report in (first, second):
        sides.append(
            {
                **{f"config {k}": v for k, v in _flat(report.run.config).items()},
                # the run's history (aborts, resumes) is compared in its own table, not as a setting
                **{f"setting {k}": v for k, v in _flat(report.run.settings).items() if not k.startswith("history")},
                **_calibrations(report),
            }
        )
    a, b = sides
    keys = [*a, *(k for k in b if k not in a)]

    def shown(value: str) -> str:  # a template's sample text is never printed as a value
        return PLACEHOLDER_SHOWN if value != "—" and is_placeholder(value) else value

    return tuple((k, shown(a.get(k, "—")), shown(b.get(k, "—"))) for k in keys if a.get(k) != b.get(k))
