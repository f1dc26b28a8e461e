"""``bench run``, ``bench runs``, ``bench resume``, ``bench export``: campaigns on a robot, into the run store.

``bench run PROTOCOL.toml`` pre-flights every target, prints the plan with ``--dry-run``, otherwise runs it on the
simulator (``--sim``), on a station's devices (``--station``) or on a controller (``--port``): with none of them it
is refused in one line, so a forgotten ``--station`` never stores a simulated run beside the real ones. It stores
every sample at once in ``--store``
(``bench.db``); it prints the run id. Ctrl-C once pauses at the next checkpoint (then resume, stop, abort or
halt); twice aborts at once (the robot is stopped). Progress goes to stderr, results and paths to stdout.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from typing import TYPE_CHECKING, Any

from bench.commands.lazy import defer
from bench.errors import ConfigError
from bench.simulators import DEFAULT_SPEED_FACTOR

if TYPE_CHECKING:  # imported inside the handlers: building the parser stays cheap
    from bench.launch import RigRequest
    from bench.protocols import Runner
    from bench.protocols.runner import RunResult
    from bench.store import Store

DEFAULT_STORE = "bench.db"


def register(groups: argparse._SubParsersAction) -> None:
    run = _parser(groups, "run", "run a protocol file on a robot (--station, --sim or --port)")
    run.add_argument("protocol", metavar="PROTOCOL.toml", help="protocol file (see examples/)")
    run.add_argument("--robot", choices=("pkm5", "delta4"), default=None, help="robot (overrides the file)")
    run.add_argument("--dry-run", action="store_true", help="print the plan and pre-flight; move nothing")
    run.add_argument("--campaign", default=None, help="campaign name the run belongs to")
    _rig_arguments(run)
    run.set_defaults(handler=_run, creates_store=True)

    runs = _parser(groups, "runs", "list the stored runs and their status")
    runs.add_argument("--json", action="store_true", help="one JSON object per run, one per line")
    runs.add_argument("--bench", default=None, help="only the runs of this bench")
    runs.add_argument("--robot", default=None, help="only the runs of this robot (pkm5, delta4, ...)")
    runs.add_argument("--since", default=None, metavar="DATE", help="only runs started on or after this UTC date")
    runs.set_defaults(handler=_runs)

    resume = _parser(groups, "resume", "continue a run at its last checkpoint without duplicating samples")
    resume.add_argument("run_id", metavar="RUN_ID", type=int)
    _rig_arguments(resume)
    resume.set_defaults(handler=_resume)

    backup = _parser(groups, "backup", "a consistent copy of the run store, safe while a run is writing")
    backup.add_argument("destination", metavar="DEST", help="the new file (it must not exist)")
    backup.set_defaults(handler=_backup)

    export = _parser(groups, "export", "write a run's tidy sample table (the input of bench analyze)")
    export.add_argument(
        "run_id",
        metavar="RUN",
        help="the run: its id, BENCH/ID or its UUID (prefix); with --store postgresql://... from the lab store",
    )
    defer(export, _add_export_format)
    export.add_argument("--out", default=None, help="output file (default run-ID.FORMAT)")
    export.add_argument(
        "--kind",
        default=None,
        help="sample kind to export (pose, arrival, actuator_travel, leg_length, grid_hit, ...; "
        "default: pose if the run has any, else its most frequent kind; arrival with --series)",
    )
    export.add_argument(
        "--series",
        action="store_true",
        help="export the streamed series of each sample (one row per point; stabilisation runs)",
    )
    export.set_defaults(handler=_export)


def _add_export_format(parser: argparse.ArgumentParser) -> None:
    from bench.store import EXPORT_FORMATS

    parser.add_argument("--format", choices=EXPORT_FORMATS, default="csv", help="file format")


def _parser(groups: argparse._SubParsersAction, name: str, text: str) -> argparse.ArgumentParser:
    parser = groups.add_parser(
        name, help=text, description=text, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--store", default=DEFAULT_STORE, help="run store (SQLite file)")
    return parser


def _rig_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--sim",
        action="store_true",
        help="simulated controller and sensors (bench run needs --sim, --station or --port; resume: the run's own rig)",
    )
    where.add_argument("--port", default=None, help="serial port of a real controller, e.g. /dev/ttyUSB0")
    parser.add_argument(
        "--station",
        default=None,
        metavar="STATION.toml",
        help="the bench's devices (examples/stations/); with --sim each is replaced by its simulator",
    )
    parser.add_argument("--seed", type=int, default=None, help="simulator seed (resume: the run's own)")
    parser.add_argument(
        "--speed-factor",
        type=float,
        default=None,
        help=f"simulated time speed-up (default {DEFAULT_SPEED_FACTOR:g}; resume: the run's own)",
    )
    parser.add_argument("--mouse-xy", default=None, help="hardware: event device of the x-y mouse")
    parser.add_argument("--mouse-xz", default=None, help="hardware: event device of the x-z mouse")
    defer(parser, _add_mouse_xz_mount)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    kinematic = parser.add_mutually_exclusive_group()
    kinematic.add_argument(
        "--kinematic-calibration",
        type=int,
        default=None,
        metavar="ID",
        help="command by this pkm5_kinematics calibration (default: the robot's newest; resume: the run's own)",
    )
    kinematic.add_argument(
        "--no-kinematic-calibration",
        action="store_true",
        help="command by the documented geometry, whatever calibration is stored",
    )
    parser.add_argument(
        "--true-geometry-seed",
        type=int,
        default=None,
        metavar="SEED",
        help="simulated pkm5 or delta4 (also a --station rehearsed with --sim): move by this seed's "
        "perturbed true geometry (docs/calibration.md)",
    )
    parser.add_argument(
        "--ideal",
        action="store_true",
        help="simulated robot without its error model (backlash, noise, play; resume: the run's own)",
    )


def _add_mouse_xz_mount(parser: argparse.ArgumentParser) -> None:
    from bench.rigs.mice_liveness import XZ_MOUNTS, XZ_PLATFORM

    parser.add_argument(
        "--mouse-xz-mount",
        choices=XZ_MOUNTS,
        default=None,
        help=f"hardware: how the x-z mouse is mounted (default {XZ_PLATFORM}: on the platform, it sees x and z; "
        "guided: on vertical guides pushed by the end effector, it sees z only)",
    )


def rig_request(args: argparse.Namespace) -> RigRequest:
    """What the rig options ask for, as the :class:`bench.launch.RigRequest` the GUI fills in too."""
    from bench.calibration.compensate import NEWEST, OFF
    from bench.launch import RigRequest

    kinematic = (
        OFF
        if args.no_kinematic_calibration
        else (NEWEST if args.kinematic_calibration is None else args.kinematic_calibration)
    )
    return RigRequest(
        station=args.station,
        port=args.port,
        mouse_xy=args.mouse_xy,
        mouse_xz=args.mouse_xz,
        mouse_xz_mount=args.mouse_xz_mount,
        simulate=args.sim,
        seed=args.seed,
        speed_factor=args.speed_factor,
        port_label="--port",
        kinematic_calibration=kinematic,
        true_geometry_seed=args.true_geometry_seed,
        ideal=args.ideal,
    )


def build_rig(
    args: argparse.Namespace,
    robot: str,
    store: Store,
    stored: dict[str, Any] | None = None,
    fixture: str = "assembled",
    requires: frozenset[str] = frozenset(),
    protocol: str = "the protocol",
):
    """The rig the command-line options describe (see :func:`bench.launch.open_rig`); says on stderr which
    kinematic calibration is in force."""
    from bench.calibration.compensate import describe_in_force
    from bench.launch import open_rig

    with _stop_signals_interrupt():  # homing and the registration's check moves are a safe stop too
        rig = open_rig(
            rig_request(args), store, robot=robot, stored=stored, fixture=fixture, requires=requires, protocol=protocol
        )
    print(f"bench: {describe_in_force(rig)}", file=sys.stderr)
    return rig


#: Signals that end a run like a double Ctrl-C: the robot is stopped, the run ends aborted and resumable (systemd
#: and docker send SIGTERM; a closed terminal sends SIGHUP).
STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


def _raise_interrupt(signum: int, frame: Any) -> None:
    name = signal.Signals(signum).name
    print(f"\nbench: {name}: stopping the robot and aborting the run (resumable)", file=sys.stderr)
    raise KeyboardInterrupt(name)


@contextmanager
def _signal_handlers(handlers: dict[int, Any]) -> Iterator[None]:
    """Install ``{signal number: handler}`` for the block; the previous handlers come back after it."""
    previous = {number: signal.getsignal(number) for number in handlers}
    for number, handler in handlers.items():
        signal.signal(number, handler)
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)


def _stop_signals_interrupt():
    """While the rig opens (homing, the registration's check moves): SIGTERM and SIGHUP interrupt like Ctrl-C, so
    the rig builder closes what it opened (the controller stops) and the run is left as it was, resumable."""
    return _signal_handlers({number: _raise_interrupt for number in STOP_SIGNALS})


def _ctrl_c_pauses(runner: Runner):
    """Ctrl-C while running: pause at the next checkpoint. Ctrl-C once a pause is asked for, at the pause menu, or in
    any state but running, and SIGTERM or SIGHUP: abort at once (robot stopped, resumable). The handler stays the
    same for the whole run (a resume does not re-arm it) and only raises the abort's KeyboardInterrupt."""
    from bench.protocols import RunState, TransitionError

    def on_signal(signum: int, frame: Any) -> None:
        if runner.state is RunState.RUNNING and not runner.pause_requested:
            try:
                runner.request_pause()
            except TransitionError:  # the run left RUNNING between the look and the request: abort instead
                pass
            else:
                print("\nbench: pausing at the next checkpoint (Ctrl-C again aborts now)", file=sys.stderr)
                return
        print("\nbench: Ctrl-C: stopping the robot and aborting the run (resumable)", file=sys.stderr)
        raise KeyboardInterrupt("Ctrl-C")

    return _signal_handlers({signal.SIGINT: on_signal, **{number: _raise_interrupt for number in STOP_SIGNALS}})


def _ask_after_pause(runner: Runner) -> None:
    actions = {"r": runner.resume, "s": runner.stop, "a": runner.abort, "h": runner.halt}
    while True:
        print("paused: [r]esume, [s]top, [a]bort, [h]alt (Ctrl-C aborts)? ", end="", file=sys.stderr, flush=True)
        line = sys.stdin.readline()
        if not line:  # end of input: nobody can answer, so abort once (the run stays resumable)
            print("\nbench: end of input while paused: aborting (resumable)", file=sys.stderr)
            runner.abort()
            return
        choice = line.strip()[:1].lower()
        if choice in actions:
            actions[choice]()
            return


def execute(runner: Runner, start) -> RunResult:
    """Run ``start()`` with the Ctrl-C handling; print the outcome; the rig is closed afterwards."""
    try:
        with _ctrl_c_pauses(runner):
            result = start()
    finally:
        runner.rig.close()
    reason = f": {result.reason}" if result.reason else ""
    print(
        f"run {result.run_id} {result.exit_status} ({result.samples} samples) in {runner.store.path}{reason}",
        file=sys.stderr,
    )
    print(result.run_id)
    if result.exception is not None and not isinstance(result.exception, KeyboardInterrupt):
        print(f"bench: error: {result.exception}", file=sys.stderr)
    return result


@contextmanager
def _new_store_removed_if_refused(path: str) -> Iterator[None]:
    """A store file this command creates is removed again when the command ends in an error before a run was
    stored in it (a station file that does not load, a device that does not open, a capability missing): a refused
    run leaves no new file behind. A store that existed is never touched here."""
    from pathlib import Path

    from bench.store import Store

    existed = Path(path).exists()
    try:
        yield
    except BaseException:
        if not existed and Path(path).exists():
            with Store(path, read_only=True) as opened:
                empty = not opened.runs()
            if empty:
                for leftover in (path, f"{path}-wal", f"{path}-shm"):
                    Path(leftover).unlink(missing_ok=True)
        raise


def _run(args: argparse.Namespace) -> int:
    from bench.launch import check_speed_factor
    from bench.protocols import Runner, load_protocol, preflight, summarize
    from bench.store import Store

    protocol = load_protocol(args.protocol, robot=args.robot)
    if args.dry_run:
        summary = summarize(protocol)
        print("\n".join(summary.lines()))
        if not summary.ok:
            from bench.errors import UnreachableTarget

            raise UnreachableTarget(f"{protocol.source}: {summary.problems()[0]}")
        return 0
    if not (args.sim or args.station or args.port):  # before the store opens: a refused run writes nothing
        raise ConfigError(
            f"bench run {args.protocol}: no rig named, expected --station STATION.toml (the bench's "
            "devices) or --sim (the simulator)"
        )
    # the one walk of the plan, before a simulator or a port is opened: the capabilities it needs and the documented
    # geometry's pre-flight; the runner checks its targets again by the geometry the rig's robot commands by
    early = preflight(protocol)
    if args.speed_factor is not None:  # before the store opens: a refused run leaves no new file behind
        check_speed_factor(args.speed_factor)
    with _new_store_removed_if_refused(args.store), Store(args.store) as store:
        rig = build_rig(
            args,
            protocol.robot,
            store,
            fixture=getattr(protocol, "fixture", "assembled"),
            requires=early.capabilities,
            protocol=f"protocol {protocol.name!r}",
        )
        runner = Runner(rig, store, progress=not args.no_progress, on_pause=_ask_after_pause)
        result = execute(runner, lambda: runner.run(protocol, campaign=args.campaign, plan=early))
    return 0 if result.exit_status == "completed" else 1


def _resume(args: argparse.Namespace) -> int:
    from bench.launch import resuming
    from bench.protocols import Runner, preflight, protocol_from_config
    from bench.protocols.resume import stored_replies
    from bench.store import Store

    with Store(args.store) as store, resuming(store, args.run_id) as record:
        protocol = protocol_from_config(record.config, source=f"run {args.run_id}", stored=True)
        # the one walk of the plan (as it ran), before the rig opens: capabilities, pre-flight, where it resumes
        early = preflight(protocol, stored=stored_replies(store, args.run_id))
        rig = build_rig(
            args,
            record.robot,
            store,
            stored=record.settings,
            fixture=record.config.get("fixture", "assembled"),
            requires=early.capabilities,
            protocol=f"protocol {protocol.name!r}",
        )
        runner = Runner(rig, store, progress=not args.no_progress, on_pause=_ask_after_pause)
        result = execute(runner, lambda: runner.resume_run(args.run_id, plan=early))
    return 0 if result.exit_status == "completed" else 1


def _runs(args: argparse.Namespace) -> int:
    from bench.store.lab import is_lab_url, open_runs_store  # a file or, read-only, a postgresql:// lab store

    if is_lab_url(args.store):
        opened = open_runs_store(args.store)
    else:
        opened = open_runs_store(args.store, read_only=True)
    with opened as store:
        records = store.runs(bench=args.bench, robot=args.robot, since=_since(args.since))
    if args.json:
        for record in records:
            print(json.dumps(record.as_dict(), sort_keys=True))
        return 0
    protocols = [f"{r.protocol_name} v{r.protocol_version}" for r in records]
    # columns as wide as their longest entry (a station's bench name can be long), at least the old widths
    bench_w = max([12, *(len(r.bench) for r in records)])
    protocol_w = max([26, *(len(p) for p in protocols)])
    print(
        f"{'id':>4}  {'bench':<{bench_w}} {'protocol':<{protocol_w}} {'robot':<6} {'rig':<9} {'status':<11} "
        f"{'samples':>7}  {'started (UTC)':<19}  reason"
    )
    for r, protocol in zip(records, protocols):
        rig = "simulated" if r.simulated else "hardware"
        print(
            f"{r.id:>4}  {r.bench:<{bench_w}} {protocol:<{protocol_w}} {r.robot:<6} {rig:<9} {r.status:<11} "
            f"{r.n_samples:>7}  {r.started_utc[:19]:<19}  {r.reason or ''}"
        )
    return 0


def _since(text: str | None) -> str | None:
    """``--since`` checked as an ISO date or time (compared with the stored ISO UTC start times)."""
    if text is None:
        return None
    try:
        datetime.fromisoformat(text)
    except ValueError:
        raise ConfigError(f"--since {text}: expected an ISO date such as 2026-11-01") from None
    return text


def _default_kind(store: Store, run_id: int) -> str:
    """:func:`bench.store.default_kind`, said on stderr when the run holds several kinds."""
    from bench.store import default_kind

    kind = default_kind(store, run_id)
    kinds = store.sample_kinds(run_id)
    if len(kinds) > 1:
        listed = ", ".join(f"{k} ({n})" for k, n in kinds.items())
        print(f"bench: exporting kind {kind}; the run also holds {listed}: choose with --kind", file=sys.stderr)
    return kind


def _backup(args: argparse.Namespace) -> int:
    from bench.store import Store

    with Store(args.store, read_only=True) as store:
        print(store.backup_to(args.destination))
    return 0


def _export(args: argparse.Namespace) -> int:
    from bench.store import export_run
    from bench.store.lab import is_lab_url
    from bench.store.lab_reader import open_named_runs

    opened, (run_id,) = open_named_runs(args.store if is_lab_url(args.store) else args.store, [args.run_id])
    with opened as store:
        out = args.out or f"run-{run_id}.{args.format}"
        kind = args.kind or ("arrival" if args.series else _default_kind(store, run_id))
        print(export_run(store, run_id, out, fmt=args.format, kind=kind, series=args.series))
    return 0
