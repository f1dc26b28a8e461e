"""The instrument of a report: its uncertainty budget per reading or per axis, its RP floor and calibrations.

Manual length readings (calliper, depth gauge: :func:`reading_instrument`) get the stated u, or the readings' last
decimal (δ/√6 for a difference of two readings, δ/√12 for one) with the stated MPE (rectangular); a counts
instrument (the mice: :func:`counts_instrument`) the stated u, or one count 25.4/cpi (δ/√6) and its count noise,
plus the scale of the mouse calibration in force at the run's largest displacement from the registration.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.metrology import (
    AxisCalibration,
    combine,
    fit_axis_scale,
    instrument_rp_floor,
    resolution_uncertainty,
)
from bench.metrology.formatting import reading_step_mm
from bench.metrology.mouse_calibration import MM_PER_INCH
from bench.store import CalibrationRecord, RunRecord, Store
from bench.store.registrations import registration_u_mm, registrations

if TYPE_CHECKING:  # pandas only in annotations: bench analyze path-run reads this module without loading pandas
    import pandas as pd

#: Where a report's instrument term comes from, as its U budget names it (``bench analyze``: --instrument-u-mm).
INSTRUMENT_SOURCE = "the run's instrument settings"


def calibrations_in_force(store: Store, run: RunRecord) -> tuple[CalibrationRecord, ...]:
    """The stored calibration records the run was taken with, in the order the run lists them."""
    return tuple(store.calibration_by_id(i) for i in run.calibration_ids)


_POSITION = ("x_mm", "y_mm", "z_mm")

__all__ = [
    "CalibrationFit",
    "InstrumentInfo",
    "NOMINAL_CPI_SCALE_ERROR",
    "STATED",
    "ap_instrument_u_mm",
    "calibration_fits",
    "calibration_scale_relative_u",
    "calibration_scale_u",
    "counts_instrument",
    "reading_instrument",
    "registration_span_mm",
    "uncertainty_stated",
]


@dataclass(frozen=True)
class CalibrationFit:
    """A calibration in force refitted from the raw samples of the run that produced it (for its plot)."""

    record: CalibrationRecord
    axis: str
    reference_mm: tuple[float, ...]  #: commanded step lengths
    counts: tuple[float, ...]  #: counts between the two ends of each step
    fit: AxisCalibration


@dataclass(frozen=True)
class InstrumentInfo:
    """The instrument as stored with the run, its uncertainty budget and calibrations."""

    settings: dict[str, Any]
    sigma_mm: float | None  #: standard uncertainty per axis, mm
    budget: tuple[tuple[str, float, str], ...]  #: (component, standard uncertainty mm, source)
    dims: int  #: measured position axes
    rp_floor_mm: float | None  #: expected RP of a perfect robot seen through this instrument
    calibrations: tuple[CalibrationRecord, ...]
    fits: tuple[CalibrationFit, ...] = ()
    #: the readings' last recorded decimal (manual readings), mm: no printed figure is finer (formatting)
    resolution_mm: float | None = None


def reading_instrument(
    run: RunRecord,
    calibrations: tuple[CalibrationRecord, ...],
    readings,
    *,
    difference: bool,
    reader: str | None = None,
) -> InstrumentInfo:
    """The instrument of manual length readings (calliper, depth gauge) and its uncertainty per reading.

    When the stored instrument settings describe the reading instrument (``reader`` None): ``settings.instrument
    .u_mm`` when stated; otherwise the reading resolution (the readings' last decimal, :func:`reading_step_mm`),
    δ/√6 for a ``difference`` of two readings (a gauge zeroed, then read) or δ/√12 for one, combined with
    ``settings.instrument.mpe_mm``/√3 (rectangular) when the maximum permissible error is stated. When they
    describe the rig's own sensors instead (a payload ladder's mice; the calliper is the operator's), ``reader``
    names the reading instrument, the stored settings are shown under ``rig`` and only the resolution is used.
    """
    stored = dict(run.settings.get("instrument") or {})
    own = stored if reader is None else {}
    budget: list[tuple[str, float, str]] = []
    step = reading_step_mm(readings)
    if "u_mm" in own:
        budget.append(("instrument, per reading", float(own["u_mm"]), f"{STATED} standard uncertainty"))
    else:
        if step is not None:
            budget.append(
                (
                    f"resolution ({'difference of the zero and the reading' if difference else 'one reading'})",
                    resolution_uncertainty(step, difference=difference),
                    f"last recorded decimal of the readings, {step:g} mm; δ/{'√6' if difference else '√12'}",
                )
            )
        if "mpe_mm" in own:
            budget.append(
                (
                    "maximum permissible error",
                    float(own["mpe_mm"]) / math.sqrt(3.0),
                    f"{STATED} maximum permissible error, {own['mpe_mm']} mm, rectangular",
                )
            )
    sigma = combine(*(u for _, u, _ in budget)) if budget else None
    settings = stored if reader is None else {"readings": reader, **({"rig": stored} if stored else {})}
    return InstrumentInfo(settings, sigma, tuple(budget), 1, None, calibrations, resolution_mm=step)


#: How a budget line whose figure the stored instrument settings state (u or MPE) names its source.
STATED = "the instrument's stated"


def uncertainty_stated(info: InstrumentInfo) -> bool:
    """Whether the instrument's uncertainty comes from stored settings (u or MPE), not from the resolution alone."""
    return any(source.startswith(STATED) for _, _, source in info.budget)


def calibration_fits(store: Store, record: CalibrationRecord) -> tuple[CalibrationFit, ...]:
    """Per-axis step data of a mouse calibration's source run (``mouse`` samples labelled ``<axis><mm>/start|end``),
    refitted with :func:`bench.metrology.fit_axis_scale`; empty when the calibration has no such source run."""
    if record.source_run_id is None:
        return ()
    samples = store.samples(record.source_run_id, kind="mouse")
    ends = {(s.pose, s.cycle): s.values for s in samples if s.pose and "/" in s.pose}
    fits = []
    for axis in ("x", "y"):
        steps = [
            (values, ends[(pose[:-3] + "start", cycle)])
            for (pose, cycle), values in ends.items()
            if pose.startswith(axis) and pose.endswith("/end") and (pose[:-3] + "start", cycle) in ends
        ]
        column = f"mouse_xy_{axis}_counts"
        steps = [(end, start) for end, start in steps if column in end and column in start]
        if len(steps) < 3:
            continue
        reference = tuple(end[f"cmd_{axis}_mm"] - start[f"cmd_{axis}_mm"] for end, start in steps)
        counts = tuple(end[column] - start[column] for end, start in steps)
        fits.append(CalibrationFit(record, axis, reference, counts, fit_axis_scale(reference, counts)))
    return tuple(fits)


#: Half-width of the scale error of a mouse read at its nominal cpi, as a fraction: sensors.md §1.3 (1-4 % before
#: calibration), taken as a rectangular distribution.
NOMINAL_CPI_SCALE_ERROR = 0.04


def calibration_scale_u(calibration: Mapping[str, Any], span_mm: float) -> tuple[float, str]:
    """Standard uncertainty (mm) a mouse calibration's scale adds to a reading ``span_mm`` from the registration.

    .. math:: u = d \\cdot \\max_i u(s_i)/s_i

    with u(s_i) the stored uncertainty of each axis's scale; a nominal calibration has none measured, so its
    scale error is taken as rectangular of half-width :data:`NOMINAL_CPI_SCALE_ERROR` (u = 0.04/√3 of the span).
    """
    relative, why = calibration_scale_relative_u(calibration)
    return span_mm * relative, f"{why} x {span_mm:.1f} mm from the registration"


def calibration_scale_relative_u(calibration: Mapping[str, Any]) -> tuple[float, str]:
    """Relative standard uncertainty of a mouse calibration's scale, max_i u(s_i)/s_i (the nominal cpi's:
    rectangular of half-width :data:`NOMINAL_CPI_SCALE_ERROR`), and where it comes from: a length's and a speed's
    (AV) relative u alike."""
    if calibration.get("nominal"):
        relative = NOMINAL_CPI_SCALE_ERROR / np.sqrt(3.0)
        why = f"nominal cpi (mouse-v{calibration.get('version')}): ±{100 * NOMINAL_CPI_SCALE_ERROR:g} % rectangular"
    else:
        relative = max(
            float(calibration.get(f"u_{a}_mm_per_count", 0.0)) / float(calibration[f"{a}_mm_per_count"])
            for a in ("x", "y")
        )
        why = f"mouse-v{calibration.get('version')}: u(scale) {100 * relative:.3g} %"
    return float(relative), why


def counts_instrument(
    run: RunRecord,
    calibrations: tuple[CalibrationRecord, ...],
    dims: int,
    fits: tuple[CalibrationFit, ...] = (),
    *,
    span_mm: float | None = None,
) -> InstrumentInfo:
    """A counts instrument (the mice) as stored with the run: u per axis from ``settings.instrument.u_mm``, else
    from its resolution 25.4/cpi (δ/√6) and ``noise_counts``, plus the scale of the calibration in force at the
    largest displacement from the registration ``span_mm`` (:func:`calibration_scale_u`) where the run recorded
    it; the RP floor in ``dims`` dimensions (none for 0)."""
    settings = dict(run.settings.get("instrument") or {})
    budget: list[tuple[str, float, str]] = []
    if "u_mm" in settings:
        budget.append(("instrument, per axis", float(settings["u_mm"]), f"{STATED} standard uncertainty"))
    elif "cpi" in settings:
        step_mm = MM_PER_INCH / float(settings["cpi"])
        budget.append(
            (
                "resolution (difference of two readings)",
                resolution_uncertainty(step_mm, difference=True),
                f"one count at {float(settings['cpi']):g} counts per inch, {step_mm:.4g} mm, δ/√6",
            )
        )
        if "noise_counts" in settings:
            budget.append(
                (
                    "count noise",
                    float(settings["noise_counts"]) * step_mm,
                    f"{settings['noise_counts']} counts x {step_mm:.4g} mm",
                )
            )
    if isinstance(settings.get("scale_calibration"), Mapping) and span_mm is not None:
        budget.append(("calibration scale", *calibration_scale_u(settings["scale_calibration"], span_mm)))
    sigma = combine(*(u for _, u, _ in budget)) if budget else None
    floor = instrument_rp_floor(sigma, dims=dims) if sigma is not None and dims else None
    return InstrumentInfo(settings, sigma, tuple(budget), dims, floor, calibrations, fits)


def _span_from_registration(run: RunRecord, table: pd.DataFrame) -> float | None:
    """The largest per-axis distance (mm) of the run's measured positions from the instrument's registration."""
    columns = [c for c in _POSITION if c in table.columns]
    if not columns:
        return None
    # each column in its axis's place (an absent axis NaN), so it is compared with its own registration coordinate
    positions = np.full((len(table), _POSITION.index(columns[-1]) + 1), np.nan)
    for column in columns:
        positions[:, _POSITION.index(column)] = table[column].to_numpy(float)
    return registration_span_mm(run, positions)


def registration_span_mm(run: RunRecord, positions_mm: np.ndarray) -> float | None:
    """The largest per-axis distance (mm) of ``positions_mm`` (k, d; x, y[, z]) from the instrument's registration
    (None: the run recorded none, or no position): the lever arm of a calibration-scale error."""
    registration = (run.settings.get("instrument") or {}).get("registration_mm")
    positions = np.asarray(positions_mm, float)
    if registration is None or positions.size == 0:
        return None
    d = positions.shape[1]
    return float(np.nanmax(np.abs(positions - np.asarray(registration, float)[:d])))


def ap_instrument_u_mm(sigma_mm: float | None, run: RunRecord) -> float | None:
    """The instrument's term of the AP budget per axis, mm: the reading's u and, for a relative instrument, its
    registrations' u measured in the run (bench.rigs.registration); None when neither is declared."""
    registered = registration_u_mm(registrations(run.settings))
    if sigma_mm is None and not registrations(run.settings):
        return None
    return combine(sigma_mm or 0.0, registered)
