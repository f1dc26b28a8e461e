"""How a report is written: the layouts of the protocols that have their own (:data:`LAYOUTS`), collecting a run's
report from the store (:func:`collect`), and writing it, a comparison or a trend as HTML, PDF and raw-data CSV
(:func:`write_report`, :func:`write_comparison`, :func:`write_trend`). Imported through :mod:`bench.reports`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from bench.errors import ConfigError
from bench.reports import actuator, content, ladder, path, positioning, positioning_time, stabilisation
from bench.reports.actuator import ActuatorReport, actuator_document, collect_actuator
from bench.reports.calibration import calibration_comparison, with_calibration_page
from bench.reports.compare import layout_comparison, with_histories
from bench.reports.content import CRITERIA, ReportBase, RunReport
from bench.reports.criteria import NO_VERDICT, Characteristic, judge
from bench.reports.deviations import Deviation, iso_deviations
from bench.reports.document import Document, Figure, RawData, Section
from bench.reports.ladder import LadderReport, collect_ladder, ladder_document
from bench.reports.language import customer_document
from bench.reports.lasergrid import SPECIFICATION as GRID_HIT_SPECIFICATION
from bench.reports.lasergrid import GridHitReport, collect_grid_hits, grid_hit_document
from bench.reports.mouse_calibration import collect_mouse_calibration, mouse_calibration_document
from bench.reports.path import collect_path, path_document
from bench.reports.pose_document import comparison_document, run_document
from bench.reports.positioning import (
    GridPositioningReport,
    collect_grid_positioning,
    grid_positioning_document,
    grid_readings,
)
from bench.reports.positioning_time import collect_positioning_time, positioning_time_document
from bench.reports.rawdata import StreamedSeries, write_tables_csv
from bench.reports.stabilisation import StabilisationReport, collect_stabilisation, stabilisation_document
from bench.reports.summary import (
    HistoryEvent,
    Identity,
    comparison_summary,
    is_simulated,
    run_history,
    summary_section,
)
from bench.store import Store

__all__ = [
    "ALL_CRITERIA",
    "CRITERIA",
    "FORMATS",
    "LAYOUTS",
    "ActuatorReport",
    "Deviation",
    "GridHitReport",
    "GridPositioningReport",
    "LadderReport",
    "Layout",
    "ReportBase",
    "ReportPaths",
    "RunReport",
    "SIMULATED_BANNER",
    "StabilisationReport",
    "collect",
    "iso_deviations",
    "own_layout",
    "write_comparison",
    "write_report",
    "write_trend",
]

#: Report formats, in the order they are written.
FORMATS = ("html", "pdf")
#: Printed at the top of every page (HTML and PDF) of a report on data from a simulated device.
SIMULATED_BANNER = "SIMULATED DATA: not a measurement of a physical robot"


@dataclass(frozen=True)
class Layout:
    """A protocol's own report: its collector, its document, the collector keywords only it takes, and (optional)
    whether a run's samples are of the kind it lays out (else the run gets the pose layout)."""

    collect: Callable[..., ReportBase]
    document: Callable[..., Document]
    options: tuple[str, ...] = ()
    applies: Callable[[Store, int], bool] | None = None
    #: what ``--criterion NAME=LIMIT`` judges (:mod:`bench.reports.criteria`); empty: the layout states no verdict
    characteristics: Mapping[str, Characteristic] = field(default_factory=dict)


#: Protocols with a layout of their own; every other protocol gets the pose layout. A delta_positioning run read by
#: another instrument than the laser grid (complete x, y, z, no screen flags) gets the pose layout too.
LAYOUTS = {
    "actuator_accuracy": Layout(collect_actuator, actuator_document, characteristics=actuator.CHARACTERISTICS),
    "payload_ladder": Layout(collect_ladder, ladder_document, characteristics=ladder.CHARACTERISTICS),
    "mouse_calibration": Layout(collect_mouse_calibration, mouse_calibration_document),
    "lasergrid_hits": Layout(collect_grid_hits, grid_hit_document),
    "delta_positioning": Layout(
        collect_grid_positioning,
        grid_positioning_document,
        applies=grid_readings,
        characteristics=positioning.CHARACTERISTICS,
    ),
    "iso9283_stabilisation": Layout(
        collect_stabilisation,
        stabilisation_document,
        ("bands_mm", "hysteresis_mm"),
        characteristics=stabilisation.CHARACTERISTICS,
    ),
    "iso9283_path": Layout(collect_path, path_document, characteristics=path.CHARACTERISTICS),
    "iso9283_cornering": Layout(collect_path, path_document, characteristics=path.CHARACTERISTICS),
    "iso9283_positioning_time": Layout(
        collect_positioning_time,
        positioning_time_document,
        ("bands_mm", "hysteresis_mm"),
        characteristics=positioning_time.CHARACTERISTICS,
    ),
}


