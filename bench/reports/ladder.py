"""The report of a ``payload_ladder`` run: leg actuation error against load (000 §8.7, Table A.14) and the project's
pose-level payload error and compliance (iso9283.md §12).

Figures, all from :mod:`bench.metrology.payload`:

- e_i(m) = L_meas − L_cmd per leg and load (signed, the mean over the lifts at that load), summarised with
  :func:`~bench.metrology.leg_error_summary` as ``bench analyze payload`` does on the raw-data CSV, and on |e| as
  000 Table 8-5 does; the slope of each leg's e against the added weight with
  :func:`~bench.metrology.payload_compliance`.
- PE(m) = x̄(m) − x̄(m₀) with :func:`~bench.metrology.payload_shift`, where x̄(m) is the barycentre of the poses
  that the forward kinematics (``motion.pkm5``, translation mode: the lift is a pure translation) finds for the six
  calliper lengths of each lift. The run stores no end-effector reading, so this is the only pose information it
  holds; a lift whose six lengths no pose fits within :data:`FK_RESIDUAL_LIMIT_MM` (RMS) is left out and named.
- The payload compliance estimate k: the slope of PE_z against (m − m₀)·g over every lift.

m₀ is the lowest load of the ladder; g the standard gravity of :mod:`bench.metrology.payload`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from bench.errors import InsufficientData
from bench.metrology import (
    STANDARD_GRAVITY_M_S2,
    LegErrorSummary,
    PayloadCompliance,
    PayloadShift,
    leg_error_summary,
    payload_compliance,
    payload_shift,
)
from bench.metrology.formatting import format_measured
from bench.metrology.tables import numeric_columns
from bench.reports.content import ReportBase, calibrations_in_force, provenance, run_table
from bench.reports.criteria import Characteristic, decision_section
from bench.reports.deviations_bench import ladder_deviations
from bench.reports.document import (
    Block,
    Document,
    Paragraph,
    RawData,
    Table,
    assemble,
    conditions_section,
    reading_formatter,
)
from bench.reports.instrument import reading_instrument
from bench.reports.plots import Plot, payload_caption, payload_shift_figure
from bench.store import Store

__all__ = [
    "FK_RESIDUAL_LIMIT_MM",
    "LadderReport",
    "LiftPose",
    "collect_ladder",
    "leg_error_table",
    "ladder_document",
    "ladder_plots",
    "lift_poses",
]

#: What reads the leg lengths: the operator's calliper, entered at the prompts (the rig's stored instrument is not it).
READER = "digital calliper, leg lengths entered by the operator (000 §8.7)"
#: Largest RMS leg residual of a lift's forward kinematics still taken as a pose (a reading slip gives more).
FK_RESIDUAL_LIMIT_MM = 0.5
SCOPE = (
    "Tested following the payload ladder of the dissertation (000 §8.7) and the project's payload-error "
    "definitions (iso9283.md §12), with the deviations listed in the deviations table. Payload error and payload "
    "compliance are project definitions, not ISO 9283 terms; k is not ISO 9283 static compliance (clause 10)."
)
NO_CRITERION = "no acceptance criterion stated: no pass/fail statement (000 §8.7 and iso9283.md §12 set none)"


@dataclass(frozen=True)
class LiftPose:
    """The pose the forward kinematics finds for the six calliper lengths of one lift."""

    load_kg: float
    repeat: int
    lengths_mm: tuple[float, ...]  #: legs 1-6
    position_mm: tuple[float, float, float]
    residual_mm: float  #: RMS of IK(pose) − L over the six legs
    used: bool  #: residual within FK_RESIDUAL_LIMIT_MM


@dataclass(frozen=True, kw_only=True)
class LadderReport(ReportBase):
    """Everything the report of a payload_ladder run prints."""

    leg_errors: pd.DataFrame  #: mean signed e_i(m), index load_kg (ladder order), one column per leg
    lifts_per_load: tuple[int, ...]
    summary: LegErrorSummary  #: on the signed errors (as ``bench analyze payload``)
    summary_abs: LegErrorSummary  #: on |e| (000 Table 8-5)
    leg_slopes: tuple[PayloadCompliance | None, ...]  #: e_i against added weight, mm/N
    commanded_mm: tuple[float, float, float]  #: the lifted pose
    lifts: tuple[LiftPose, ...]
    shift: PayloadShift | None
    compliance: PayloadCompliance | None
    g_m_s2: float


def leg_error_table(table: pd.DataFrame) -> pd.DataFrame:
    """Mean signed error per load (rows, in ladder order) and leg (columns), as ``bench analyze payload`` pivots."""
    numeric = numeric_columns(table, ["load_kg", "error_mm"])
    legs = numeric["leg"].astype(str).str.strip()
    return numeric.assign(leg=legs).pivot_table(
        index="load_kg", columns="leg", values="error_mm", aggfunc="mean", sort=False
    )


def lift_poses(table: pd.DataFrame) -> tuple[LiftPose, ...]:
    """One pose per lift (six consecutive leg readings at one load and repeat), by forward kinematics."""
    from motion import pkm5

    ordered = table.sort_values("step_index")
    key = ordered["load_kg"].astype(str) + "/" + ordered["cycle"].astype(str)
    lifts = []
    for _, rows in ordered.groupby((key != key.shift()).cumsum(), sort=False):
        lengths = rows.drop_duplicates("leg", keep="last").set_index("leg")["length_mm"]
        if sorted(lengths.index) == [1, 2, 3, 4, 5, 6]:
            lifts.append(
                (
                    float(rows["load_kg"].iloc[0]),
                    int(rows["cycle"].iloc[0]),
                    tuple(float(lengths[leg]) for leg in range(1, 7)),
                )
            )
    if not lifts:
        return ()
    fk = pkm5.forward_kinematics(
        np.array([lengths for _, _, lengths in lifts]), mode="translation", residual_tol_mm=FK_RESIDUAL_LIMIT_MM
    )
    return tuple(
        LiftPose(
            load,
            repeat,
            lengths,
            tuple(float(v) for v in fk.pose[i, :3]),
            float(fk.residual_mm[i]),
            bool(fk.converged[i]),
        )
        for i, (load, repeat, lengths) in enumerate(lifts)
    )


def _leg_slopes(table: pd.DataFrame, legs, reference_kg: float) -> tuple[PayloadCompliance | None, ...]:
    """Slope of each leg's e against the added weight (every reading), in the order of ``legs``."""
    slopes = []
    for leg in legs:
        rows = table[table["leg"].astype(str).str.strip() == leg]
        try:
            slopes.append(payload_compliance(rows["load_kg"], rows["error_mm"], reference_load_kg=reference_kg))
        except InsufficientData:
            slopes.append(None)
    return tuple(slopes)


