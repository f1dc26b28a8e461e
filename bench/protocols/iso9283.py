"""ISO 9283 pose protocols: accuracy and repeatability (AP/RP), distance (AD/RD), multi-directional (vAP), drift,
stabilisation time and overshoot (from a streamed arrival).

Spec: ``shared/reference/iso9283.md`` §4-5. The test cube is centred where the robot works most and sized to the
workspace: with ``cube_side_mm = 0`` the largest cube around ``cube_centre_mm`` whose 27 lattice points (corners,
edge and face centres) pass the pre-flight is used. P1 is the centre; P2-P5 lie on the diagonals of the chosen
diagonal plane at 10 % of the diagonal from the corners, i.e. at (+/-0.4 L, +/-0.4 L, +/-0.4 L) from P1, with P2 and
P4 on one diagonal (the distance pair) and P3 and P5 on the other [U: clause 6.8 unchecked]. Where a cube does not
fit, ``poses`` gives a documented plane or grid of labelled poses instead. Cycle order: P1 -> P5 -> P4 -> P3 -> P2,
unidirectional, 30 cycles, at 100/50/10 % velocity, with an optional second load; a Checkpoint closes every cycle.
"""

from __future__ import annotations

import functools
import itertools
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.metrology.documents import ISO9283_CYCLES, ISO9283_POSE_ORDER, ISO9283_VELOCITIES_PCT
from bench.protocols.base import Protocol, register
from bench.protocols.kinematics import DEFAULT_SINGULARITY_THRESHOLD, robot_model
from bench.protocols.parameters import (
    ChoiceParameter,
    FloatListParameter,
    FloatParameter,
    IntegerParameter,
    PoseTableParameter,
)
from bench.steps import Capture, Checkpoint, Move, Payload, Plan, Settle, commanded_values, visit

__all__ = [
    "DistanceAccuracy",
    "Drift",
    "MultiDirectional",
    "PoseAccuracy",
    "StabilisationOvershoot",
    "cube_poses",
    "fit_cube_side",
]

#: Sign patterns of P2..P5 on each diagonal plane (cube coordinates); P2/P4 and P3/P5 are opposite corners.
_PLANES = {
    "x=z": [(-1, -1, -1), (-1, 1, -1), (1, 1, 1), (1, -1, 1)],
    "x=-z": [(-1, -1, 1), (-1, 1, 1), (1, 1, -1), (1, -1, -1)],
    "y=z": [(-1, -1, -1), (1, -1, -1), (1, 1, 1), (-1, 1, 1)],
    "y=-z": [(-1, -1, 1), (1, -1, 1), (1, 1, -1), (-1, 1, -1)],
}
#: ISO order within a cycle, starting at P1 (iso9283.md §5.4).
POSE_ORDER = ISO9283_POSE_ORDER


def cube_poses(centre_mm, side_mm: float, plane: str = "x=z", angles_deg=()) -> dict[str, tuple[float, ...]]:
    """P1-P5 of an ISO cube of edge ``side_mm`` centred at ``centre_mm`` (iso9283.md §5.3: P = P1 + 0.8 (C - P1)).

    Examples
    --------
    >>> cube_poses((100, 0, 300), 50)["P4"]
    (120.0, 20.0, 320.0)
    """
    centre = np.asarray(centre_mm, dtype=float)
    poses = {"P1": tuple(centre.tolist()) + tuple(angles_deg)}
    for label, signs in zip(("P2", "P3", "P4", "P5"), _PLANES[plane]):
        point = centre + 0.4 * side_mm * np.asarray(signs, dtype=float)
        poses[label] = tuple(float(v) for v in point) + tuple(angles_deg)
    return poses


