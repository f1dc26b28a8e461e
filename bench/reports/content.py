"""What a report says about one stored run: identification, device, method, deviations, instruments, results.

:func:`collect` reads the store (never hardware) and calls :mod:`bench.metrology` for every number: AP, RP and
their uncertainties come from :func:`bench.metrology.tables.analyze_poses`, AD/RD from
:func:`~bench.metrology.tables.analyze_distance`, vAP from :func:`~bench.metrology.path_tables.analyze_multidirectional`,
the payload error from :func:`~bench.metrology.payload_shift` and the instrument RP floor from
:func:`~bench.metrology.instrument_rp_floor`. This module computes no statistic of its own, so a report number
equals the analysis API's number on the same tidy table by construction.

Decisions (documented here because the renderers only print them):

- Commanded angles with no measured counterpart (a pkm5 commands alpha/beta; the mice measure x, y, z only) are
  dropped before the analysis and the missing orientation is a ``dimensionality`` deviation.
- The instrument's standard uncertainty per axis is ``settings.instrument.u_mm`` when stated, otherwise it is
  built from the counts sensor's resolution 25.4/cpi mm (a difference of two readings, δ/√6) and its noise
  ``noise_counts`` (counts, 1 σ), combined in quadrature. Without either, the sensor row is unknown and the
  report is refused.
- An instrument that measures a subset of the position axes (the camera spot sensor: x, y on its plane, never z)
  gets AP and RP over the measured axes (:func:`bench.metrology.tables.analyze_poses`: ISO 9283 7.2.1 AP components
  on the measured axes, 7.2.2 RP from l_j over them), labelled so in every table and on the summary page
  (:func:`axes_statement`: "AP and RP in the x-y plane: ... z not measured"); a missing axis is never filled.
  Readings that are partial reading by reading (the laser grid: NaN where a screen did not decode) get the
  partial-pose layout instead (:mod:`bench.reports.positioning`, whatever the protocol).
- The decision uses the rule the caller chooses (:mod:`bench.reports.decision`: simple acceptance, ILAC-G8:09/2019
  4.2.1, or guarded acceptance, ISO 14253-1, with the zones pass / not proven / fail) against criteria passed by
  the caller, labelled "project criterion"; without criteria no pass/fail is stated (ISO 9283 defines no grades).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from typing import Any, ClassVar

import pandas as pd

from bench import __version__
from bench.errors import ConfigError
from bench.metrology import (
    DistanceCharacteristics,
    Measured,
    MultidirectionalVariation,
    OrientationDistanceCharacteristics,
    OrientationVariation,
    PayloadShift,
    distance_accuracy_uncertainty,
    payload_shift,
)
from bench.metrology.formatting import pose_label, report_order
from bench.metrology.orientation import TiltGauge
from bench.metrology.orientation_tables import TiltPoseResult, analyze_tilts, table_spacing_mm, tilt_table
from bench.metrology.path_tables import analyze_multidirectional
from bench.metrology.tables import (
    ANGLE_PAIRS,
    PoseResult,
    analyze_distance,
    analyze_orientation_distance,
    analyze_poses,
    measured_axes,
    pose_table,
)
from bench.metrology.uncertainty import instrument_budget
from bench.metrology.uncertainty_figures import spread_uncertainty
from bench.reports.decision import PASS, decide, rule_text
from bench.reports.deviations import CLAUSES_APPLIED, Deviation, iso_deviations, orientation_deviation
from bench.reports.instrument import (
    _POSITION,
    INSTRUMENT_SOURCE,
    InstrumentInfo,
    _span_from_registration,
    ap_instrument_u_mm,
    calibration_fits,
    calibrations_in_force,
    counts_instrument,
)
from bench.store import CalibrationRecord, RunRecord, Store, series_table, tidy_table

__all__ = [
    "CRITERIA",
    "Decision",
    "DistanceRow",
    "PayloadRow",
    "ReportBase",
    "RunReport",
    "VapRow",
    "analysis_table",
    "axes_statement",
    "check_same_axes",
    "calibrations_in_force",
    "collect",
    "provenance",
    "run_table",
]

#: Acceptance criteria a caller may state, with the result each applies to (all "smaller is better").
CRITERIA = {
    "AP_mm": "AP_P of every pose",
    "RP_mm": "RP_l of every pose",
    "AD_mm": "|AD_p| of every pair and conditions (iso9283_distance runs; short or long alike)",
    "RD_mm": "RD of every pair and conditions (iso9283_distance runs)",
}


@dataclass(frozen=True)
class DistanceRow:
    label: str
    first: str
    second: str
    result: DistanceCharacteristics
    u_ad: Measured  #: AD_p with U: scatter of D_j and the instrument term twice (a difference of two readings)
    u_rd: Measured  #: RD with U (chi pivot, k = 2: :func:`bench.metrology.uncertainty_figures.spread_uncertainty`)
    budget: str  #: the instrument's place in U(AD), as ``bench analyze distance`` words it
    orientation: OrientationDistanceCharacteristics | None = None  #: AD_a/RD_a when the run measured angles
    angle_names: tuple[str, ...] = ()


@dataclass(frozen=True)
class VapRow:
    label: str
    directions: tuple[str, ...]
    result: MultidirectionalVariation
    orientation: OrientationVariation | None = None  #: vAP_a/b/c when the run measured angles
    angle_names: tuple[str, ...] = ()


@dataclass(frozen=True)
class PayloadRow:
    label: str
    result: PayloadShift


@dataclass(frozen=True)
class Decision:
    """Verdicts against stated project criteria under a named decision rule (:mod:`bench.reports.decision`), or
    none."""

    rule: str  #: the sentence naming the rule
    #: (criterion, pose label, value, expanded U, limit, result: "pass" / "not proven" / "fail")
    verdicts: tuple[tuple[str, str, float, float, float, str], ...]

    @property
    def passed(self) -> bool | None:
        """True when every verdict passes, None without verdicts (a "not proven" is not a pass)."""
        return None if not self.verdicts else all(v[-1] == PASS for v in self.verdicts)


@dataclass(frozen=True, kw_only=True)
class ReportBase:
    """What every run report prints whatever its protocol: identification, method, instrument, raw data."""

    run: RunRecord
    report_id: str
    generated_utc: str
    report_software_version: str
    config_sha256: str
    calibration_sha256: str
    title: str
    reference: str = "ISO 9283"  #: the method the deviations table compares the run with
    clauses: tuple[str, ...]
    deviations: tuple[Deviation, ...]
    instrument: InstrumentInfo
    table: pd.DataFrame  #: the analysed tidy table (the raw-data CSV holds the same rows)
    coverage_factor: float
    notes: tuple[str, ...] = field(default=())
    #: verdicts against the stated criteria (``--criterion``) under the chosen rule; None when none were stated
    decision: Decision | None = None
    #: whether the report states a U of an accuracy (AP, AT_p), whose instrument term adds a relative instrument's
    #: registration (its budget table then names both)
    states_accuracy_u: ClassVar[bool] = False


@dataclass(frozen=True, kw_only=True)
class RunReport(ReportBase):
    """Everything one pose run's report prints; renderers format it and add nothing."""

    states_accuracy_u: ClassVar[bool] = True  # U(AP)

    measured_columns: tuple[str, ...]
    poses: tuple[PoseResult, ...]
    distances: tuple[DistanceRow, ...]
    multidirectional: tuple[VapRow, ...]
    payload: tuple[PayloadRow, ...]
    decision: Decision
    #: orientation AP/RP per pose from the calliper tilt readings (``dissertation_pose`` alpha/beta runs)
    orientation: tuple[TiltPoseResult, ...] = ()
    tilt_table: pd.DataFrame | None = None  #: the stored tilt (or depth) readings, as their raw-data CSV
    tilt_gauge: TiltGauge | None = None  #: how the tilts were derived, for the budget