def _shift(lifts: tuple[LiftPose, ...], reference_kg: float) -> tuple[PayloadShift | None, PayloadCompliance | None]:
    used = [lift for lift in lifts if lift.used]
    by_load: dict[float, list] = {}
    for lift in used:
        by_load.setdefault(lift.load_kg, []).append(lift.position_mm)
    if reference_kg not in by_load or len(by_load) < 2:
        return None, None
    shift = payload_shift(by_load, reference_load_kg=reference_kg)
    reference_z = shift.barycentre_mm[list(shift.load_kg).index(reference_kg), 2]
    try:
        compliance = payload_compliance(
            [lift.load_kg for lift in used],
            [lift.position_mm[2] - reference_z for lift in used],
            reference_load_kg=reference_kg,
        )
    except InsufficientData:
        compliance = None
    return shift, compliance


def collect_ladder(
    store: Store, run_id: int, *, k: float = 2.0, resamples: int = 1000, allow_unknown: bool = False
) -> LadderReport:
    """Gather the facts and figures of the report of ``payload_ladder`` run ``run_id`` (``resamples`` unused)."""
    run = store.run(run_id)
    table = run_table(store, run_id, "leg_length")
    calibrations = calibrations_in_force(store, run)
    instrument = reading_instrument(run, calibrations, table["length_mm"], difference=False, reader=READER)
    errors = leg_error_table(table)
    incomplete = tuple(
        f"load {load:g} kg: {int(row.isna().sum())} leg(s) not read, left out of e_i(m)"
        for load, row in errors.iterrows()
        if row.isna().any()
    )
    errors = errors.dropna()
    if errors.empty:
        raise InsufficientData(f"run {run_id}: no load with all six legs read")
    summary = leg_error_summary(errors.index.to_numpy(), errors.to_numpy())
    reference_kg = float(min(errors.index))
    lifts_per_load = tuple(int(table[table["load_kg"] == load].groupby("leg").size().min()) for load in errors.index)
    lifts = lift_poses(table)
    shift, compliance = _shift(lifts, reference_kg)
    deviations = ladder_deviations(
        config=run.config,
        settings=run.settings,
        repeats_measured=min(lifts_per_load),
        instrument_sigma_mm=instrument.sigma_mm,
        reference_load_kg=reference_kg,
        g_m_s2=STANDARD_GRAVITY_M_S2,
        reader=READER,
        allow_unknown=allow_unknown,
    )
    x, y, z = (float(v) for v in run.config.get("start_mm", (np.nan,) * 3))
    base = provenance(run, calibrations)
    left_out = tuple(
        f"lift at {lift.load_kg:g} kg, repeat {lift.repeat}: no pose fits its six lengths within "
        f"{FK_RESIDUAL_LIMIT_MM:g} mm (RMS residual {lift.residual_mm:.3g} mm), left out of PE(m)"
        for lift in lifts
        if not lift.used
    )
    return LadderReport(
        **{**base, "notes": base["notes"] + incomplete + left_out},
        title=run.config.get("title") or "Payload ladder: leg actuation error and payload error (000 §8.7)",
        reference="000 §8.7 / iso9283.md §12",
        clauses=(
            "000 §8.7: leg actuation error against load (Tables A.14, 8-5)",
            "iso9283.md §12.1 (project): PE(m) and the payload compliance estimate k",
        ),
        deviations=tuple(deviations),
        instrument=instrument,
        table=table,
        coverage_factor=k,
        leg_errors=errors,
        lifts_per_load=lifts_per_load,
        summary=summary,
        summary_abs=leg_error_summary(errors.index.to_numpy(), np.abs(errors.to_numpy())),
        leg_slopes=_leg_slopes(table, [str(c) for c in errors.columns], reference_kg),
        commanded_mm=(x, y, z + float(run.config.get("lift_mm", np.nan))),
        lifts=lifts,
        shift=shift,
        compliance=compliance,
        g_m_s2=STANDARD_GRAVITY_M_S2,
    )