def fit_cube_side(
    robot: str,
    centre_mm,
    *,
    max_side_mm: float = 200.0,
    angles_deg=(),
    threshold: float = DEFAULT_SINGULARITY_THRESHOLD,
) -> float:
    """Edge (mm, 0.1 mm resolution) of the largest cube around ``centre_mm`` whose 27 lattice points all pass the
    pre-flight of ``robot`` (bisection; the reachable set is assumed star-shaped about the centre)."""
    return _fit_cube_side(
        robot,
        tuple(float(v) for v in centre_mm),
        float(max_side_mm),
        tuple(float(v) for v in angles_deg),
        float(threshold),
    )


@functools.lru_cache(maxsize=64)
def _fit_cube_side(
    robot: str, centre_mm: tuple[float, ...], max_side_mm: float, angles_deg: tuple[float, ...], threshold: float
) -> float:
    """:func:`fit_cube_side`, remembered: the pre-flight models are fixed, and every cube protocol built asks
    (0.02 s of bisection; the desktop window's form builds one on every edit)."""
    model = robot_model(robot)
    lattice = np.array(list(itertools.product((-0.5, 0.0, 0.5), repeat=3)))

    def fits(side: float) -> bool:
        points = np.asarray(centre_mm, float) + side * lattice
        targets = model.as_targets([tuple(p) + tuple(angles_deg) for p in points])
        return bool(model.check(targets, threshold).reachable.all())

    if not fits(0.0):
        return 0.0
    low, high = 0.0, max_side_mm
    if fits(high):
        return high
    while high - low > 0.1:
        mid = (low + high) / 2
        low, high = (mid, high) if fits(mid) else (low, mid)
    return round(low, 1)


class _CubeProtocol(Protocol):
    """Shared parameters: the robot, the cube or explicit poses, velocities, loads, cycles and settling."""

    cycles = IntegerParameter(ISO9283_CYCLES, minimum=2, description="cycles per pose (ISO Table 5: 30)")
    velocities_pct = FloatListParameter(
        ISO9283_VELOCITIES_PCT,
        unit="%",
        minimum=0.1,
        maximum=100.0,
        description="test velocities, % of rated (ISO 6.7: 100, 50, 10)",
    )
    loads_kg = FloatListParameter(
        (0.0,), unit="kg", minimum=0.0, maximum=30.0, description="loads, kg (ISO 6.6: 100 % rated, optionally 10 %)"
    )
    cube_centre_mm = FloatListParameter(
        (110.0, 0.0, 320.0),
        length=3,
        unit="mm",
        description="centre of the test cube (P1), mm; the default holds the "
        "largest pkm5 cube found by a grid search (40 mm)",
    )
    cube_side_mm = FloatParameter(
        0.0,
        unit="mm",
        minimum=0.0,
        maximum=1000.0,
        description="edge of the test cube; 0 = the largest that fits the workspace",
    )
    plane = ChoiceParameter("x=z", choices=tuple(_PLANES), description="diagonal plane of P2-P5 (cube frame)")
    poses = PoseTableParameter(None, description="explicit labelled poses instead of the cube (plane or grid)")
    settle_s = FloatParameter(1.0, unit="s", minimum=0.0, maximum=600.0, description="dwell before each capture")

    def validate(self) -> None:
        if self.poses is None:
            self._side_mm = self.cube_side_mm or fit_cube_side(self.robot, self.cube_centre_mm)
            if self._side_mm <= 0:
                raise ConfigError(
                    f"{self.source}: cube_centre_mm = {list(self.cube_centre_mm)}, expected a centre "
                    f"inside the {self.robot} workspace (no cube fits around it)"
                )
            self._poses = cube_poses(self.cube_centre_mm, self._side_mm, self.plane)
        else:
            width = len(robot_model(self.robot).target_fields)
            for label, pose in self.poses.items():
                if len(pose) > width:
                    raise ConfigError(
                        f"{self.source}: poses.{label} = {list(pose)}, expected at most {width} "
                        f"numbers for the {self.robot}"
                    )
            self._poses = dict(self.poses)

    def resolved(self) -> dict[str, Any]:
        out = super().resolved()
        out["cube_side_mm"] = self.cube_side_mm or getattr(self, "_side_mm", 0.0)
        return out

    def test_poses(self) -> dict[str, tuple[float, ...]]:
        """The labelled command poses (mm, degrees) this protocol visits."""
        return dict(self._poses)

    def _iso_order(self) -> list[str]:
        """The cube's poses in ISO cycle order, or the explicit poses in file order."""
        return [p for p in POSE_ORDER if p in self._poses] if self.poses is None else list(self._poses)

    def _cycles(self, order: list[str]) -> Plan:
        """Per load (confirmed by the operator), per velocity: ``cycles`` visits of ``order`` (each by
        :meth:`_visit`), a Checkpoint after each cycle."""
        payload = Payload()
        for load in self.loads_kg:
            yield from payload.mount(load)
            for velocity in self.velocities_pct:
                for cycle in range(1, self.cycles + 1):
                    for label in order:
                        yield from self._visit(label, self._poses[label], cycle, velocity, load)
                    yield Checkpoint(f"load {load:g} kg, {velocity:g} %, cycle {cycle}")

    def _visit(self, label: str, target: tuple[float, ...], cycle: int, velocity: float, load: float) -> Plan:
        """One visit of a pose: move, settle, capture."""
        yield from visit(
            label, target, cycle, velocity_pct=velocity, settle_s=self.settle_s, conditions={"load_kg": load}
        )

    def final_steps(self) -> Plan:
        yield from self.return_home()

    def _one_load(self) -> Plan:
        """The single load of a protocol that runs at one (validated by :meth:`_validate_one_load`)."""
        yield from Payload().mount(self.loads_kg[0])

    def _validate_one_load(self, clause: str) -> None:
        if len(self.loads_kg) != 1:
            raise ConfigError(
                f"{self.source}: loads_kg = {list(self.loads_kg)}: {self.name} runs at one load "
                f"(ISO 9283 {clause}: rated), expected one value"
            )