def _sha256_json(value: Any) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def run_table(store: Store, run_id: int, kind: str, *, series: bool = False, samples=None) -> pd.DataFrame:
    """The stored samples of ``kind`` of run ``run_id`` as a report analyses them: the tidy table (``series``: the
    table of their streamed series, from ``samples`` when already read), its source named ``run <id>`` so that
    analysis messages name the run."""
    table = series_table(store, run_id, kind=kind, samples=samples) if series else tidy_table(store, run_id, kind=kind)
    table.attrs["source"] = f"run {run_id}"
    return table


def provenance(run: RunRecord, calibrations: tuple[CalibrationRecord, ...]) -> dict[str, Any]:
    """The identification fields of a report of ``run``: id (run and configuration hash), time, versions, hashes,
    and a note when the run did not complete."""
    config_hash = _sha256_json({"config": run.config, "settings": run.settings})
    notes = []
    if run.status != "completed":
        notes.append(
            f"run status {run.status}"
            + (f" ({run.reason})" if run.reason else "")
            + ": results cover the samples stored before it ended"
        )
    return {
        "run": run,
        "report_id": f"BR-{run.id:05d}-{config_hash[:8]}",
        "generated_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "report_software_version": __version__,
        "config_sha256": config_hash,
        "calibration_sha256": _sha256_json([c.params for c in calibrations]),
        "notes": tuple(notes),
    }