def _r(value: float | None) -> str:
    return "n/a (constant)" if value is None else f"{value:+.3f}"


def _slope(slope: PayloadCompliance | None, k: float) -> str:
    if slope is None:
        return "— (needs 3 readings at 2 loads)"
    return format_measured(slope.compliance_mm_per_n, k * slope.u_compliance_mm_per_n, signed=True)


def _results(report: LadderReport) -> tuple[Block, ...]:
    mm = reading_formatter(report)
    k = report.coverage_factor
    legs = [str(c) for c in report.leg_errors.columns]
    ladder = tuple(
        (f"{load:g}", str(n), *(mm(v, True) for v in row))
        for (load, row), n in zip(report.leg_errors.iterrows(), report.lifts_per_load)
    )
    s, a = report.summary, report.summary_abs
    per_leg = tuple(
        (
            leg,
            mm(s.max_error_mm[i]),
            f"{s.load_at_max_kg[i]:g}",
            mm(a.max_error_mm[i]),
            f"{a.load_at_max_kg[i]:g}",
            mm(s.mean_error_mm[i], True),
            _r(s.correlation_with_load[i]),
            _slope(report.leg_slopes[i], k),
        )
        for i, leg in enumerate(legs)
    )
    blocks: list[Block] = [
        Table(
            "ladder",
            ("Load (kg)", "Lifts", *(f"e_{leg} (mm)" for leg in legs)),
            ladder,
            "Leg actuation error e_i(m) = L_meas − L_cmd, signed, mean over the lifts at each load (000 Table "
            "A.14 prints |e|); L_cmd = IK leg length at the commanded lifted pose",
        ),
        Table(
            "legs",
            (
                "Leg",
                "max e (mm)",
                "at (kg)",
                "max |e| (mm)",
                "at (kg)",
                "mean e (mm)",
                "r(load)",
                f"slope of e against weight ± U (mm/N, k = {k:g})",
            ),
            per_leg,
            "Per leg: bench.metrology.leg_error_summary on the signed e (as bench analyze payload) and on |e| "
            "(000 Table 8-5); the slope is bench.metrology.payload_compliance of e against (m − m₀)·g",
        ),
        Paragraph(
            f"All legs: mean e {mm(s.overall_mean_mm, True)} mm, SD {mm(s.overall_sd_mm)} mm; mean |e| "
            f"{mm(a.overall_mean_mm)} mm, SD {mm(a.overall_sd_mm)} mm, over {s.n_loads} loads."
        ),
    ]
    if report.shift is not None:
        shift = report.shift
        blocks.append(
            Table(
                "payload-shift",
                ("Load (kg)", "FK barycentre x, y, z (mm)", "PE(m) x, y, z (mm)", "|PE(m)| (mm)"),
                tuple(
                    (f"{m:g}", ", ".join(mm(v) for v in b), ", ".join(mm(v, True) for v in d), mm(n))
                    for m, b, d, n in zip(shift.load_kg, shift.barycentre_mm, shift.shift_mm, shift.shift_norm_mm)
                ),
                f"Pose-level payload error PE(m) = x̄(m) − x̄(m₀), m₀ = {shift.reference_load_kg:g} kg, "
                f"from the forward kinematics of the calliper lengths (commanded lifted pose "
                f"{', '.join(f'{v:g}' for v in report.commanded_mm)} mm; project definition, not an "
                f"ISO 9283 term)",
            )
        )
    else:
        blocks.append(Paragraph("PE(m) not computed: fewer than two loads with a lift whose six lengths fit a pose."))
    if report.compliance is not None:
        c = report.compliance
        blocks.append(
            Paragraph(
                f"Payload compliance estimate k = {c.compliance_mm_per_n:+.3e} ± {k * c.u_compliance_mm_per_n:.3e} mm/N "
                f"(k = {k:g}; slope of PE_z against (m − m₀)·g, g = {report.g_m_s2:g} m/s², intercept "
                f"{mm(c.intercept_mm, True)} mm, residual SD {mm(c.residual_sd_mm)} mm, {c.n} lifts). Next to, never "
                f"called, ISO 9283 static compliance."
            )
        )
    blocks.append(
        Table(
            "lifts",
            ("Load (kg)", "Repeat", "L_1-L_6 (mm)", "FK x, y, z (mm)", "Residual RMS (mm)", "Used"),
            tuple(
                (
                    f"{lift.load_kg:g}",
                    str(lift.repeat),
                    " ".join(f"{v:.2f}" for v in lift.lengths_mm),
                    ", ".join(mm(v) for v in lift.position_mm),
                    mm(lift.residual_mm),
                    "yes" if lift.used else "no",
                )
                for lift in report.lifts
            ),
            "Every lift: the six calliper lengths and the pose the forward kinematics finds for them "
            "(translation mode)",
        )
    )
    return tuple(blocks)