#: Fractions of ``approach_from_below_mm`` tried, in turn, for a pose whose pre-pose the pre-flight refuses: a
#: D-optimal calibration pose may hold a leg within 0.14 mm of its window (C11 of examples/kinematic_calibration.toml,
#: which 0.1 mm below passes).
_APPROACH_FRACTIONS = (1.0, 0.5, 0.25, 0.1)


@register
class PoseAccuracy(_CubeProtocol):
    """ISO 9283 7.2: pose accuracy AP and repeatability RP at P1-P5.

    With ``approach_from_below_mm`` > 0 every visit first moves to the pose that far below (z), then up into it. On
    the pkm5 every leg then extends into every pose (a leg lengthens by 0.57-1.0 mm per mm of z over the workspace:
    2,000 reachable poses, the documented geometry), so each leg's backlash is taken up on the same side at every
    arrival and acts as a constant offset, which a kinematic calibration identifies, instead of an error whose sign
    follows the previous pose (docs/calibration.md, "Backlash"). A pose whose pre-pose the pre-flight refuses is
    approached from a half, a quarter, else a tenth of that (``resolved()['approach_mm']`` gives each pose's);
    without any the protocol is refused naming it.
    """

    name = "iso9283_pose"
    version = "1"
    title = "ISO 9283 pose accuracy and repeatability (7.2.1, 7.2.2)"
    approach_from_below_mm = FloatParameter(
        0.0,
        unit="mm",
        minimum=0.0,
        maximum=10.0,
        description="arrive at each pose from this far below it (every pkm5 leg extending into it); 0: directly",
    )

    def validate(self) -> None:
        super().validate()
        self._below_mm = self._approach_drops() if self.approach_from_below_mm else {}

    def _approach_drops(self) -> dict[str, float]:
        """Per pose the largest of ``approach_from_below_mm`` x :data:`_APPROACH_FRACTIONS` whose pre-pose passes
        the pre-flight; ConfigError naming a pose that has none."""
        model = robot_model(self.robot)
        width = len(model.target_fields)
        labels = list(self._poses)
        poses = np.array([list(self._poses[k]) + [0.0] * (width - len(self._poses[k])) for k in labels], dtype=float)
        drops: dict[str, float] = {}
        for fraction in _APPROACH_FRACTIONS:
            drop = self.approach_from_below_mm * fraction
            below = poses - np.eye(width)[2] * drop
            for label, ok in zip(labels, model.check(below).reachable):
                if ok and label not in drops:
                    drops[label] = drop
        missing = [k for k in labels if k not in drops]
        if missing:
            raise ConfigError(
                f"{self.source}: approach_from_below_mm = {self.approach_from_below_mm:g}: poses "
                f"{', '.join(missing)} cannot be approached from below (the pre-pose "
                f"{self.approach_from_below_mm * _APPROACH_FRACTIONS[-1]:g} mm below fails the pre-flight); "
                "expected poses with room below them, or 0 (arrive directly)"
            )
        return drops

    def resolved(self) -> dict[str, Any]:
        out = super().resolved()
        if getattr(self, "_below_mm", None):
            out["approach_mm"] = dict(self._below_mm)
        return out

    def steps(self) -> Plan:
        yield from self._cycles(self._iso_order())

    def _visit(self, label: str, target: tuple[float, ...], cycle: int, velocity: float, load: float) -> Plan:
        """From below (the pre-pose) when asked, then move, settle, capture."""
        if label in self._below_mm:
            below = list(target)
            below[2] -= self._below_mm[label]
            yield Move(tuple(below), velocity, f"{label}/below")
        yield from super()._visit(label, target, cycle, velocity, load)


