"""ISO 9283 clause 8 path protocols for the pkm5: path accuracy/repeatability AT/RT (8.2, 8.3), path velocity
AV/RV/FV (8.6) on a straight line or a circle, and cornering CR/CO (8.5) on a rectangle.

Spec: ``shared/reference/iso9283.md`` §6.10-6.14: 10 cycles for AT/RT and path velocity, 3 for cornering [N]; 100,
50 and 10 % of the rated path velocity [U]; the paths in the test plane of the cube (`path_geometry`). The firmware
moves its legs linearly in joint space, so the path is cut into segments whose joint-space chord error stays at most
``chord_error_mm`` (default 0.01 mm); every segment end is pre-flighted (reachability, joint limits, singularity
proximity) when the protocol is loaded and again by the runner's pre-flight, like any Move target.

Each segment is one Move at the leg speed that gives the commanded path velocity on that segment (the firmware's
integer steps/s, so the commanded speed is met to within 0.5 step/s), followed at once by a capture of kind
``path``: the instrument's streamed position over the segment's move (``lead_s`` = the segment's duration,
``hold_s`` = 0; the last segment of a cycle holds ``final_hold_s`` so the arrival is recorded). The sample's commanded
columns are the segment's end, ``velocity_pct`` the path velocity in % of the rated one; the analysis
(`bench.reports.path_run`) joins a cycle's segments by their start times. ``path_speed_mm_s = 0`` takes as rated
path velocity the largest speed the pkm5 holds on every segment of the path at its rated leg speed [choice].
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.metrology.documents import ISO9283_VELOCITIES_PCT
from bench.metrology.path_geometry import CommandedPath, Segmentation, commanded_path, segment_path
from bench.protocols.base import Protocol, register
from bench.protocols.iso9283 import _PLANES, cube_poses, fit_cube_side
from bench.protocols.kinematics import robot_model
from bench.protocols.parameters import ChoiceParameter, FloatListParameter, FloatParameter, IntegerParameter
from bench.rigs.mice import PATH as PATH_KIND
from bench.steps import Capture, Checkpoint, Move, Payload, Plan, Settle, commanded_values

__all__ = ["Cornering", "PathAccuracy", "PathProtocol"]


class PathProtocol(Protocol):
    """Shared parameters and plan of the path protocols; subclasses fix the shapes and the cycle count."""

    robots = ("pkm5",)
    shapes: tuple[str, ...] = ("line", "circle")

    velocities_pct = FloatListParameter(
        ISO9283_VELOCITIES_PCT,
        unit="%",
        minimum=0.1,
        maximum=100.0,
        description="path velocities, % of the rated path velocity (ISO 6.7)",
    )
    path_speed_mm_s = FloatParameter(
        0.0,
        unit="mm/s",
        minimum=0.0,
        maximum=100.0,
        description="rated path velocity (100 %); 0 = the largest the robot holds on "
        "every segment at its rated leg speed",
    )
    load_kg = FloatParameter(0.0, unit="kg", minimum=0.0, maximum=30.0, description="payload (ISO 6.6: rated)")
    cube_centre_mm = FloatListParameter((110.0, 0.0, 320.0), length=3, unit="mm", description="centre P1 of the cube")
    cube_side_mm = FloatParameter(
        0.0,
        unit="mm",
        minimum=0.0,
        maximum=1000.0,
        description="edge of the test cube; 0 = the largest that fits the workspace",
    )
    plane = ChoiceParameter("x=z", choices=tuple(_PLANES), description="diagonal plane of the cube: the test plane")
    chord_error_mm = FloatParameter(
        0.01,
        unit="mm",
        minimum=0.0001,
        maximum=1.0,
        description="bound on the joint-space chord error of every segment",
    )
    max_segment_mm = FloatParameter(
        4.0, unit="mm", minimum=0.1, maximum=100.0, description="longest segment before the chord error is checked"
    )
    settle_s = FloatParameter(
        1.0,
        unit="s",
        minimum=0.0,
        maximum=600.0,
        description="dwell at the path's start before each cycle (the robot starts at rest)",
    )
    final_hold_s = FloatParameter(
        1.0,
        unit="s",
        minimum=0.0,
        maximum=60.0,
        description="streamed time after the last segment of a cycle (the arrival)",
    )

    def validate(self) -> None:
        if self.robot != "pkm5":  # the segmentation is the pkm5's (joint-linear legs)
            raise ConfigError(f"{self.source}: robot = {self.robot!r}, expected pkm5 for protocol {self.name!r}")
        self._side_mm = self.cube_side_mm or fit_cube_side(self.robot, self.cube_centre_mm)
        if self._side_mm <= 0:
            raise ConfigError(
                f"{self.source}: cube_centre_mm = {list(self.cube_centre_mm)}, expected a centre "
                f"inside the {self.robot} workspace (no cube fits around it)"
            )
        model = robot_model(self.robot)
        for shape in self.shapes:
            targets = model.as_targets([tuple(p) for p in self.segmentation(shape).targets_mm])
            check = model.check(targets, self.min_inverse_condition)
            if not check.reachable.all():
                bad = int(np.flatnonzero(~check.reachable)[0])
                raise ConfigError(
                    f"{self.source}: {shape} path point "
                    f"({', '.join(f'{v:.2f}' for v in targets[bad][:3])}) mm: {check.reason[bad]}"
                )
        if self.path_speed_mm_s > self.rated_limit_mm_s:
            raise ConfigError(
                f"{self.source}: path_speed_mm_s = {self.path_speed_mm_s:g}, expected at most "
                f"{self.rated_limit_mm_s:g} mm/s (the rated leg speed on the slowest segment)"
            )

    @cached_property
    def poses(self) -> dict[str, tuple[float, ...]]:
        return cube_poses(self.cube_centre_mm, self._side_mm, self.plane)

    def path(self, shape: str) -> CommandedPath:
        """The commanded path of ``shape`` (`path_geometry.commanded_path`)."""
        return commanded_path(shape, self.poses)

    def segmentation(self, shape: str) -> Segmentation:
        cache = self.__dict__.setdefault("_segmentations", {})
        if shape not in cache:
            cache[shape] = segment_path(
                self.path(shape),
                robot_model(self.robot).kinematics,
                max_segment_mm=self.max_segment_mm,
                chord_error_mm=self.chord_error_mm,
            )
        return cache[shape]

    def _segment_steps(self, shape: str) -> tuple[np.ndarray, np.ndarray]:
        """Per segment: its length (mm) and the steps of its longest-travelling leg."""
        kinematics = robot_model(self.robot).kinematics
        seg = self.segmentation(shape)
        lengths = np.linalg.norm(np.diff(seg.targets_mm, axis=0), axis=1)
        steps = np.max(np.abs(np.diff(seg.joints, axis=0)) / kinematics.geometry.mm_per_step, axis=1)
        return lengths, np.maximum(np.rint(steps), 1.0)

    @cached_property
    def rated_limit_mm_s(self) -> float:
        """The largest path velocity every segment holds at the rated leg speed, mm/s (0.01 mm/s resolution)."""
        rated = robot_model(self.robot).kinematics.geometry.max_speed_steps_per_s
        limit = min(
            float(np.min(length * rated / steps)) for length, steps in (self._segment_steps(s) for s in self.shapes)
        )
        return float(np.floor(limit * 100) / 100)

    @property
    def rated_mm_s(self) -> float:
        """The rated path velocity (100 %), mm/s."""
        return self.path_speed_mm_s or self.rated_limit_mm_s

    def resolved(self) -> dict[str, Any]:
        out = super().resolved()
        out["cube_side_mm"] = self.cube_side_mm or getattr(self, "_side_mm", 0.0)
        return out

    #: What the report reads of the design, stored with the run (the analysis needs no protocol code): per shape
    #: the commanded path and its segment targets, and the rated path velocity the percentages refer to.
    design_keys = ("paths", "rated_path_speed_mm_s")

    def config(self) -> dict[str, Any]:
        paths = []  # a list: the order driven (a stored mapping's keys come back sorted)
        for shape in self.shapes:
            path, segmentation = self.path(shape), self.segmentation(shape)
            paths.append(
                {
                    "shape": shape,
                    "vertices_mm": path.vertices_mm.tolist(),
                    "centre_mm": path.centre_mm.tolist(),
                    "radius_mm": path.radius_mm,
                    "u": path.u.tolist(),
                    "v": path.v.tolist(),
                    "segment_targets_mm": segmentation.targets_mm.tolist(),
                    "max_chord_error_mm": segmentation.chord_error_mm,
                }
            )
        return {**super().config(), "paths": paths, "rated_path_speed_mm_s": self.rated_mm_s}

    def segment_plan(self, shape: str, velocity_pct: float) -> list[tuple[tuple[float, ...], float, float]]:
        """Per segment: its end target, the Move's velocity (% of the rated leg speed), its duration (s)."""
        rated = robot_model(self.robot).kinematics.geometry.max_speed_steps_per_s
        lengths, steps = self._segment_steps(shape)
        speed_mm_s = self.rated_mm_s * velocity_pct / 100.0
        steps_per_s = np.clip(np.rint(steps * speed_mm_s / lengths), 1, rated)
        ends = self.segmentation(shape).targets_mm[1:]
        return [
            (tuple(float(v) for v in end), float(sps / rated * 100.0), float(n / sps))
            for end, sps, n in zip(ends, steps_per_s, steps)
        ]

    def steps(self) -> Plan:
        yield from Payload().mount(self.load_kg)  # the samples are labelled with it: the operator confirms it is on
        for shape in self.shapes:
            seg = self.segmentation(shape)
            start = tuple(float(v) for v in seg.targets_mm[0])
            for velocity in self.velocities_pct:
                plan = self.segment_plan(shape, velocity)
                yield Move(start, 100.0, f"{shape} start")
                for cycle in range(1, self.cycles + 1):
                    if self.settle_s > 0:
                        yield Settle(self.settle_s)
                    for number, (end, move_pct, duration_s) in enumerate(plan, start=1):
                        yield Move(end, move_pct, f"{shape} {number}")
                        hold = self.final_hold_s if number == len(plan) else 0.0
                        yield Capture(
                            shape,
                            cycle,
                            kind=PATH_KIND,
                            commanded=commanded_values(end),
                            conditions={
                                "velocity_pct": velocity,
                                "load_kg": self.load_kg,
                                "lead_s": round(duration_s, 3),
                                "hold_s": hold,
                            },
                        )
                    if not self.path(shape).closed:  # back to the start along the pre-flighted targets
                        for back in seg.targets_mm[-2::-1]:
                            yield Move(tuple(float(v) for v in back), 100.0, f"{shape} return")
                    yield Checkpoint(f"{shape}, {velocity:g} %, cycle {cycle}")

    def final_steps(self) -> Plan:
        yield from self.return_home()


