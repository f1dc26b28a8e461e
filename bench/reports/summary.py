"""Page 1 of a report: who and what was tested, the headline numbers, the verdict, whether the data are simulated,
and what happened during the run.

- :class:`Identity`: the device under test and the people (serial/asset, customer, order, operator, laboratory),
  from ``bench report`` options or, with the same keys, from the run's stored ``settings.dut`` (so a station file
  that records them at run time supplies them; an option given to ``bench report`` wins).
- :func:`headline_rows`: per velocity and load, the worst and the mean AP_P and RP_l over the poses, with U. The U
  of the mean is the mean of the poses' U (the poses share the instrument terms; fully correlated, conservative).
- :func:`verdicts`: per characteristic, the worst pose against the stated criterion, and the overall result
  (simple acceptance, ILAC-G8:09/2019 4.2.1, as :class:`bench.reports.content.Decision`).
- :func:`is_simulated`: whether any device of the run was simulated (the run's settings name a simulator).
- :func:`run_history`: start, every abort, failure and resume the store recorded (the run's settings' ``history``,
  written by :meth:`bench.store.Store.set_status`), interruptions (gaps in the stored sample times: pauses, and
  the runs stored before that history), end status with its reason.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from datetime import datetime
from statistics import median
from typing import Any

from bench.errors import ConfigError
from bench.metrology.formatting import condition_text, format_measured
from bench.metrology.tables import PoseResult
from bench.reports.signature import is_placeholder, measuring_point, signature_table
from bench.store import RunRecord, Store

__all__ = [
    "HistoryEvent",
    "Identity",
    "comparison_summary",
    "headline_rows",
    "is_simulated",
    "run_history",
    "summary_section",
    "verdicts",
]

#: A field nobody stated: printed as an empty line to fill in (:data:`bench.reports.signature.BLANK`).
NOT_RECORDED = ""
#: A gap between two stored samples longer than this many times the run's median interval, and at least
#: :data:`MIN_GAP_S`, is an interruption (pause, abort then resume, loss of a device).
GAP_FACTOR = 20.0
MIN_GAP_S = 30.0


@dataclass(frozen=True)
class Identity:
    """Who and what the report is about; every field is free text, "not recorded" when nobody stated it."""

    dut_serial: str = NOT_RECORDED  #: robot serial number or asset tag
    customer: str = NOT_RECORDED
    order: str = NOT_RECORDED  #: order or job number
    operator: str = NOT_RECORDED
    laboratory: str = NOT_RECORDED
    measuring_point: str = NOT_RECORDED  #: TCP / reference point measured (ISO 9283 6.3); see signature.measuring_point

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any], source: str = "settings.dut") -> Identity:
        """An identity from a mapping with the field names as keys (a station file's ``[dut]`` table)."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ConfigError(f"{source}: unknown key {unknown[0]!r}, expected some of {', '.join(sorted(names))}")
        return cls(**{k: str(v) for k, v in values.items() if not is_placeholder(v)})

    def merged(self, given: Mapping[str, str | None]) -> Identity:
        """This identity with the ``given`` values (e.g. command-line options) replacing the stored ones; a
        placeholder (a template's sample text) is no value."""
        return Identity(
            **{
                f.name: (given.get(f.name) if not is_placeholder(given.get(f.name)) else getattr(self, f.name))
                for f in fields(self)
            }
        )

    @classmethod
    def of_run(cls, run: RunRecord, given: Mapping[str, str | None] | None = None) -> Identity:
        """The run's stored identity (``settings.dut``), completed or overridden by ``given``."""
        identity = cls.from_mapping(run.settings.get("dut") or {}).merged(given or {})
        return replace(
            identity, measuring_point=measuring_point(identity.measuring_point or None, run.settings.get("robot") or {})
        )

    def rows(self) -> list[tuple[str, str]]:
        return [
            ("Customer", self.customer),
            ("Order", self.order),
            ("Device under test (serial / asset)", self.dut_serial),
            ("Measuring point (TCP / reference point)", self.measuring_point),
            ("Operator", self.operator),
            ("Laboratory", self.laboratory),
        ]


def is_simulated(run: RunRecord) -> bool:
    """True when any device of the run was simulated: the settings carry a ``simulator`` entry, or the robot's
    firmware version or the instrument's description says so."""
    settings = run.settings
    if "simulator" in settings:
        return True

    def entry(mapping: Any, *keys: str) -> Any:
        for key in keys:
            mapping = mapping.get(key) if isinstance(mapping, Mapping) else None
        return mapping

    firmware = str(entry(settings, "robot", "firmware", "firmware_version") or "")
    described = str(entry(settings, "instrument", "instrument") or "")
    return firmware.endswith("-sim") or "simulated" in described.lower()


def _by_conditions(poses: Sequence[PoseResult]) -> dict[tuple, list[PoseResult]]:
    groups: dict[tuple, list[PoseResult]] = {}
    for pose in poses:
        groups.setdefault(pose.conditions, []).append(pose)
    return groups


def headline_rows(poses: Sequence[PoseResult]) -> tuple[tuple[str, ...], ...]:
    """Per set of conditions: conditions, poses, worst AP_P ± U (pose), mean AP_P ± U, worst RP_l ± U (pose),
    mean RP_l ± U; every number rounded by its uncertainty."""
    rows = []
    for conditions, group in _by_conditions(poses).items():
        worst_ap = max(group, key=lambda p: p.accuracy.ap_mm)
        worst_rp = max(group, key=lambda p: p.repeatability.rp_mm)
        mean = lambda values: sum(values) / len(values)  # noqa: E731
        rows.append(
            (
                condition_text(conditions) or "all",
                str(len(group)),
                f"{format_measured(worst_ap.ap_u.value, worst_ap.ap_u.expanded_uncertainty)} ({worst_ap.pose})",
                format_measured(
                    mean([p.ap_u.value for p in group]), mean([p.ap_u.expanded_uncertainty for p in group])
                ),
                f"{format_measured(worst_rp.rp_u.value, worst_rp.rp_u.expanded_uncertainty)} ({worst_rp.pose})",
                format_measured(
                    mean([p.rp_u.value for p in group]), mean([p.rp_u.expanded_uncertainty for p in group])
                ),
            )
        )
    return tuple(rows)


def verdicts(decision_verdicts) -> tuple[tuple[str, ...], ...]:
    """Per criterion: name, limit, the worst value ± U and where, poses passed, result; then the overall row.

    ``decision_verdicts``: (criterion, pose label, value, U, limit, result) rows of a Decision. The worst value is
    the one whose upper end value + U is highest (the one closest to failing under either rule); the result of a
    criterion and the overall one follow :func:`bench.reports.decision.overall` (fail > not proven > pass).
    """
    from bench.reports.decision import PASS, overall, unit_of

    by_name: dict[str, list] = {}
    for row in decision_verdicts:
        by_name.setdefault(row[0], []).append(row)
    out = []
    for name, rows in by_name.items():
        worst = max(rows, key=lambda r: r[2] + r[3])
        passed = sum(r[5] == PASS for r in rows)
        out.append(
            (
                f"{name.rsplit('_', 1)[0]} ({unit_of(name)})",
                f"≤ {worst[4]:g}",
                f"{format_measured(worst[2], worst[3])} ({worst[1]})",
                f"{passed} of {len(rows)}",
                overall(r[5] for r in rows).upper(),
            )
        )
    if out:
        out.append(("Overall", "", "", "", overall(r[-1].lower() for r in out).upper()))
    return tuple(out)


@dataclass(frozen=True)
class HistoryEvent:
    time_utc: str
    event: str


def _parse(text: str) -> datetime:
    return datetime.fromisoformat(text.replace("Z", "+00:00"))


def interruptions(times: Sequence[datetime]) -> list[HistoryEvent]:
    """The gaps in sample times ``times`` longer than :data:`GAP_FACTOR` x their median interval and at least
    :data:`MIN_GAP_S`: one event per gap, at the last sample before it, saying how long and when sampling resumed."""
    times = sorted(times)
    gaps = [(b - a).total_seconds() for a, b in zip(times, times[1:])]
    if not gaps:
        return []
    limit = max(MIN_GAP_S, GAP_FACTOR * median(gaps))
    return [
        HistoryEvent(
            before.isoformat(timespec="seconds"),
            f"interrupted: no sample for {gap:.0f} s (paused, or stopped and resumed); sampling "
            f"resumed {after.isoformat(timespec='seconds')}",
        )
        for before, after, gap in zip(times, times[1:], gaps)
        if gap >= limit
    ]


def run_history(store: Store, run: RunRecord) -> tuple[HistoryEvent, ...]:
    """Start, each interruption of the stored samples (:func:`interruptions`: a pause, an abort and a resume, a lost
    device), and the end with its status and reason."""
    started = HistoryEvent(_seconds(run.started_utc), "started")
    gaps = interruptions([_parse(wall_utc) for wall_utc in _sample_wall_times(store, run.id)])
    stored = list(run.settings.get("history", ()))  # every settle and resume, as the store recorded them
    if stored and stored[-1]["event"] == run.status:
        stored.pop()  # the run's end: said below, once
    events = [
        HistoryEvent(_seconds(e["utc"]), e["event"] + (f": {e['reason']}" if e.get("reason") else "")) for e in stored
    ]
    end = {"running": "no end stored (still running, or the program stopped without settling the status)"}.get(
        run.status, run.status
    )
    ended = HistoryEvent(
        _seconds(run.ended_utc) if run.ended_utc else "—", end + (f": {run.reason}" if run.reason else "")
    )
    return (started, *sorted([*events, *gaps], key=lambda event: event.time_utc), ended)


def _sample_wall_times(store: Store, run_id: int) -> list[str]:
    """The stored wall-clock time of every sample of the run in step order, without parsing the samples' JSON (a
    long path run's streamed series took seconds to parse for these times alone); a store without raw rows (the lab
    store's reader) gives them from its parsed samples."""
    if hasattr(store, "stored_rows"):
        return [row[5] for row in store.stored_rows(run_id)]
    return [s.wall_utc for s in store.samples(run_id)]


def _seconds(text: str) -> str:
    return _parse(text).isoformat(timespec="seconds")


def summary_section(
    report, identity: Identity, history: Sequence[HistoryEvent], simulated: bool, decision_line: str | None = None
):
    """Page 1: identity, test and date, the headline table (pose runs) and the verdict under its rule (any layout
    with stated criteria), else ``decision_line`` (why there is none), the data's nature, the run history and the
    signature block. ``report`` is any layout's report."""
    from bench.reports.content import RunReport
    from bench.reports.document import Paragraph, Section, Table, key_values
    from bench.reports.orientation import orientation_headline

    run = report.run
    rows = [
        *identity.rows(),
        ("Test", f"{report.title}; robot {run.robot}"),  # a title may end in a reference in brackets already
        ("Test date (UTC)", (run.started_utc or "—")[:10]),
        ("Report", report.report_id),
    ]
    blocks: list = []
    if simulated:
        blocks.append(
            Paragraph(
                "SIMULATED DATA: at least one device of this run (robot or instrument) was a "
                "simulator. The numbers describe the simulation, not a physical robot."
            )
        )
    blocks.append(key_values("summary-identity", rows))
    if isinstance(report, RunReport) and report.poses:
        from bench.reports.content import axes_statement

        k = f"{report.coverage_factor:g}"
        axes = axes_statement(report)
        if axes:
            blocks.append(Paragraph(axes + "."))
        blocks.append(
            Table(
                "headline",
                (
                    "Conditions",
                    "Poses",
                    "Worst AP_P ± U (mm)",
                    "Mean AP_P ± U (mm)",
                    "Worst RP_l ± U (mm)",
                    "Mean RP_l ± U (mm)",
                ),
                headline_rows(report.poses),
                f"Headline results per velocity and load (U: expanded uncertainty, k = {k}; U of a mean "
                f"is the mean of the poses' U" + (f"; {axes}" if axes else "") + ")",
            )
        )
        blocks.extend(orientation_headline(report))
    if report.decision is not None and (report.decision.verdicts or (isinstance(report, RunReport) and report.poses)):
        verdict = verdicts(report.decision.verdicts)
        blocks.append(Paragraph(f"Decision rule: {report.decision.rule}."))
        if verdict:
            blocks.append(
                Table(
                    "verdict",
                    (
                        "Characteristic",
                        "Criterion",
                        "Worst value ± U (where)",
                        "Poses passed" if isinstance(report, RunReport) else "Passed",
                        "Result",
                    ),
                    verdict,
                    "Verdict against the stated criteria under the decision rule above",
                )
            )
    elif decision_line:
        blocks.append(Paragraph(f"Decision: {decision_line}."))
    blocks.append(
        Table("history", ("Time (UTC)", "Event"), tuple((e.time_utc, e.event) for e in history), "Run history")
    )
    blocks.extend(registration_blocks(run))
    blocks.append(signature_table(identity.operator))
    return Section("Summary", tuple(blocks))


def registration_blocks(run: RunRecord) -> list:
    """The registrations of a relative instrument (:mod:`bench.store.registrations`), one per segment, and, for a
    resumed run, what they mean for its numbers; nothing for a run without them."""
    from bench.reports.document import Paragraph, Table
    from bench.store.registrations import registration_u_mm, registrations

    entries = registrations(run.settings)
    if not entries:
        return []
    rows = tuple(
        (
            str(e["segment"]),
            _seconds(e["utc"]),
            str(e.get("from_step", "—")),
            f"{e['check_discrepancy_max_mm']:.3f}",
            f"{e['tolerance_mm']:.2f}",
            f"{e['u_mm']:.3f}",
        )
        for e in entries
    )
    blocks: list = []
    if len(entries) > 1:
        blocks.append(
            Paragraph(
                f"RESUMED RUN OF A RELATIVE INSTRUMENT: the mice were registered at home {len(entries)} times (export "
                "column registration). Rows of two registrations share a frame only within √(u_i² + u_j²) per axis; "
                "a pose measured in several of them has that spread in its RP."
            )
        )
    blocks.append(
        Table(
            "registrations",
            ("Segment", "Registered (UTC)", "From step", "Check discrepancy (mm)", "Tolerance (mm)", "u per axis (mm)"),
            rows,
            f"Registrations at home, each verified at the check pose (bench.rigs.registration); the U "
            f"of AP includes the largest u, {registration_u_mm(entries):.3f} mm",
        )
    )
    return blocks


def comparison_summary(first, second, identity: Identity, report_id: str):
    """Page 1 of a comparison: who and what (the identity of run A, as for a report of it), the two runs and their
    dates, why a comparison states no verdict, and the signature block."""
    from bench.reports.document import Paragraph, Section, key_values

    a, b = first.run, second.run
    rows = [
        *identity.rows(),
        ("Test", f"comparison of run {a.id} (A) and run {b.id} (B): {first.title} ({a.robot} / {b.robot})"),
        ("Test dates (UTC)", f"A {(a.started_utc or '—')[:10]}, B {(b.started_utc or '—')[:10]}"),
        ("Report", report_id),
    ]
    return Section(
        "Summary",
        (
            key_values("summary-identity", rows),
            Paragraph(
                "Decision: no verdict: a comparison states the differences between two runs (B − A, rounded by "
                "their U); each run's own report states a verdict against criteria."
            ),
            signature_table(identity.operator),
        ),
    )