@register
class DistanceAccuracy(_CubeProtocol):
    """ISO 9283 7.3: distance accuracy AD and repeatability RD between P4 and P2 (starting at P4)."""

    name = "iso9283_distance"
    version = "1"
    title = "ISO 9283 distance accuracy and repeatability (7.3)"

    def steps(self) -> Plan:
        yield from self._cycles(["P4", "P2"] if self.poses is None else list(self._poses)[:2])


@register
class MultiDirectional(_CubeProtocol):
    """ISO 9283 7.2.3: multi-directional pose accuracy variation vAP at P1, P2, P4 from three directions.

    Each pose is approached along x, y and z in turn from a pre-pose ``approach_mm`` away on the side of the cube
    centre (so the pre-poses stay inside the pre-flighted cube; P1 is approached from its negative side) [U];
    the capture label is ``<pose>/<direction>`` (e.g. ``P2/+x``: moving in +x) so the barycentre per direction can
    be computed.
    """

    name = "iso9283_multidirectional"
    version = "2"  # 2: the load's confirmation is the first step (every step index moved by one where it is asked)
    title = "ISO 9283 multi-directional pose accuracy variation (7.2.3)"
    approach_mm = FloatParameter(
        10.0, unit="mm", minimum=0.5, maximum=100.0, description="pre-pose offset along each approach direction"
    )

    def validate(self) -> None:
        super().validate()
        self._validate_one_load("7.2.3")

    def steps(self) -> Plan:
        yield from self._one_load()
        labels = [p for p in ("P1", "P2", "P4") if p in self._poses] or list(self._poses)
        centre = np.asarray(next(iter(self._poses.values()))[:3]) if self.poses else np.asarray(self._poses["P1"][:3])
        for velocity in self.velocities_pct:
            for cycle in range(1, self.cycles + 1):
                for label in labels:
                    target = self._poses[label]
                    for axis, name in enumerate("xyz"):
                        side = np.sign(centre[axis] - target[axis]) or -1.0
                        pre = list(target)
                        pre[axis] += side * self.approach_mm
                        direction = f"{'-' if side > 0 else '+'}{name}"
                        yield Move(tuple(pre), velocity, f"{label}/pre{direction}")
                        yield from visit(
                            f"{label}/{direction}",
                            target,
                            cycle,
                            velocity_pct=velocity,
                            settle_s=self.settle_s,
                            conditions={"load_kg": self.loads_kg[0]},
                        )
                yield Checkpoint(f"{velocity:g} %, cycle {cycle}")