#: Every name ``--criterion`` takes, in any layout (each layout checks its own: :func:`bench.reports.criteria.judge`).
ALL_CRITERIA = tuple(dict.fromkeys([*CRITERIA, *(n for layout in LAYOUTS.values() for n in layout.characteristics)]))

#: The layout of a pose protocol's run whose samples are laser-grid readings (partial, NaN where a screen did not
#: decode): the partial-pose statistics of the delta_positioning layout, never a filled axis (bench.reports.content).
PARTIAL_READINGS = LAYOUTS["delta_positioning"]


def own_layout(store: Store, run_id: int) -> Layout | None:
    """The layout of run ``run_id`` when it has one of its own (:data:`LAYOUTS`, or :data:`PARTIAL_READINGS` for a
    pose protocol read by the laser grid), None for the pose layout."""
    layout = LAYOUTS.get(store.run(run_id).protocol_name)
    if layout is None and grid_readings(store, run_id):
        return PARTIAL_READINGS
    if layout is not None and layout.applies is not None and not layout.applies(store, run_id):
        return None
    return layout


#: The command-line flag of each layout keyword, for error messages.
_FLAGS = {"bands_mm": "--band-mm", "hysteresis_mm": "--hysteresis-mm"}


def _layout_options(
    run_id: int, protocol: str, layout: Layout | None, options: Mapping[str, object]
) -> dict[str, object]:
    """The layout keywords given (not None), refusing those the run's layout does not take."""
    given = {name: value for name, value in options.items() if value is not None}
    for name in given:
        if layout is None or name not in layout.options:
            takes = [p for p, each in LAYOUTS.items() if name in each.options]
            raise ConfigError(f"{_FLAGS[name]}: applies to {', '.join(takes)} runs; run {run_id} is a {protocol} run")
    return given


def collect(
    store: Store,
    run_id: int,
    *,
    criteria: Mapping[str, float] | None = None,
    k: float = 2.0,
    resamples: int = 1000,
    allow_unknown: bool = False,
    bands_mm: Sequence[float] | None = None,
    hysteresis_mm: float | None = None,
    decision_rule: str = "simple",
) -> ReportBase:
    """Every fact and number of the report of run ``run_id``, laid out for its protocol (:data:`LAYOUTS`; pose
    protocols: :func:`bench.reports.content.collect`). Project criteria apply to pose runs only; limit bands and
    hysteresis to stabilisation runs only."""
    protocol = store.run(run_id).protocol_name
    layout = own_layout(store, run_id)
    options = _layout_options(run_id, protocol, layout, {"bands_mm": bands_mm, "hysteresis_mm": hysteresis_mm})
    if layout is None:
        return content.collect(
            store,
            run_id,
            criteria=criteria,
            k=k,
            resamples=resamples,
            allow_unknown=allow_unknown,
            decision_rule=decision_rule,
        )
    report = layout.collect(store, run_id, k=k, resamples=resamples, allow_unknown=allow_unknown, **options)
    if not criteria:
        return report
    why = NO_VERDICT.get(protocol, f"a {protocol} run")
    return replace(report, decision=judge(layout.characteristics, report, criteria, decision_rule, why))


def _document(
    report: ReportBase, raw: list[RawData], identity: Identity, history: tuple[HistoryEvent, ...]
) -> Document:
    """The layout's document with the summary (page 1) in front and, for simulated data, the banner of every page."""
    document = (
        run_document
        if isinstance(report, RunReport)
        else grid_positioning_document
        if isinstance(report, GridPositioningReport)
        else LAYOUTS[report.run.protocol_name].document
    )
    body = document(report, raw, operator=identity.operator or "—", laboratory=identity.laboratory or "—")
    return customer_document(
        with_summary(
            body,
            summary_section(report, identity, history, is_simulated(report.run), _decision_line(report)),
            simulated=is_simulated(report.run),
        )
    )