def analysis_table(store: Store, run_id: int) -> pd.DataFrame:
    """The run's tidy pose table as the metrology reads it (commanded angles without measured ones dropped)."""
    table = tidy_table(store, run_id, kind="pose")
    for command, attained in ANGLE_PAIRS:
        if command in table.columns and attained not in table.columns:
            table = table.drop(columns=command)
    table.attrs["source"] = f"run {run_id}"
    return pose_table(table, partial_axes=True)


def check_same_axes(reports, flag: str) -> None:
    """Refuse to set pose runs side by side (``flag``: --compare, --trend) whose instruments measured different
    axes: a planar AP next to a 3-D AP would read as a change of the robot."""
    measured = {r.run.id: r.poses[0].axis_names for r in reports if isinstance(r, RunReport) and r.poses}
    if len(set(measured.values())) > 1:
        raise ConfigError(
            f"{flag}: "
            + "; ".join(f"run {i} measured {', '.join(a)}" for i, a in measured.items())
            + "; expected runs measured on the same axes"
        )


def axes_statement(report: RunReport) -> str | None:
    """What the position figures of a pose run cover when its instrument measured fewer than three axes, e.g.
    "AP and RP in the x-y plane: the camera laser spot (xy plane) measures x, y; z not measured"; None for x, y, z.
    Printed with every table of AP/RP and on the summary page."""
    axes = report.poses[0].axis_names if report.poses else ("x", "y", "z")
    missing = [a for a in "xyz" if a not in axes]
    if not missing:
        return None
    where = {1: f"along {axes[0]}", 2: f"in the {'-'.join(axes)} plane"}[len(axes)]
    name = report.instrument.settings.get("instrument") or report.instrument.settings.get("name") or "instrument"
    return (
        f"AP and RP {where}: the {name} measures {', '.join(axes)}; {', '.join(missing)} not measured (never "
        f"filled), so these are not the 3-D figures of ISO 9283 7.2.1/7.2.2"
    )


def _condition_groups(table: pd.DataFrame):
    varying = [c for c in ("velocity_pct", "load_kg") if c in table.columns and table[c].nunique() > 1]
    if not varying:
        yield "", table
        return
    for key, group in table.groupby(varying, sort=False):
        key = key if isinstance(key, tuple) else (key,)
        group = group.copy()
        group.attrs["source"] = table.attrs.get("source", "table")
        yield ", ".join(f"{n}={v:g}" for n, v in zip(varying, key)), group


def _distances(table: pd.DataFrame, sigma_mm: float | None, k: float) -> tuple[DistanceRow, ...]:
    """AD/RD per set of conditions, with U(AD), U(RD) and the budget as ``bench analyze distance`` gives them."""
    first, second = list(dict.fromkeys(table["pose"]))[:2]
    budget = instrument_budget(sigma_mm, INSTRUMENT_SOURCE)
    rows = []
    for label, group in _condition_groups(table):
        result = analyze_distance(group, first, second)
        u_ad = distance_accuracy_uncertainty(
            result.ad_mm, result.u_ad_mm, result.n, instrument_u_mm=sigma_mm or 0.0, k=k
        )
        u_rd = spread_uncertainty(result.rd_mm, result.n, unit="mm", k=k)
        angles = analyze_orientation_distance(group, first, second)
        names, orientation = angles if angles is not None else ((), None)
        rows.append(
            DistanceRow(label or f"{first}-{second}", first, second, result, u_ad, u_rd, budget, orientation, names)
        )
    return tuple(rows)