@register
class Drift(_CubeProtocol):
    """ISO 9283 7.6: drift of AP and RP, a short run: cycle P1 -> P5 -> P4 -> P3 -> P2 continuously, capture at P1.

    ISO cycles for 8 h from cold [N]; this protocol is count-based (deterministic, so it can be resumed):
    ``cycles`` measured visits of P1, each after one pass over P5..P2, with ``pause_s`` between cycles. Analyse
    with ``bench analyze drift RUN.csv --pose P1 --window-s ...`` (the samples carry ``t_s``).
    """

    name = "iso9283_drift"
    version = "2"  # 2: the load's confirmation is the first step (every step index moved by one where it is asked)
    title = "ISO 9283 drift of pose characteristics (7.6), short run"
    pause_s = FloatParameter(0.0, unit="s", minimum=0.0, maximum=3600.0, description="wait between cycles")

    def validate(self) -> None:
        super().validate()
        self._validate_one_load("7.6")

    def steps(self) -> Plan:
        yield from self._one_load()
        others = [p for p in POSE_ORDER[1:] if p in self._poses]
        velocity = self.velocities_pct[0]
        for cycle in range(1, self.cycles + 1):
            yield from visit(
                "P1",
                self._poses["P1"],
                cycle,
                velocity_pct=velocity,
                settle_s=self.settle_s,
                conditions={"load_kg": self.loads_kg[0]},
            )
            for label in others:
                yield Move(self._poses[label], velocity, label)
            if self.pause_s > 0:
                yield Settle(self.pause_s)
            yield Checkpoint(f"drift cycle {cycle}")


@register
class StabilisationOvershoot(_CubeProtocol):
    """ISO 9283 7.4 and 7.5: position stabilisation time and overshoot at P1-P5, 3 cycles, 100 % velocity.

    Every visit moves to the pose and, as soon as the controller reports the move done, captures the streamed
    arrival (kind ``arrival``): the instrument's position from ``lead_s`` before that moment to ``hold_s`` after it.
    No dwell comes before the capture, since the settling is what is measured. The limit band is chosen at analysis
    time (``bench analyze stabilisation``; ISO comparison bands 0.1, 0.5 and 1.0 mm), so one run serves every band.
    ``lead_s`` must cover the approach into the band and ``hold_s`` the ringing until it has died out.
    """

    name = "iso9283_stabilisation"
    version = "1"
    title = "ISO 9283 position stabilisation time and overshoot (7.4, 7.5)"

    cycles = IntegerParameter(3, minimum=1, description="cycles per pose (ISO Table 5: 3)")
    velocities_pct = FloatListParameter(
        (100.0,), unit="%", minimum=0.1, maximum=100.0, description="test velocities, % of rated (ISO 4.2: 100)"
    )
    lead_s = FloatParameter(
        1.0, unit="s", minimum=0.0, maximum=60.0, description="streamed time kept before the move is reported done"
    )
    hold_s = FloatParameter(
        3.0, unit="s", minimum=0.1, maximum=60.0, description="streamed time recorded after the move is reported done"
    )

    def steps(self) -> Plan:
        yield from self._cycles(self._iso_order())

    def _visit(self, label: str, target: tuple[float, ...], cycle: int, velocity: float, load: float) -> Plan:
        """Move, then at once capture the streamed arrival (no dwell: the settling is what is measured)."""
        yield Move(target, velocity, label)
        yield Capture(
            label,
            cycle,
            kind="arrival",
            commanded=commanded_values(target),
            conditions={"velocity_pct": velocity, "load_kg": load, "lead_s": self.lead_s, "hold_s": self.hold_s},
        )