def _decision_line(report: ReportBase) -> str | None:
    """Page 1's one line on the verdict of a report that states none: why, and how a criterion is stated."""
    if report.decision is not None or isinstance(report, RunReport):
        return None
    if isinstance(report, GridHitReport):
        lowest = min(report.hits.heights, key=lambda h: h.expected.rate)
        result = "PASS" if lowest.expected.rate >= GRID_HIT_SPECIFICATION else "FAIL"
        return (
            f"{result} against the thesis's specification (hit rate >= {100 * GRID_HIT_SPECIFICATION:g} % at every "
            f"height, simple acceptance): lowest {100 * lowest.expected.rate:.2f} % at {lowest.height_mm:g} mm"
        )
    protocol = report.run.protocol_name
    layout = PARTIAL_READINGS if isinstance(report, GridPositioningReport) else LAYOUTS[protocol]
    if not layout.characteristics:
        return f"no verdict: {NO_VERDICT.get(protocol, 'this report states none')}"
    return (
        "no acceptance criterion stated: no pass/fail statement (a criterion is stated with --criterion "
        f"NAME=LIMIT, NAME in {', '.join(layout.characteristics)})"
    )


def with_summary(document: Document, summary: Section, *, simulated: bool) -> Document:
    """``document`` with ``summary`` as its first section and ``meta["banner"]`` set when the data are simulated."""
    meta = dict(document.meta)
    if simulated:
        meta["banner"] = SIMULATED_BANNER
    return replace(document, sections=(summary, *document.sections), meta=meta)


@dataclass(frozen=True)
class ReportPaths:
    """What a report call wrote: the report files (None for formats not asked for) and the raw-data CSVs."""

    html: Path | None
    pdf: Path | None
    csv: tuple[Path, ...]
    report_id: str


def _check_formats(formats: Iterable[str]) -> tuple[str, ...]:
    formats = tuple(formats)
    unknown = [f for f in formats if f not in FORMATS]
    if unknown or not formats:
        raise ConfigError(f"--format {','.join(formats) or '(none)'}: expected one or more of {', '.join(FORMATS)}")
    return formats


def _out_dir(out_dir: str | Path) -> Path:
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: exists and is not a folder, expected a folder for the report files")
    out.mkdir(parents=True, exist_ok=True)
    return out


def _write_table(table, path: Path) -> tuple[Path, RawData]:
    """``table`` (or a :class:`~bench.reports.rawdata.StreamedSeries`) as a raw-data CSV at full precision, hashed."""
    digest, rows = table.write_csv(path) if isinstance(table, StreamedSeries) else write_tables_csv([table], path)
    return path, RawData(path.name, digest, rows)


def _write_raw(report: ReportBase, out: Path) -> tuple[Path, RawData]:
    """The analysed tidy table at full precision, so the report's `bench analyze` command reproduces every number."""
    return _write_table(report.table, out / f"run{report.run.id}_samples.csv")


def _write_tilts(report: ReportBase, out: Path) -> list[tuple[Path, RawData]]:
    """The analysed tilt readings of a pose run read by the calliper (``bench analyze orientation`` input)."""
    tilts = getattr(report, "tilt_table", None)
    return [] if tilts is None else [_write_table(tilts, out / f"run{report.run.id}_tilts.csv")]


def _write(
    document: Document, out: Path, stem: str, formats: tuple[str, ...], progress: Callable[[str], None]
) -> tuple[dict[str, Path], str]:
    """Write ``document`` in ``formats`` under its unique number (:mod:`bench.reports.numbering`); the files written
    and that number."""
    from importlib import import_module

    from bench.reports.numbering import numbered
    from bench.reports.plots import draw_all

    draw_all([block.plot for section in document.sections for block in section.blocks if isinstance(block, Figure)])
    document = numbered(document, out, stem)
    written = {}
    for fmt in formats:  # each format's writer imported when asked for (reportlab only for a PDF)
        progress(f"writing {stem}.{fmt}")
        written[fmt] = getattr(import_module(f"bench.reports.{fmt}"), f"write_{fmt}")(document, out / f"{stem}.{fmt}")
    return written, document.meta["report_id"]