def ladder_plots(report: LadderReport) -> list[Plot]:
    """e_i(m) per leg against load; |PE(m)| and PE_z(m) against load with the compliance fit."""
    figure = Figure(figsize=(10, 3.8), layout="constrained")
    errors = figure.add_subplot(1, 1, 1)
    for leg in report.leg_errors.columns:
        errors.plot(report.leg_errors.index, report.leg_errors[leg], marker="o", ms=3, lw=1, label=f"leg {leg}")
    errors.axhline(0.0, color="0.6", lw=0.8)
    errors.set_xlabel("load (kg)")
    errors.set_ylabel("e_i(m) = L_meas − L_cmd (mm)")
    errors.legend(fontsize=6, ncols=2)
    plots = [Plot("Leg actuation error of each leg against load (signed, mean over the lifts at each load).", figure)]
    if report.shift is not None:
        figure, (norm, sag) = payload_shift_figure([("FK of the leg lengths", report.shift)])
        if report.compliance is not None:
            c = report.compliance
            loads = np.asarray(report.shift.load_kg)
            force = (loads - report.shift.reference_load_kg) * report.g_m_s2
            sag.plot(
                loads,
                c.intercept_mm + c.compliance_mm_per_n * force,
                ls="--",
                color="tab:red",
                label=f"k = {c.compliance_mm_per_n:+.2e} mm/N",
            )
        for each in (norm, sag):
            each.legend(fontsize=6)
        plots.append(Plot(payload_caption(report.shift.reference_load_kg), figure))
    return plots


def ladder_document(
    report: LadderReport, raw: list[RawData], *, operator: str = "—", laboratory: str = "—"
) -> Document:
    config = report.run.config
    method = (
        f"Dissertation 000 §8.7: for each load a pure vertical lift of {config.get('lift_mm', '—')} mm from "
        f"{config.get('start_mm', '—')} mm, then the six leg lengths read by calliper, home between loads. "
        "e_i(m) = L_meas − L_cmd with L_cmd the IK length at the commanded lifted pose (iso9283.md §12.1); "
        "PE(m) = x̄(m) − x̄(m₀) with x̄ the barycentre of the forward-kinematics poses of the lifts at load m; "
        "k = least-squares slope of PE_z against (m − m₀)·g with intercept and its standard uncertainty."
    )
    recompute = (
        "bench analyze payload FILE.csv (the per-leg summary of the signed e; bench export RUN_ID --kind "
        "leg_length writes the same table); for each lift, bench kin fk pkm5 L1 L2 L3 L4 L5 L6 --mode "
        "translation --json with its six length_mm (one load and cycle, consecutive step_index); PE(m) "
        "and k: bench.metrology.payload_shift and payload_compliance on those poses (no bench analyze "
        "subcommand yet)"
    )
    return assemble(
        report,
        raw,
        operator=operator,
        laboratory=laboratory,
        method=method,
        scope=SCOPE,
        conditions=conditions_section(
            report, ("loads_kg", "lift_mm", "start_mm", "repeats", "velocity_pct", "settle_s", "warmup_s", "ambient_c")
        ),
        results=_results(report),
        plots=ladder_plots(report),
        decision=decision_section(report, NO_CRITERION),
        recompute=recompute,
    )


#: What ``--criterion`` judges in a payload-ladder report: the largest |e| of every leg over the loads (no U stated).
CHARACTERISTICS = {
    "leg_error_mm": Characteristic(
        "largest leg actuation error |e| of every leg over the loads",
        lambda report: [
            (f"leg {leg}", float(report.summary_abs.max_error_mm[i]), None)
            for i, leg in enumerate(report.leg_errors.columns)
        ],
    ),
}
