"""Simulated delta4 controller: ``python -m bench.simulators.delta4`` (or ``bench sim delta4``).

Behaves like the ATmega128 firmware as ``docs/protocol-delta4.md`` specifies it: ``E`` starts control and sensor
reporting, ``G`` stops both, ``P``/``Q``/``R``/``S`` + digits + ``X`` set servo references (stored while stopped),
``T`` is logged and ignored, malformed messages are discarded; ``A`` (this project's pot query) is answered with
the four pot ADC counts of the servos' current angles on :data:`bench.robots.delta4_wire.POT_SCALE` (the pots sit on
the servo shafts inside the servos' own loop, so they see the trajectory, not the error model's terms). Each servo follows the closed-loop target
b/(s + b), b = 4 1/s (reference §6.2.2), in simulated time scaled by ``--speed-factor``; ``z`` is sent once all four
are within one ADC count (140/255 deg) for 10 ticks of 2 ms. The attained pose then comes from the seeded error
model and :mod:`motion.delta4` forward kinematics and goes to the truth log. Sensor reports (one per 80 ms frame,
horizontal screen first) come from a pluggable ``sensor(pose_mm) -> (horizontal, vertical)`` observing that true
attained pose. The program attaches the laser-grid simulator
(:class:`bench.simulators.lasergrid.LaserGridSimulator`: default GUI screen geometry, spot half-width
``--grid-spot-half-width-mm`` 1.0 mm, Appendix D2 miss probability by height unless ``--grid-p-miss`` is given,
``--grid-p-false`` stray hits, its own random stream derived from ``--seed``); ``--no-grid`` reports no hit in
every frame (``h`` then ``v``), as a controller with its screens unplugged.

``--true-geometry-seed SEED`` moves the robot by a seeded TRUE geometry
(:func:`bench.simulators.true_geometry.delta4_true_deviations`: servo zeros, arm lengths, servo axis positions)
through :func:`motion.delta4.calibration.attained_positions` (the four closures best met), instead of the error
model's geometric stand-ins (joint offset and scale, pose gain and bias, then zeroed); the truth log's poses are that
geometry's. ``--camera FIFO`` attaches a simulated camera watching the laser spot of the true pose
(:class:`bench.simulators.camera_feed.CameraFeed`), read by the host as a video stream.
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
import math
import sys
from collections.abc import Callable
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.robots import delta4_wire as wire
from bench.robots.delta4 import HOME_MM
from bench.simulators.error_model import ErrorMagnitudes, ErrorModel
from bench.simulators.plant import Plant
from bench.simulators.pty import TruthLog, add_common_arguments, main_for

__all__ = [
    "DELTA4_ERRORS",
    "DESCRIPTION",
    "Delta4SimDevice",
    "add_arguments",
    "build_device",
    "build_grid_sensor",
    "build_plant",
    "grid_seed",
    "main",
]

_log = logging.getLogger(__name__)

DESCRIPTION = "Simulated delta4 (ATmega128) controller on a pseudo-terminal (prints the device path)."
BANDWIDTH_PER_S = 4.0
ADC_DEG_PER_COUNT = 140.0 / 255.0
SETTLE_HOLD_S = 10 * 0.002
FRAME_PERIOD_S = 0.080
#: Second entropy word of the laser grid's random stream (the first is ``--seed``).
GRID_STREAM = 0x4C47

#: Error sizes giving axial errors of 2-3 mm and spatial errors up to about 4 mm (reference §7.2); joint units deg.
DELTA4_ERRORS = ErrorMagnitudes(
    scale_sigma=0.004,
    offset_sigma=0.35,
    backlash=0.6,
    noise_sigma=ADC_DEG_PER_COUNT / math.sqrt(3),
    sag_per_kg=0.15,
    pose_gain_sigma=0.004,
    pose_play_sigma=(0.6, 0.6, 0.6),
    pose_sag_per_kg=(0.0, 0.0, -0.8),
    pose_offset_sigma=(0.3, 0.3, 0.3),
)

Sensor = Callable[[np.ndarray], tuple[tuple[int, ...], tuple[int, ...]]]


def _no_hit(_: np.ndarray) -> tuple[tuple[int, ...], tuple[int, ...]]:
    return (), ()


class Delta4SimDevice:
    """The firmware state machine over simulated servos; ``plant(servo_deg, load_kg) -> (x, y, z) mm``. Fine
    references as the firmware: ``C`` answered with its step, ``F<n><ddddd>X`` on its PWM tick (0.01125 deg)."""

    def __init__(
        self,
        plant: Any,
        mapping: wire.ServoMapping,
        *,
        speed_factor: float = 1.0,
        truth: TruthLog | None = None,
        load_kg: float = 0.0,
        sensor: Sensor | None = None,
        home_servo_deg: np.ndarray | None = None,
    ) -> None:
        self.plant = plant
        self.mapping = mapping
        self.speed_factor = speed_factor
        self.truth = truth or TruthLog(None, ("x_mm", "y_mm", "z_mm"))
        self.load_kg = load_kg
        self.sensor = sensor or _no_hit
        home = np.full(4, 71.66) if home_servo_deg is None else np.asarray(home_servo_deg, dtype=float)
        self.angle_deg = home.copy()  # where the servos are at t0
        self.target_deg = home.copy()
        self.references = mapping.to_bytes(home)
        # the angle each servo is sent to: its byte's, or its fine reference's
        self.reference_deg = mapping.to_deg(self.references.astype(float))
        self.t0_s = 0.0
        self.started = False
        self.settle_at_s: float | None = None
        self.true_pose = np.asarray(plant(self.target_deg, load_kg), dtype=float)
        self._next_frame_s = 0.0
        self._letter: int | None = None
        self._digits = bytearray()
        self._stored_while_stopped = False
        self._pots_asked = 0
        self.camera: Any = None  #: a :class:`bench.simulators.camera_feed.CameraFeed`, or None
        self._capability_asked = 0

    # -- bytes in ----------------------------------------------------------------------------------------------
    def feed(self, data: bytes, now_s: float) -> bytes:
        out = self.tick(now_s)
        for byte in data:
            self._byte(byte, now_s)
        for _ in range(self._pots_asked):  # after any report, as the firmware answers from its main loop
            out += self._pot_reply(now_s)
        out += wire.format_capability_reply(wire.FineReference().controller_step_deg) * self._capability_asked
        self._pots_asked = self._capability_asked = 0
        return out

    def _byte(self, byte: int, now_s: float) -> None:
        if self._letter is not None:
            fine = self._letter == wire.FINE_LETTER[0]  # F<servo 1-4><1-5 digits, 0.01 deg>X
            if 0x30 <= byte <= 0x39 and len(self._digits) < (6 if fine else 3):
                self._digits.append(byte)
                return
            if (
                byte == ord("X")
                and fine
                and len(self._digits) >= 2
                and 0x31 <= self._digits[0] <= 0x34
                and int(self._digits[1:]) <= 18000
            ):
                self._reference(self._digits[0] - 0x31, None, now_s, wire.FineReference().to_deg(int(self._digits[1:])))
                self._letter = None
                return
            if byte == ord("X") and not fine and self._digits and int(self._digits) <= 255:
                self._reference(wire.SERVO_LETTERS.index(self._letter), int(self._digits), now_s)
                self._letter = None
                return
            _log.info("discarded malformed message %r", bytes([self._letter]) + bytes(self._digits) + bytes([byte]))
            self._letter = None
            if 0x30 <= byte <= 0x39 or byte == ord("X"):
                return
        if byte in wire.SERVO_LETTERS or byte == wire.FINE_LETTER[0]:
            self._letter, self._digits = byte, bytearray()
        elif byte == wire.CAPABILITY_QUERY[0]:
            self._capability_asked += 1
        elif byte == ord("E"):
            self._start(now_s)
        elif byte == ord("G"):
            self._hold(now_s)
            self.started = False
        elif byte == wire.POT_QUERY[0]:
            self._pots_asked += 1
        elif byte == ord("T"):
            _log.info("received T (undocumented command): ignored")
        elif byte != ord("z"):  # z is the PC's acknowledgement
            _log.info("ignored byte %r", bytes([byte]))

    def _start(self, now_s: float) -> None:
        if not self.started:
            self.started = True
            self._hold(now_s)
            self._next_frame_s = now_s
            if self._stored_while_stopped:  # 'z' follows servo commands only (§5.7 items 7 and 10)
                self._retarget(now_s)
            self._stored_while_stopped = False

    def _reference(self, servo: int, value: int | None, now_s: float, fine_deg: float | None = None) -> None:
        if value is not None:
            self.references[servo] = value
        self.reference_deg[servo] = (
            self.mapping.to_deg(self.references.astype(float))[servo] if fine_deg is None else fine_deg
        )
        self._stored_while_stopped = not self.started
        if self.started:
            self._hold(now_s)
            self._retarget(now_s)

    def _hold(self, now_s: float) -> None:
        """Freeze the servo trajectories at ``now_s`` as the new starting angles."""
        self.angle_deg = self._angles(now_s)
        self.t0_s = now_s

    def _retarget(self, now_s: float) -> None:
        self.target_deg = self.reference_deg.copy()
        worst = float(np.max(np.abs(self.angle_deg - self.target_deg)))
        rise_s = math.log(worst / ADC_DEG_PER_COUNT) / BANDWIDTH_PER_S if worst > ADC_DEG_PER_COUNT else 0.0
        self.settle_at_s = now_s + (rise_s + SETTLE_HOLD_S) / self.speed_factor

    def _angles(self, now_s: float) -> np.ndarray:
        if not self.started:
            return self.angle_deg
        decay = math.exp(-BANDWIDTH_PER_S * max(0.0, now_s - self.t0_s) * self.speed_factor)
        return self.target_deg + (self.angle_deg - self.target_deg) * decay

    def idle(self, now_s: float) -> None:
        """Between turns of the event loop: the attached camera (if any) streams frames of the true pose."""
        if self.camera is not None:
            self.camera.stream(self.true_pose)

    # -- bytes out ---------------------------------------------------------------------------------------------
    def _pot_reply(self, now_s: float) -> bytes:
        return wire.format_pot_reply(wire.POT_SCALE.to_bytes(self._angles(now_s)))

    def tick(self, now_s: float) -> bytes:
        out = bytearray()
        if not self.started:
            return b""
        if self.settle_at_s is not None and now_s >= self.settle_at_s:
            self.settle_at_s = None
            self.true_pose = np.asarray(self.plant(self.target_deg, self.load_kg), dtype=float)
            self.truth.record(list(self.target_deg), list(self.true_pose), self.load_kg)
            out += b"z"
        if now_s >= self._next_frame_s:
            self._next_frame_s = max(self._next_frame_s + FRAME_PERIOD_S, now_s)
            out += self._report()
        return bytes(out)

    def _report(self) -> bytes:
        horizontal, vertical = self.sensor(self.true_pose)
        report = b"".join(b"H%03dX" % i for i in horizontal) if horizontal else b"h"
        return report + (b"".join(b"V%03dX" % i for i in vertical) if vertical else b"v")


def build_plant(
    seed: int, *, ideal: bool = False, geometry: Any = None, true_deviations: dict[str, float] | None = None
) -> tuple[Plant, np.ndarray]:
    """The seeded delta4 plant and the servo angles of the home point (0, 0, -150) mm (by the documented IK).

    With ``true_deviations`` (names of :data:`motion.delta4.calibration.PARAMETERS` -> deg or mm, e.g.
    :func:`bench.simulators.true_geometry.delta4_true_deviations`) the robot stands where the four legs of that
    geometry close best (:func:`motion.delta4.calibration.attained_positions`), and the error model's stand-ins for
    geometry (joint offset and scale, pose gain and bias) are zeroed; backlash, noise, sag and play stay."""
    from motion import delta4
    from motion.delta4.calibration import attained_positions

    geometry = geometry or delta4.NOMINAL

    def forward(servo_deg: np.ndarray, _commanded: np.ndarray, _previous: np.ndarray | None) -> np.ndarray | None:
        if true_deviations is not None:
            pose = attained_positions(
                servo_deg.reshape(1, 4), tuple(true_deviations), tuple(true_deviations.values()), geometry
            )[0]
            return pose if bool(np.all(np.isfinite(pose))) else None
        result = delta4.forward_kinematics(servo_deg.reshape(1, 4), geometry)
        return result.pose_mm[0] if bool(result.ok[0]) else None

    model = ErrorModel.ideal(4, 3) if ideal else ErrorModel.draw(DELTA4_ERRORS, 4, seed, joint_zero=100.0)
    if true_deviations is not None:
        model = dataclasses.replace(
            model, offset=np.zeros(4), scale=np.zeros(4), pose_gain=np.zeros((3, 3)), pose_offset=np.zeros(3)
        )
    home = delta4.inverse_kinematics(np.array([HOME_MM]), geometry).servo_deg[0]
    return Plant(lambda q: q, forward, model, np.array(HOME_MM), seed), home


def grid_seed(seed: int) -> int:
    """The laser grid's own seed: a stream independent of the error model's, reproducible from ``--seed``."""
    return int(np.random.SeedSequence((seed, GRID_STREAM)).generate_state(1)[0])


def build_grid_sensor(args: argparse.Namespace) -> Sensor | None:
    """The laser-grid simulator the command line asks for (``None`` with ``--no-grid``)."""
    from bench.simulators.lasergrid import LaserGridSimulator

    if args.no_grid:
        return None
    checks = (
        ("--grid-p-miss", args.grid_p_miss, 0.0 <= (args.grid_p_miss or 0.0) <= 1.0, "in [0, 1]"),
        ("--grid-p-false", args.grid_p_false, 0.0 <= args.grid_p_false <= 1.0, "in [0, 1]"),
        (
            "--grid-spot-half-width-mm",
            args.grid_spot_half_width_mm,
            0.0 < args.grid_spot_half_width_mm < 5.0,
            "in (0, 5) mm, below half the 10 mm pitch",
        ),
    )
    for option, value, ok, expected in checks:
        if not ok:
            raise ConfigError(f"{option} = {value!r}, expected a number {expected}")
    by_distance = args.grid_p_miss is None
    return LaserGridSimulator(
        spot_half_width_mm=args.grid_spot_half_width_mm,
        p_miss=0.0 if by_distance else args.grid_p_miss,
        p_miss_by_distance=by_distance,
        p_false=args.grid_p_false,
        seed=grid_seed(args.seed),
    ).observer()


def build_device(args: argparse.Namespace) -> Delta4SimDevice:
    """The simulated controller described by the command-line ``args``."""
    true_seed = getattr(args, "true_geometry_seed", None)
    deviations = None
    if true_seed is not None:
        from bench.simulators.true_geometry import delta4_true_deviations

        deviations = delta4_true_deviations(true_seed)
        _log.info("true geometry (seed %d): %s", true_seed, deviations)
    plant, home = build_plant(args.seed, ideal=args.ideal, true_deviations=deviations)
    truth = TruthLog(args.truth, ("x_mm", "y_mm", "z_mm"))
    mapping = wire.MAPPINGS[args.mapping]()
    device = Delta4SimDevice(
        plant,
        mapping,
        speed_factor=args.speed_factor,
        truth=truth,
        load_kg=args.load_kg,
        home_servo_deg=home,
        sensor=build_grid_sensor(args),
    )
    if getattr(args, "camera", None):
        from bench.simulators.camera_feed import CameraFeed

        device.camera = CameraFeed(args.camera, seed=args.seed)
    return device


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``bench sim delta4`` / ``python -m bench.simulators.delta4``."""
    add_common_arguments(parser)
    parser.add_argument(
        "--mapping",
        choices=sorted(wire.MAPPINGS),
        default="legacy_vb",
        help="servo byte <-> angle mapping the firmware uses (must match the driver)",
    )
    parser.add_argument(
        "--no-grid", action="store_true", help="no laser-grid simulator: every sensor report is 'h' 'v' (no hit)"
    )
    parser.add_argument(
        "--grid-spot-half-width-mm",
        type=float,
        default=1.0,
        help="half-width r of a phototransistor's detection window, mm (reference §4.10)",
    )
    parser.add_argument(
        "--grid-p-miss",
        type=float,
        default=None,
        help="probability of losing each hit (default: Appendix D2 values by height)",
    )
    parser.add_argument(
        "--grid-p-false", type=float, default=0.0, help="probability of one stray lit sensor per screen and frame"
    )
    parser.add_argument(
        "--true-geometry-seed",
        type=int,
        default=None,
        metavar="SEED",
        help="move by a seeded perturbed geometry (bench.simulators.true_geometry) instead of the "
        "error model's geometric stand-ins",
    )
    parser.add_argument(
        "--camera",
        default=None,
        metavar="FIFO",
        help="a simulated camera watching the laser spot of the true pose, streamed as YUV4MPEG2 "
        "video into this FIFO (bench.simulators.camera_feed)",
    )


def main(argv: list[str] | None = None) -> int:
    return main_for(build_device, add_arguments, DESCRIPTION, argv)


if __name__ == "__main__":
    sys.exit(main())