def _multidirectional(table: pd.DataFrame) -> tuple[VapRow, ...]:
    return tuple(
        VapRow(r.label, r.directions, r.position, r.orientation, r.angle_names) for r in analyze_multidirectional(table)
    )


def _payload(table: pd.DataFrame) -> tuple[PayloadRow, ...]:
    if "load_kg" not in table.columns or table["load_kg"].nunique() < 2:
        return ()
    others = [c for c in ("velocity_pct",) if c in table.columns and table[c].nunique() > 1]
    rows = []
    for key, group in table.groupby(["pose", *others], sort=False):
        key = key if isinstance(key, tuple) else (key,)
        by_load = {float(m): g[list(measured_axes(g))].to_numpy() for m, g in group.groupby("load_kg")}
        if len(by_load) < 2:
            continue
        label = str(key[0]) + "".join(f" ({n}={v:g})" for n, v in zip(others, key[1:]))
        rows.append(PayloadRow(label, payload_shift(by_load, reference_load_kg=min(by_load))))
    return tuple(rows)


def _judged(name: str, poses: tuple[PoseResult, ...], distances: tuple[DistanceRow, ...]) -> list[tuple[str, Measured]]:
    """The figures ``--criterion name`` judges, each with its U: (where, figure)."""
    if name in ("AD_mm", "RD_mm"):
        if not distances:
            raise ConfigError(f"criteria: {name} judges distance figures, expected an iso9283_distance run")
        # AD_p is signed (short of or past the commanded distance): a limit bounds its size, |AD_p| ± U
        return [(d.label, replace(d.u_ad, value=abs(d.u_ad.value)) if name == "AD_mm" else d.u_rd) for d in distances]
    return [(pose_label(p.pose, p.conditions), p.ap_u if name == "AP_mm" else p.rp_u) for p in poses]


def _decision(
    poses: tuple[PoseResult, ...], criteria: Mapping[str, float], rule: str, distances: tuple[DistanceRow, ...] = ()
) -> Decision:
    unknown = sorted(set(criteria) - set(CRITERIA))
    if unknown:
        raise ConfigError(f"criteria: {', '.join(unknown)} not known, expected some of {', '.join(CRITERIA)}")
    verdicts = []
    for name, limit in criteria.items():
        for where, measured in _judged(name, poses, distances):
            u = measured.expanded_uncertainty
            verdicts.append(
                (name, where, measured.value, u, float(limit), decide(measured.value, u, float(limit), rule))
            )
    text = (
        rule_text(rule)
        if criteria
        else "no acceptance criterion stated: no pass/fail statement (ISO 9283 defines methods, not grades)"
    )
    return Decision(text, tuple(verdicts))


