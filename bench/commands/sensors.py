"""``bench sensors``: list mice, simulate and read a mouse stream, decode laser-grid hits, tilt from two depths, and
prompted calliper entry stored row by row. Units: mm and degrees."""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
from pathlib import Path

from bench.commands.kin import emit
from bench.commands.lazy import defer
from bench.errors import ConfigError


def register(groups: argparse._SubParsersAction) -> None:
    sensors = groups.add_parser("sensors", help="sensors: mouse, laser grid, calliper (mm, degrees)")
    actions = sensors.add_subparsers(dest="action", metavar="ACTION", required=True)
    for name, adder in (
        ("mouse-list", _add_mouse_list),
        ("mouse-sim", _add_mouse_sim),
        ("mouse-read", _add_mouse_read),
        ("grid-decode", _add_grid_decode),
        ("tilt", _add_tilt),
        ("calliper-entry", _add_entry),
    ):
        adder(actions, name)


def _parser(actions: argparse._SubParsersAction, name: str, help_text: str) -> argparse.ArgumentParser:
    parser = actions.add_parser(name, help=help_text, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--json", action="store_true", help="print the result as one JSON object")
    return parser


def _add_mouse_list(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "list event devices with REL_X/REL_Y (mice) and their stable names")
    parser.set_defaults(handler=_mouse_list)


def _mouse_list(args: argparse.Namespace) -> int:
    from bench.sensors.mouse import list_mice

    mice = list_mice()
    emit(
        {"mice": [vars(m) for m in mice]},
        args.json,
        [f"{m.path}\t{m.name}\t{m.phys}" for m in mice] or ["no mice found under /sys/class/input"],
    )
    return 0


def _add_mouse_sim(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "write a simulated mouse's input_event records (a circle) to a FIFO or file")
    parser.add_argument("out", help="FIFO or file to write")
    defer(parser, _add_stream_arguments)
    parser.set_defaults(handler=_mouse_sim)


def _add_stream_arguments(parser: argparse.ArgumentParser) -> None:
    from bench.simulators.mouse import add_stream_arguments

    add_stream_arguments(parser)


def _mouse_sim(args: argparse.Namespace) -> int:
    from bench.simulators.mouse import write_stream_from_args

    count = write_stream_from_args(args)
    emit({"path": args.out, "events": count}, args.json, [f"{count} events written to {args.out}"])
    return 0


def _add_mouse_read(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "read a mouse (event device, FIFO or file) and print the displacement in mm")
    parser.add_argument("path", help="/dev/input/by-path/...-event-mouse, a FIFO or a recorded file")
    parser.add_argument("--label", default="mouse")
    parser.add_argument("--cpi", type=float, default=800.0, help="nominal CPI when no --calibration is given")
    parser.add_argument("--calibration", type=Path, help="calibration JSON (CountsCalibration.to_dict)")
    parser.add_argument("--duration-s", type=float, default=5.0, help="stop after this time or at end of stream")
    parser.add_argument("--grab", action="store_true", help="exclusive access (event devices only)")
    parser.set_defaults(handler=_mouse_read)


def _load_calibration(args: argparse.Namespace):
    from bench.sensors.calibration import CountsCalibration

    if args.calibration is None:
        return CountsCalibration.from_cpi(args.cpi)
    try:
        data = json.loads(args.calibration.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"{args.calibration}: cannot read the calibration ({exc}); expected a JSON file") from None
    return CountsCalibration.from_dict(data, where=str(args.calibration))


def _mouse_read(args: argparse.Namespace) -> int:
    from bench.sensors.mouse import EvdevMouse, MouseGroup

    mouse = EvdevMouse(args.path, _load_calibration(args), label=args.label, grab=args.grab)
    group = MouseGroup([mouse])
    try:
        frames = group.collect(args.duration_s)[args.label]
        reading = mouse.read()
    finally:
        group.close()
    result = {
        "path": args.path,
        "frames": len(frames),
        "x_mm": reading.value[0],
        "y_mm": reading.value[1],
        "count_x": reading.raw[0],
        "count_y": reading.raw[1],
        "valid": reading.valid,
        "calibration_id": reading.calibration_id,
    }
    emit(
        result,
        args.json,
        [
            f"{len(frames)} frames from {args.path}",
            (
                f"x = {reading.value[0]:.4f} mm, y = {reading.value[1]:.4f} mm "
                f"({reading.raw[0]}, {reading.raw[1]} counts; calibration {reading.calibration_id})"
            ),
            "valid" if reading.valid else f"INVALID: {reading.note}",
        ],
    )
    return 0 if reading.valid else 1


def _add_grid_decode(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "decode laser-grid sensor numbers into the end-effector position (mm)")
    parser.add_argument("--horizontal", type=int, nargs="*", default=[], metavar="N", help="horizontal-screen hits")
    parser.add_argument("--vertical", type=int, nargs="*", default=[], metavar="N", help="vertical-screen hits")
    parser.add_argument(
        "--prior-mm",
        type=float,
        nargs=3,
        required=True,
        metavar=("X", "Y", "Z"),
        help="expected end-effector centre (command or FK of the pots)",
    )
    parser.add_argument("--spot-half-width-mm", type=float, default=1.0)
    parser.set_defaults(handler=_grid_decode)


def _grid_decode(args: argparse.Namespace) -> int:
    from bench.sensors.lasergrid import GridGeometry, decode_frame

    result = decode_frame(
        GridGeometry(), args.horizontal, args.vertical, args.prior_mm, spot_half_width_mm=args.spot_half_width_mm
    )
    x, y, z = result.position_mm
    screens = {s: getattr(result, s) for s in ("horizontal", "vertical")}
    out = {
        "x_mm": x,
        "y_mm": y,
        "z_mm": z,
        "measured": list(result.measured),
        "misaligned": result.misaligned,
        **{f"{k}_status": v.status.value for k, v in screens.items()},
        **{f"{k}_lasers": list(v.lasers) for k, v in screens.items()},
    }
    lines = [f"position = ({x:.2f}, {y:.2f}, {z:.2f}) mm, measured axes {result.measured}"]
    lines += [f"{k}: {v.status.value} {' '.join(v.lasers)} {v.reason}".rstrip() for k, v in screens.items()]
    emit(out, args.json, lines)
    return 0


def _add_tilt(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "tilt from two calliper depths, with the play-bias correction (degrees)")
    parser.add_argument("--h1-mm", type=float, required=True, help="depth at hole 1")
    parser.add_argument("--h2-mm", type=float, required=True, help="depth at hole 2")
    parser.add_argument("--spacing-mm", type=float, required=True, help="hole spacing")
    parser.add_argument("--bias-deg", type=float, default=0.0, help="measured tilt bias to subtract")
    parser.add_argument("--u-h-mm", type=float, default=0.0119, help="standard uncertainty of one depth")
    parser.add_argument("--u-spacing-mm", type=float, default=0.058, help="standard uncertainty of the spacing")
    parser.set_defaults(handler=_tilt)


def _tilt(args: argparse.Namespace) -> int:
    from bench.sensors.calliper import tilt_deg, tilt_uncertainty_deg

    measured = float(tilt_deg(args.h1_mm, args.h2_mm, args.spacing_mm))
    u = tilt_uncertainty_deg(args.h1_mm, args.h2_mm, args.spacing_mm, args.u_h_mm, args.u_spacing_mm)
    corrected = measured - args.bias_deg
    emit(
        {"tilt_measured_deg": measured, "tilt_corrected_deg": corrected, "bias_deg": args.bias_deg, "u_deg": u},
        args.json,
        [
            (
                f"tilt = {corrected:.4f} deg (measured {measured:.4f} deg, bias {args.bias_deg:+.4f} deg), "
                f"u = {u:.4f} deg without the bias uncertainty"
            )
        ],
    )
    return 0


def _add_entry(actions: argparse._SubParsersAction, name: str) -> None:
    parser = _parser(actions, name, "prompted manual calliper entry, each reading appended to a CSV at once")
    parser.add_argument("--out", type=Path, required=True, help="CSV file (appended; created with a header)")
    parser.add_argument("--label", default="reading", help="what is measured (pose, cycle, leg...)")
    parser.add_argument("--count", type=int, default=1, help="number of readings to take")
    parser.add_argument("--expected-mm", type=float, help="plausible value; far entries need confirmation")
    parser.add_argument("--tolerance-mm", type=float, default=2.0)
    parser.add_argument("--min-mm", type=float, default=0.0)
    parser.add_argument("--max-mm", type=float, default=150.0)
    parser.add_argument("--double-entry", action="store_true", help="type each reading twice")
    parser.add_argument("--operator", default="")
    parser.set_defaults(handler=_entry)


def _entry(args: argparse.Namespace) -> int:
    from bench.sensors.calliper import ReadingRequest, prompt_reading

    if args.count < 1:
        raise ConfigError(f"calliper-entry: --count = {args.count}, expected an integer >= 1")
    if not args.out.parent.is_dir():
        raise ConfigError(
            f"calliper-entry: --out {args.out}: folder {args.out.parent} does not exist, expected an existing folder"
        )
    if args.out.is_dir():
        raise ConfigError(f"calliper-entry: --out {args.out}: a folder, expected a CSV file name")
    new_file = not args.out.exists() or args.out.stat().st_size == 0
    with args.out.open("a", newline="") as handle:
        writer = None

        def store(reading) -> None:
            nonlocal writer
            row = reading.as_row()
            if writer is None:
                writer = csv.DictWriter(handle, fieldnames=list(row))
                if new_file:
                    writer.writeheader()
            writer.writerow(row)
            handle.flush()
            os.fsync(handle.fileno())

        for k in range(args.count):
            request = ReadingRequest(
                f"{args.label} #{k + 1}", args.min_mm, args.max_mm, args.expected_mm, args.tolerance_mm
            )
            reading = prompt_reading(request, store, ask=_ask, double_entry=args.double_entry, operator=args.operator)
            print(f"{reading.value:.3f} mm stored in {args.out}", file=sys.stderr)
    emit({"path": str(args.out), "readings": args.count}, args.json, [str(args.out)])
    return 0


def _ask(prompt: str) -> str:
    sys.stderr.write(prompt)
    sys.stderr.flush()
    line = sys.stdin.readline()
    if not line:
        raise ConfigError("calliper-entry: input ended before all readings were entered; entries so far are stored")
    return line.rstrip("\n")