def _quiet(message: str) -> None:
    """The default progress callback: say nothing."""


def _open(store: str | Path | Store) -> tuple[Store, bool]:
    if not isinstance(store, (str, Path)):  # a Store, or a reader with its interface (bench.store.lab_reader)
        return store, False
    return Store(store, read_only=True), True  # (a path that names no store is refused, never created)


def write_report(
    store: str | Path | Store,
    run_id: int,
    out_dir: str | Path,
    formats: Iterable[str] = FORMATS,
    *,
    criteria: Mapping[str, float] | None = None,
    operator: str | None = None,
    laboratory: str | None = None,
    k: float = 2.0,
    allow_unknown: bool = False,
    bands_mm: Sequence[float] | None = None,
    hysteresis_mm: float | None = None,
    identity: Mapping[str, str | None] | None = None,
    decision_rule: str = "simple",
    progress: Callable[[str], None] = _quiet,
) -> ReportPaths:
    """Write the report of one run: ``report_run<ID>.html`` / ``.pdf`` and ``run<ID>_samples.csv`` in ``out_dir``.

    Parameters
    ----------
    store : path or Store
        The run store (a path is opened read-only in practice and closed again).
    run_id : int
    out_dir : path
        Folder for the files (created when missing).
    formats : iterable of {"html", "pdf"}
    criteria : mapping, optional
        Project acceptance criteria (``AP_mm``, ``RP_mm``); without them no pass/fail is stated.
    decision_rule : {"simple", "guarded"}
        How the verdict uses U (:mod:`bench.reports.decision`; guarded: pass / not proven / fail, ISO 14253-1).
    operator, laboratory : str, optional
        Printed on the summary page and in the identification section (override ``identity``).
    identity : mapping, optional
        Fields of :class:`bench.reports.summary.Identity` (``dut_serial``, ``customer``, ``order``, ``operator``,
        ``laboratory``, ``measuring_point``); they override the run's stored ``settings.dut``. Missing fields print an
        empty line to fill in by hand (never a template's placeholder).
    k : float
        Coverage factor of the expanded uncertainties.
    allow_unknown : bool
        Write the report even when a row of the deviations table is unknown (printed as "unknown"); by default
        such a run is refused (iso9283.md §11.2).
    progress : callable, optional
        Called with a short line before each long step (figures, each format), once the input is known to be
        good (an error stays the only line).
    bands_mm, hysteresis_mm : optional
        Stabilisation runs only: the limit bands (default 0.1, 0.5, 1.0 mm) and the hysteresis (default one count of
        the run's instrument, 0 without one).
    """
    formats = _check_formats(formats)
    store, opened = _open(store)
    try:
        report = collect(
            store,
            run_id,
            criteria=criteria,
            k=k,
            allow_unknown=allow_unknown,
            bands_mm=bands_mm,
            hysteresis_mm=hysteresis_mm,
            decision_rule=decision_rule,
        )
        history = run_history(store, report.run)
        out = _out_dir(out_dir)
        csv_path, raw = _write_raw(report, out)  # with the store open: a long run's raw data streams from it
        tilts = _write_tilts(report, out)
    finally:
        if opened:
            store.close()
    given = {
        **(identity or {}),
        **({"operator": operator} if operator else {}),
        **({"laboratory": laboratory} if laboratory else {}),
    }
    progress(f"run {run_id} analysed; drawing the figures")
    document = _document(report, [raw, *(r for _, r in tilts)], Identity.of_run(report.run, given), history)
    written, number = _write(document, out, f"report_run{run_id}", formats, progress)
    return ReportPaths(written.get("html"), written.get("pdf"), (csv_path, *(p for p, _ in tilts)), number)