def collect(
    store: Store,
    run_id: int,
    *,
    criteria: Mapping[str, float] | None = None,
    k: float = 2.0,
    resamples: int = 1000,
    allow_unknown: bool = False,
    decision_rule: str = "simple",
) -> RunReport:
    """Gather every fact and number of the report of run ``run_id``.

    Parameters
    ----------
    store : Store
    run_id : int
    criteria : mapping, optional
        Project acceptance criteria, keys from :data:`CRITERIA` (mm).
    decision_rule : {"simple", "guarded"}
        How the verdicts use U (:mod:`bench.reports.decision`).
    k : float
        Coverage factor of every expanded uncertainty.
    resamples : int
        Bootstrap resamples for U(RP) (as ``bench analyze iso9283``).
    allow_unknown : bool
        Produce the report even when the deviations table has unknown rows (they are printed as unknown).

    Raises
    ------
    InsufficientData
        No pose samples, a pose with fewer than 2 cycles, or an incomplete deviations table.
    """
    run = store.run(run_id)
    table = analysis_table(store, run_id)
    measured = tuple(c for c in (*_POSITION, *(a for _, a in ANGLE_PAIRS)) if c in table.columns)
    calibrations = calibrations_in_force(store, run)
    fits = tuple(fit for record in calibrations for fit in calibration_fits(store, record))
    instrument = counts_instrument(
        run, calibrations, sum(c in table.columns for c in _POSITION), fits, span_mm=_span_from_registration(run, table)
    )
    # a relative instrument's frame is known to its registrations' u: AP carries it (bench.store.registrations)
    ap_u_mm = ap_instrument_u_mm(instrument.sigma_mm, run)
    poses = report_order(analyze_poses(table, instrument_u_mm=ap_u_mm or 0.0, k=k, resamples=resamples))
    protocol = run.protocol_name
    if len(measured_axes(table)) < 3 and protocol in ("iso9283_distance", "iso9283_multidirectional"):
        raise ConfigError(
            f"run {run_id}: the instrument measured {', '.join(measured_axes(table))} only; the "
            f"{protocol} figures need x_mm, y_mm and z_mm"
        )
    distances = _distances(table, instrument.sigma_mm, k) if protocol == "iso9283_distance" else ()
    tilts, orientation, gauge = _orientation(store, run_id, k)
    tilt_angles = tuple(f"{f.angle}_deg" for f in orientation[0].figures) if orientation else ()
    cycles = int(table.groupby(["pose", *[c for c in ("velocity_pct", "load_kg") if c in table.columns]]).size().min())
    deviations = iso_deviations(
        protocol=protocol,
        config=_effective_config(run.config, table),
        settings=run.settings,
        measured_columns=(*measured, *(a for a in tilt_angles if a not in measured)),
        cycles_measured=cycles,
        instrument_sigma_mm=instrument.sigma_mm,
        smallest_rp_mm=min(p.repeatability.rp_mm for p in poses),
        rp_floor_mm=instrument.rp_floor_mm,
        allow_unknown=allow_unknown,
    )
    if orientation:
        deviations = [*deviations, orientation_deviation(tilt_angles, gauge.as_dict())]
    return RunReport(
        **provenance(run, calibrations),
        title=run.config.get("title") or _title(protocol),
        clauses=CLAUSES_APPLIED.get(protocol, CLAUSES_APPLIED["iso9283_pose"]),
        deviations=tuple(deviations),
        instrument=instrument,
        measured_columns=measured,
        table=table,
        poses=poses,
        distances=distances,
        multidirectional=_multidirectional(table) if protocol == "iso9283_multidirectional" else (),
        payload=_payload(table),
        decision=_decision(poses, criteria or {}, decision_rule, distances),
        coverage_factor=k,
        orientation=orientation,
        tilt_table=tilts,
        tilt_gauge=gauge,
    )


def _orientation(store: Store, run_id: int, k: float):
    """The run's tilt readings (kind ``tilt``, or the two depths of kind ``tilt_depth`` turned into tilts with their
    stored hole spacing) and their orientation AP/RP per pose, in report order, with the calliper gauge
    (:class:`~bench.metrology.orientation.TiltGauge`); ``(None, (), None)`` without any."""
    kinds = store.sample_kinds(run_id)
    kind = "tilt_depth" if "tilt_depth" in kinds else "tilt" if "tilt" in kinds else None
    if kind is None:
        return None, (), None
    readings = tidy_table(store, run_id, kind=kind)
    readings.attrs["source"] = f"run {run_id}"
    spacing = table_spacing_mm(readings)
    gauge = TiltGauge() if spacing is None else TiltGauge(spacing_mm=spacing)
    table = tilt_table(readings, gauge.spacing_mm)
    table.attrs["source"] = f"run {run_id}"
    return readings, report_order(analyze_tilts(table, gauge, k=k)), gauge  # the raw readings go to the raw data


def _effective_config(config: Mapping[str, Any], table: pd.DataFrame) -> dict[str, Any]:
    """The stored configuration, completed from the stored samples' condition columns where it has no key.

    Protocols other than the ISO ones (e.g. ``delta_positioning``, ``dissertation_pose``) record velocity and load
    per sample rather than as ``velocities_pct``/``loads_kg`` lists; the samples are part of the stored run.
    """
    completed = dict(config)
    for column, key in (("velocity_pct", "velocities_pct"), ("load_kg", "loads_kg")):
        if key not in completed and column in table.columns:
            completed[key] = [float(v) for v in dict.fromkeys(table[column])]
    return completed


def _title(protocol: str) -> str:
    names = {
        "iso9283_pose": "pose accuracy and repeatability",
        "iso9283_distance": "distance accuracy and repeatability",
        "iso9283_multidirectional": "multi-directional pose accuracy variation",
    }
    return f"ISO 9283-style {names.get(protocol, f'pose accuracy and repeatability ({protocol})')}"