@register
class PathAccuracy(PathProtocol):
    """ISO 9283 8.2, 8.3, 8.6: AT/RT on a straight line and a circle, AV/RV/FV on the line, 10 cycles."""

    name = "iso9283_path"
    version = "2"  # 2: a load's confirmation is the first step (the step indices after it moved by one)
    title = "ISO 9283 path accuracy and repeatability, path velocity (8.2, 8.3, 8.6)"
    shapes = ("line", "circle")
    cycles = IntegerParameter(10, minimum=2, description="cycles per path and velocity (ISO Table 5: 10)")
    shape = ChoiceParameter("both", choices=("both", "line", "circle"), description="the paths driven")

    def validate(self) -> None:
        self.shapes = ("line", "circle") if self.shape == "both" else (self.shape,)
        super().validate()


@register
class Cornering(PathProtocol):
    """ISO 9283 8.5: cornering round-off CR and overshoot CO on a rectangle with sharp corners, 3 cycles."""

    name = "iso9283_cornering"
    version = "2"  # 2: a load's confirmation is the first step (the step indices after it moved by one)
    title = "ISO 9283 cornering deviations (8.5)"
    shapes = ("rectangle",)
    cycles = IntegerParameter(3, minimum=2, description="cycles per velocity (ISO Table 5: 3)")