def write_comparison(
    store: str | Path | Store,
    first_run: int,
    second_run: int,
    out_dir: str | Path,
    formats: Iterable[str] = FORMATS,
    *,
    k: float = 2.0,
    identity: Mapping[str, str | None] | None = None,
    progress: Callable[[str], None] = _quiet,
) -> ReportPaths:
    """Write two runs side by side (before/after calibration, two loads, two robots): ``compare_run<A>_run<B>``.

    Pose runs are paired pose by pose; runs of a protocol with a layout of its own must both be of that protocol
    and get their results sections side by side (:mod:`bench.reports.compare`). Both get the run histories. Page 1
    names customer, order, device, measuring point, operator and laboratory (``identity`` over run A's stored
    ``settings.dut``, as :func:`write_report`) and carries the signature block."""
    formats = _check_formats(formats)
    store, opened = _open(store)
    try:
        layouts = [own_layout(store, run_id) for run_id in (first_run, second_run)]
        protocols = [store.run(run_id).protocol_name for run_id in (first_run, second_run)]
        if (layouts[0] is None) != (layouts[1] is None) or (layouts[0] is not None and protocols[0] != protocols[1]):
            raise ConfigError(
                f"--compare: run {first_run} is a {protocols[0]} run and run {second_run} a "
                f"{protocols[1]} run; compare runs of the same kind"
            )
        first, second = collect(store, first_run, k=k), collect(store, second_run, k=k)
        content.check_same_axes((first, second), "--compare")
        histories = (run_history(store, first.run), run_history(store, second.run))
        calibrated = (
            calibration_comparison(store, first, second)
            if layouts[0] is None or layouts[0] is PARTIAL_READINGS
            else None
        )
        out = _out_dir(out_dir)
        raws = [_write_raw(report, out) for report in (first, second)]
    finally:
        if opened:
            store.close()
    progress(f"runs {first_run} and {second_run} analysed; drawing the figures")
    if layouts[0] is None:
        document = with_calibration_page(comparison_document(first, second, [raw for _, raw in raws]), calibrated)
    else:
        own = [layouts[0].document(report, [raw]) for report, (_, raw) in zip((first, second), raws)]
        document = with_calibration_page(layout_comparison(first, second, *own, [raw for _, raw in raws]), calibrated)
    document = with_histories(document, first, second, histories)
    provisional = str(document.meta["report_id"])  # replaced by the document's number where printed (numbering)
    document = with_summary(
        replace(document, subtitle=f"Report {provisional}; {document.subtitle}"),
        comparison_summary(first, second, Identity.of_run(first.run, identity), provisional),
        simulated=is_simulated(first.run) or is_simulated(second.run),
    )
    document = customer_document(document)
    written, number = _write(document, out, f"compare_run{first_run}_run{second_run}", formats, progress)
    return ReportPaths(written.get("html"), written.get("pdf"), tuple(p for p, _ in raws), number)


def write_trend(
    store: str | Path | Store,
    run_ids: Sequence[int],
    out_dir: str | Path,
    formats: Iterable[str] = FORMATS,
    *,
    k: float = 2.0,
    progress: Callable[[str], None] = _quiet,
) -> ReportPaths:
    """Write the trend of N >= 2 pose runs (drift across days): ``trend_run<A>_..._run<Z>`` (:mod:`.trend`)."""
    from bench.reports.trend import trend_document

    formats = _check_formats(formats)
    ids = list(dict.fromkeys(int(i) for i in run_ids))
    if len(ids) < 2:
        raise ConfigError(f"--trend: {len(ids)} distinct run(s), expected two or more")
    store, opened = _open(store)
    try:
        for run_id in ids:
            if own_layout(store, run_id) is not None:
                raise ConfigError(
                    f"--trend: run {run_id} is a {store.run(run_id).protocol_name} run; trends cover pose runs"
                )
        reports = sorted((collect(store, run_id, k=k) for run_id in ids), key=lambda r: r.run.started_utc)
        histories = [run_history(store, r.run) for r in reports]
    finally:
        if opened:
            store.close()
    out = _out_dir(out_dir)
    raws = [_write_raw(report, out) for report in reports]
    progress(f"{len(reports)} runs analysed; drawing the figures")
    document = trend_document(reports, histories, [raw for _, raw in raws])
    if any(is_simulated(r.run) for r in reports):
        document = replace(document, meta={**document.meta, "banner": SIMULATED_BANNER})
    document = customer_document(document)
    written, number = _write(document, out, "trend_" + "_".join(f"run{r.run.id}" for r in reports), formats, progress)
    return ReportPaths(written.get("html"), written.get("pdf"), tuple(p for p, _ in raws), number)
