"""``bench run``, ``bench runs``, ``bench resume``, ``bench export``: campaigns on a robot, into the run store.

``bench run PROTOCOL.toml`` pre-flights every target, prints the plan with ``--dry-run``, otherwise runs it on the
simulator (``--sim``, the default) or on hardware (``--port``), storing every sample at once in ``--store``
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
from typing import Any

from bench.errors import ConfigError, LinkError
from bench.protocols import Runner, load_protocol, preflight, summarize
from bench.protocols.runner import RunResult
from bench.store import EXPORT_FORMATS, Store, export_run

DEFAULT_STORE = "bench.db"
#: Simulated time runs this much faster than real moves in ``--sim`` runs unless told otherwise.
DEFAULT_SPEED_FACTOR = 10000.0


def register(groups: argparse._SubParsersAction) -> None:
    run = _parser(groups, "run", "run a protocol file on a robot (simulated by default)")
    run.add_argument("protocol", metavar="PROTOCOL.toml", help="protocol file (see examples/)")
    run.add_argument("--robot", choices=("pkm5", "delta4"), default=None, help="robot (overrides the file)")
    run.add_argument("--dry-run", action="store_true", help="print the plan and pre-flight; move nothing")
    run.add_argument("--campaign", default=None, help="campaign name the run belongs to")
    _rig_arguments(run)
    run.set_defaults(handler=_run)

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

    export = _parser(groups, "export", "write a run's tidy sample table (the input of bench analyze)")
    export.add_argument("run_id", metavar="RUN_ID", type=int)
    export.add_argument("--format", choices=EXPORT_FORMATS, default="csv", help="file format")
    export.add_argument("--out", default=None, help="output file (default run-RUN_ID.FORMAT)")
    export.add_argument("--kind", default=None,
                        help="sample kind to export (pose, arrival, actuator_travel, leg_length, grid_hit, ...; "
                             "default: pose if the run has any, else its most frequent kind; arrival with --series)")
    export.add_argument("--series", action="store_true",
                        help="export the streamed series of each sample (one row per point; stabilisation runs)")
    export.set_defaults(handler=_export)


def _parser(groups: argparse._SubParsersAction, name: str, text: str) -> argparse.ArgumentParser:
    parser = groups.add_parser(name, help=text, description=text,
                               formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--store", default=DEFAULT_STORE, help="run store (SQLite file)")
    return parser


def _rig_arguments(parser: argparse.ArgumentParser) -> None:
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--sim", action="store_true", help="use the simulated controller and sensors (default)")
    where.add_argument("--port", default=None, help="serial port of a real controller, e.g. /dev/ttyUSB0")
    parser.add_argument("--seed", type=int, default=None, help="simulator seed (resume: the run's own)")
    parser.add_argument("--speed-factor", type=float, default=None,
                        help=f"simulated time speed-up (default {DEFAULT_SPEED_FACTOR:g}; resume: the run's own)")
    parser.add_argument("--mouse-xy", default=None, help="hardware: event device of the x-y mouse")
    parser.add_argument("--mouse-xz", default=None, help="hardware: event device of the x-z mouse")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def build_rig(args: argparse.Namespace, robot: str, store: Store, stored: dict[str, Any] | None = None,
              fixture: str = "assembled"):
    """The rig the arguments describe: the simulator by default, hardware with ``--port``; ``fixture`` is the
    protocol's (``actuator-bench``: the pkm5's actuators free-standing, moved one at a time)."""
    stored = stored or {}
    if args.port is None:
        seed = args.seed if args.seed is not None else stored.get("simulator", {}).get("seed", 0)
        speed = args.speed_factor or stored.get("speed_factor") or DEFAULT_SPEED_FACTOR
        return simulated_rig_in(store, robot, seed=seed, speed_factor=speed, fixture=fixture)
    if fixture == "actuator-bench":
        return _hardware_actuator_bench(args.port, robot)
    if robot != "pkm5" or not (args.mouse_xy and args.mouse_xz):
        raise ConfigError("--port: hardware runs support the pkm5 with --mouse-xy and --mouse-xz event devices")
    from bench.protocols.kinematics import robot_model
    from bench.rigs.mice import hardware_rig
    from bench.sensors.calibration import CountsCalibration

    try:
        record = store.calibration("mouse")
    except ConfigError:  # before the first mouse_calibration run: the sensor's nominal 800 cpi, recorded as such
        record = store.ensure_calibration("mouse", {"mm_per_count": 25.4 / 800, "nominal": True},
                                          notes="nominal 800 cpi; run examples/mouse_calibration.toml")
    scale = record.params["mm_per_count"]
    calibration = CountsCalibration.from_scales(scale, scale, calibration_id=f"mouse-v{record.version}",
                                                date=record.created_utc[:10])
    rig = hardware_rig(args.port, mouse_xy=args.mouse_xy, mouse_xz=args.mouse_xz, calibration=calibration,
                       home_mm=robot_model(robot).home)
    rig.calibration_ids = (record.id,)
    return rig


def _hardware_actuator_bench(port: str, robot: str):
    """The pkm5 controller on ``port`` driving free-standing actuators; readings are typed in from the gauge."""
    import serial

    from bench.rigs.mice import ConsoleOperator
    from bench.rigs.interfaces import Rig
    from bench.simulators.rig import CalliperOnly, DriverMover
    from bench.robots.pkm5 import Pkm5Controller

    if robot != "pkm5":
        raise ConfigError(f"--robot {robot}: the actuator bench exists for the pkm5 only")
    try:
        port_instance = serial.serial_for_url(port, baudrate=115200, timeout=0.05)
    except serial.SerialException as exc:
        raise LinkError(f"--port {port}: cannot open it ({exc.strerror or exc})") from None
    controller = Pkm5Controller(port_instance, fixture="actuator-bench")
    try:
        controller.identify()
        controller.enable()
    except BaseException:
        controller.shutdown()
        raise
    return Rig(DriverMover(controller), CalliperOnly(), ConsoleOperator())


def simulated_rig_in(store: Store, robot: str, *, seed: int, speed_factor: float, fixture: str = "assembled"):
    """A simulated rig whose mouse calibration is recorded (get-or-create) in ``store``."""
    from bench.simulators.rig import simulated_rig

    if not speed_factor > 0:
        raise ConfigError(f"--speed-factor = {speed_factor:g}, expected a number > 0")
    rig = simulated_rig(robot, seed=seed, speed_factor=speed_factor, fixture=fixture)
    rig.extra["simulator"] = {"seed": seed}
    if fixture == "actuator-bench":
        return rig  # no calibration in force: the readings are typed-in gauge values
    if robot == "pkm5":
        params = {"cpi": rig.instrument.cpi, "mm_per_count": 25.4 / rig.instrument.cpi}
        name, notes = rig.instrument.calibration.calibration_id, "nominal calibration of the simulated mice"
    else:
        params = {"screens": repr(rig.instrument.geometry)}
        name, notes = rig.instrument.geometry.calibration_id, "laser-grid geometry of the legacy GUI drawing"
    rig.calibration_ids = (store.ensure_calibration(name, params, notes=notes).id,)
    return rig


@contextmanager
def _ctrl_c_pauses(runner: Runner) -> Iterator[None]:
    """First Ctrl-C: pause at the next checkpoint; a second one: KeyboardInterrupt (abort, robot stopped)."""
    previous = signal.getsignal(signal.SIGINT)

    def on_signal(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nbench: pausing at the next checkpoint (Ctrl-C again aborts now)", file=sys.stderr)
        runner.request_pause()

    signal.signal(signal.SIGINT, on_signal)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _ask_after_pause(runner: Runner) -> None:
    actions = {"r": runner.resume, "s": runner.stop, "a": runner.abort, "h": runner.halt}
    while True:
        print("paused: [r]esume, [s]top, [a]bort, [h]alt? ", end="", file=sys.stderr, flush=True)
        choice = sys.stdin.readline().strip()[:1].lower()
        if choice in actions:
            actions[choice]()
            if choice == "r":
                signal.signal(signal.SIGINT, lambda *_: (runner.request_pause()))
            return


def execute(runner: Runner, start) -> RunResult:
    """Run ``start()`` with the Ctrl-C handling; print the outcome; the rig is closed afterwards."""
    try:
        with _ctrl_c_pauses(runner):
            result = start()
    finally:
        runner.rig.close()
    reason = f": {result.reason}" if result.reason else ""
    print(f"run {result.run_id} {result.exit_status} ({result.samples} samples) in {runner.store.path}{reason}",
          file=sys.stderr)
    print(result.run_id)
    if result.exception is not None and not isinstance(result.exception, KeyboardInterrupt):
        print(f"bench: error: {result.exception}", file=sys.stderr)
    return result


def _run(args: argparse.Namespace) -> int:
    protocol = load_protocol(args.protocol, robot=args.robot)
    if args.dry_run:
        summary = summarize(protocol)
        print("\n".join(summary.lines()))
        if not summary.ok:
            from bench.errors import UnreachableTarget
            raise UnreachableTarget(f"{protocol.source}: {summary.problems()[0]}")
        return 0
    preflight(protocol)  # before a simulator or a port is opened; the runner checks again
    with Store(args.store) as store:
        rig = build_rig(args, protocol.robot, store, fixture=getattr(protocol, "fixture", "assembled"))
        runner = Runner(rig, store, progress=not args.no_progress, on_pause=_ask_after_pause)
        result = execute(runner, lambda: runner.run(protocol, campaign=args.campaign))
    return 0 if result.exit_status == "completed" else 1


def _resume(args: argparse.Namespace) -> int:
    with Store(args.store) as store:
        record = store.run(args.run_id)
        rig = build_rig(args, record.robot, store, stored=record.settings,
                        fixture=record.config.get("fixture", "assembled"))
        runner = Runner(rig, store, progress=not args.no_progress, on_pause=_ask_after_pause)
        result = execute(runner, lambda: runner.resume_run(args.run_id))
    return 0 if result.exit_status == "completed" else 1


def _runs(args: argparse.Namespace) -> int:
    from bench.store.lab import open_runs_store  # the store is a file or, read-only, a postgresql:// lab store
    with open_runs_store(args.store) as store:
        records = store.runs(bench=args.bench, robot=args.robot, since=_since(args.since))
    if args.json:
        for record in records:
            print(json.dumps(record.as_dict(), sort_keys=True))
        return 0
    print(f"{'id':>4}  {'bench':<12} {'protocol':<26} {'robot':<6} {'status':<9} {'samples':>7}  "
          f"{'started (UTC)':<19}  reason")
    for r in records:
        protocol = f"{r.protocol_name} v{r.protocol_version}"
        print(f"{r.id:>4}  {r.bench:<12} {protocol:<26} {r.robot:<6} {r.status:<9} "
              f"{r.n_samples:>7}  {r.started_utc[:19]:<19}  {r.reason or ''}")
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
    """``pose`` when the run has pose samples, else its most frequent kind (said on stderr when the run has several)."""
    store.run(run_id)  # names a run that does not exist
    kinds = store.sample_kinds(run_id)
    if "pose" in kinds or not kinds:
        kind = "pose"
    else:
        kind = next(iter(kinds))
    if len(kinds) > 1:
        listed = ", ".join(f"{k} ({n})" for k, n in kinds.items())
        print(f"bench: exporting kind {kind}; the run also holds {listed}: choose with --kind", file=sys.stderr)
    return kind


def _export(args: argparse.Namespace) -> int:
    out = args.out or f"run-{args.run_id}.{args.format}"
    with Store(args.store) as store:
        kind = args.kind or ("arrival" if args.series else _default_kind(store, args.run_id))
        print(export_run(store, args.run_id, out, fmt=args.format, kind=kind, series=args.series))
    return 0
