"""The simulated pkm5 plant: the seeded error model between commanded steps and the true attained pose (or, on the
actuator bench, the true strokes), through the kinematics of :mod:`motion.pkm5`."""

from __future__ import annotations

import dataclasses
import importlib.util
import itertools
import logging
import threading
from typing import Any

import numpy as np

from bench.errors import ConfigError
from bench.robots.pkm5_kinematics import MODE_TOL_MM, pose_deg_from_rad
from bench.simulators.error_model import ErrorMagnitudes, ErrorModel, JointMemory
from bench.simulators.plant import Plant
from motion import kernels, pkm5
from motion.pkm5 import compiled as pkm5_compiled

__all__ = ["PKM5_ERRORS", "build_actuator_bench", "build_plant", "load_fk_kernel", "plant_engine"]

_log = logging.getLogger(__name__)

#: Largest FK residual RMS of the plant's perturbed legs that still counts as a pose (the error model leaves 0.1-0.2 mm).
_PLANT_RESIDUAL_TOL_MM = 2.0
#: Largest residual RMS of commanded lengths in the documented geometry that are a pose of it (steps round to 3 um).
NOMINAL_FIT_MM = 0.01
#: Largest residual RMS of the true legs' translation fit for which a command with unequal pairs is taken as a
#: translation (a compensated command): the steps' rounding (3 um) and a good calibration's error leave less.
TRANSLATION_FIT_MM = 0.05
#: LM step criterion of the plant's warm solve (mm, rad): far below the 0.03 mm count of the simulated mice.
_PLANT_STEP_TOL = 1e-7
#: Distinct commands whose documented geometry's pose a plant of a true geometry keeps (a campaign revisits a few).
_NOMINAL_STARTS_KEPT = 1024
#: Warm solves that a compiled plant no simulator warmed up (:meth:`Plant.warm_up`) leaves to numpy (7 ms each)
#: before it loads numba and waits for it (0.5-2 s from numba's cache): a short use never loads it.
NUMPY_SOLVES_AT_START = 32
#: Warm solves that a simulator serving without a kernel wait (``--kernel-wait-s 0``) leaves to numpy before it
#: starts loading the kernel behind its port. The load costs about 1.5 s of CPU (measured: a simulator that served
#: nothing used 1.8 s, 0.25 s of it imports), what ~200 numpy solves of 7 ms cost: loading once numpy has spent
#: that much is never more than twice the better choice made in hindsight (the ski-rental rule), and a short
#: session (a test, a few jogs) never pays for it. ``--kernel-wait-s`` > 0 (bench demo) loads at once and waits.
NUMPY_SOLVES_BEFORE_LOAD = 200

#: Error sizes for AP/RP of the order of the documents' physical tests (pkm5.md §6.8: AP 1.2-1.9 mm, RP 1.6-2.7 mm,
#: angles 0.2-1.9 deg). Joint units mm of leg length; pose units (mm, mm, mm, deg, deg). Actuator noise per
#: Table A.7 (sigma 0.02-0.11 mm); passive-joint play dominates the random part (joint tolerance <= 1 mm, Table 4-2).
PKM5_ERRORS = ErrorMagnitudes(
    scale_sigma=0.003,
    offset_sigma=0.25,
    backlash=0.10,
    noise_sigma=0.05,
    sag_per_kg=0.005,
    pose_gain_sigma=0.004,
    pose_play_sigma=(0.6, 0.6, 0.6, 0.35, 0.35),
    pose_sag_per_kg=(0.0, 0.0, -0.03, 0.0, 0.0),
    pose_offset_sigma=(0.5, 0.5, 0.5, 1.0, 1.0),
)


def plant_engine() -> str:
    """FK engine of the plant's per-move solve: the compiled single-pose kernel when numba is installed (~0.1 ms a
    solve, against ~7 ms for the numpy reference on one row, longer than most moves of the demo at speed factor
    10,000), else numpy; asked without importing numba (its import alone takes 0.3-1 s, done on the loader
    thread). Until the kernel is loaded the solves stay numpy's (never waiting for it), so which engine solved a
    move depends on timing; the two agree within 1e-9 mm, far below a mouse count (0.03 mm)."""
    return "compiled" if importlib.util.find_spec("numba") is not None else "numpy"


def load_fk_kernel(geometry: Any = pkm5.DEFAULT_GEOMETRY) -> None:
    """Load numba and the compiled FK kernel into this process (machine code from numba's cache, or compiled on a
    fresh install): one solve of ``geometry``'s home lengths. Raises what a broken numba install raises."""
    pkm5.forward_kinematics(
        geometry.home_lengths_mm[None, :],
        geometry,
        mode="translation",
        initial_pose=(150.0, 0.0, 300.0, 0.0, 0.0),
        engine="compiled",
    )


class _KernelLoader(threading.Thread):
    """Loads numba and the FK kernel (0.5-2 s: the import, machine code from numba's cache) on a thread: before a
    simulator serves its pty when it waits for it (``--kernel-wait-s``, :meth:`Plant.warm_up`), else once the
    plant has solved NUMPY_SOLVES_BEFORE_LOAD moves with numpy; solves use it once it is loaded (:meth:`engine`).
    Started while the device is being built, the import fought the seed-table build for
    the GIL and doubled the start-up. While it loads, the event loop's replies wait for the GIL and each move's
    solve is numpy's (7-10 ms), so a campaign's first moves ran 30 ms past their end (the demo's first 45 moves at
    load 4: 1.4 s); a simulator started with ``--kernel-wait-s`` waits for it before serving."""

    def __init__(self, geometry: Any) -> None:
        super().__init__(name="pkm5-fk-kernel", daemon=True)
        self.geometry, self.failure = geometry, None
        self._starting = threading.Lock()
        #: a simulator serves this plant (warm was called): solves never wait for the load
        self.served = False
        self._numpy_solves = itertools.count()

    def start_once(self) -> None:
        with self._starting:
            if self.ident is None:
                self.start()

    def warm(self, wait_s: float = 0.0) -> None:
        """A simulator is about to serve: with ``wait_s`` > 0 load now and return once loaded or after ``wait_s``
        (a fresh install compiles for 10-20 s: the load then goes on behind the served port); with 0 the load
        starts behind the port after NUMPY_SOLVES_BEFORE_LOAD solves."""
        self.served = True
        if wait_s > 0:
            self.start_once()
            self.join(wait_s)

    def run(self) -> None:
        try:
            load_fk_kernel(self.geometry)
        except Exception as exc:  # a broken numba install: the plant keeps the numpy reference, and says so
            self.failure = exc
            _log.warning("compiled FK kernel not loaded (%s): the plant solves with numpy", exc)

    def engine(self) -> str:
        """The engine of the next solve. A simulator (which started the load in :meth:`Plant.warm_up`) never waits
        for it: on a fresh install numba compiles the kernel first (10-20 s of CPU), and a controller that holds a
        reply that long is a dead link to the host (a CI run failed so, at its 33rd move). Until the load is done
        its solves stay numpy's, which the compiled kernel equals within 1e-9 mm, far below a mouse count. A plant
        used without a simulator (no warm-up) loads after NUMPY_SOLVES_AT_START solves and waits for it. A kernel
        already in the process (a parent loaded it before it forked this one) costs nothing to load: it is used
        from the first solve (the loader's one solve then takes milliseconds)."""
        if self.ident is None:
            if pkm5_compiled.fk_kernel_loaded():
                self.start_once()
                self.join()
            elif next(self._numpy_solves) < (NUMPY_SOLVES_BEFORE_LOAD if self.served else NUMPY_SOLVES_AT_START):
                return "numpy"
            else:
                self.start_once()
                if not self.served:
                    self.join()
        if self.is_alive():
            return "numpy"
        return "numpy" if self.failure is not None else "compiled"


def build_actuator_bench(seed: int, *, ideal: bool = False, geometry: Any = pkm5.DEFAULT_GEOMETRY):
    """The six actuators free-standing (000 §8.4): ``bench(steps, load_kg) -> true strokes`` (6,), mm.

    Each actuator's attained leg length comes from the same seeded joint errors as :func:`build_plant` (scale,
    offset, backlash, noise; no payload on a free-standing actuator), reported as stroke from full retraction.
    """
    offsets = np.asarray(geometry.leg_length_offset_mm, dtype=float)
    model = ErrorModel.ideal(6, 5) if ideal else ErrorModel.draw(PKM5_ERRORS, 6, seed, offsets)
    rng = np.random.default_rng([seed, 1])
    memory: list[JointMemory] = []

    def true_strokes(steps: np.ndarray, load_kg: float) -> np.ndarray:
        lengths = pkm5.steps_to_lengths(np.asarray(steps)[None, :], geometry)[0]
        if not memory:
            memory.append(JointMemory(lengths))
        direction = memory[0].update(lengths)
        return model.true_joints(lengths, direction, 0.0, rng) - offsets

    true_strokes.model = model  # type: ignore[attr-defined]  # the drawn errors, for tests against the truth
    return true_strokes


def _home_pose(geometry: Any):
    """FK of the home lengths, started at the neutral pose: one solve (7 ms) where the default start builds the
    seed table and imports scipy.spatial (0.8 s of every simulator's start); the seed table's solve if that
    one does not converge (an unusual geometry). The two agree within 1e-12 mm on the documented geometry."""
    home = geometry.home_lengths_mm[None, :]
    fk = pkm5.forward_kinematics(home, geometry, initial_pose=pkm5.NEUTRAL_POSE, engine="numpy")
    return fk if fk.converged[0] else pkm5.forward_kinematics(home, geometry, engine="numpy")


def build_plant(
    seed: int,
    *,
    ideal: bool = False,
    geometry: Any = pkm5.DEFAULT_GEOMETRY,
    true_geometry: Any = None,
    engine: str = "auto",
) -> Plant:
    """Steps -> leg lengths -> seeded errors -> least-squares FK -> pose errors; pose in mm and degrees.

    With ``true_geometry`` (a perturbed :class:`motion.pkm5.Geometry`, e.g. from
    :func:`bench.simulators.true_geometry.true_geometry`) the robot moves by that geometry's lengths and FK, and the
    error model's stand-ins for geometry (joint offset and scale, pose gain and bias) are zeroed; backlash, noise,
    sag and play stay.

    ``engine`` of the per-move solves: 'numpy' (the reference), 'compiled' (numba required) or 'auto'
    (:func:`plant_engine`). The first pose, solved while the simulator is built, is always numpy's.
    """
    if engine not in kernels.ENGINES:
        raise ConfigError(f"engine = {engine!r}, expected one of {list(kernels.ENGINES)}")
    if engine == "auto":
        engine = plant_engine()
    elif engine == "compiled" and plant_engine() != "compiled":
        raise ConfigError("engine = 'compiled' needs numba, which is not installed (pip install 'bench[fast]')")
    moved_by = geometry if true_geometry is None else true_geometry
    loader = _KernelLoader(geometry) if engine == "compiled" else None

    def joints_of(steps: np.ndarray) -> np.ndarray:
        return pkm5.steps_to_lengths(steps[None, :], moved_by)[0]

    def engine_for(previous: np.ndarray | None) -> str:
        # The first pose (at power-up, before the pty is served: no previous pose) is numpy's; then
        # _KernelLoader.engine decides (numpy until the kernel is loaded, and when to load it).
        if previous is None or loader is None:
            return "numpy"
        return loader.engine()

    def forward(lengths: np.ndarray, commanded: np.ndarray, previous: np.ndarray | None) -> np.ndarray | None:
        use = engine_for(previous)
        if true_geometry is not None:
            return _forward_true(lengths, commanded, use)
        mode = pkm5.detect_mode(commanded[None, :], MODE_TOL_MM)[0]
        if previous is not None:
            start = np.r_[previous[:3], np.radians(previous[3:])]
        elif np.allclose(commanded, geometry.home_lengths_mm, rtol=0, atol=NOMINAL_FIT_MM):
            # the power-up pose, commanded home: started at the home pose, not from the seed table (scipy.spatial
            # and 4,000 IK poses, 0.8 s of every simulator's start)
            start = home_fk.pose[0]
        else:
            start = None
        if start is not None:
            # One solve warm-started near the answer (Plant: the pose last attained at this command, else the last
            # pose). The perturbed legs never fit a pose exactly (a 0.1-0.2 mm residual), so the default
            # ``retry_above_mm`` would run every restart on every move; they run only when the warm solve did not
            # converge (tests/test_plant_forward.py: the same poses within 1e-6 mm).
            fk = pkm5.forward_kinematics(
                lengths[None, :],
                geometry,
                initial_pose=start,
                mode=mode,
                residual_tol_mm=_PLANT_RESIDUAL_TOL_MM,
                retry_above_mm=np.inf,
                step_tol=_PLANT_STEP_TOL,
                engine=use,
            )
            if fk.converged[0]:
                return pose_deg_from_rad(fk.pose[0])
        fk = pkm5.forward_kinematics(
            lengths[None, :],
            geometry,
            initial_pose=start,
            mode=mode,
            residual_tol_mm=_PLANT_RESIDUAL_TOL_MM,
            engine=use,
        )
        return pose_deg_from_rad(fk.pose[0]) if fk.converged[0] else None

    nominal_starts: dict[tuple[bytes, str, str], Any] = {}

    def _nominal_start(commanded: np.ndarray, mode: str, use: str):
        # the documented geometry's solution: the true fit's start (no seed table for a perturbed geometry). It
        # depends on the command alone, and a campaign commands each pose once per cycle: solved once per command
        # (with every restart it is 2/3 of a move's solve), kept like the attained poses (Plant's warm starts)
        key = (commanded.tobytes(), mode, use)
        if key not in nominal_starts:
            if len(nominal_starts) >= _NOMINAL_STARTS_KEPT:
                del nominal_starts[next(iter(nominal_starts))]  # the command solved longest ago
            nominal_starts[key] = pkm5.forward_kinematics(
                commanded[None, :], geometry, mode=mode, residual_tol_mm=2.0, max_iter=200, engine=use
            )
        return nominal_starts[key]

    def _fit_true(lengths: np.ndarray, start: Any, mode: str, use: str):
        # true lengths never fit exactly (6 legs, 3-4 unknowns): retrying every inexact fit from the restart guesses
        # would trade the near solution for a far branch with a smaller residual
        return pkm5.forward_kinematics(
            lengths[None, :],
            moved_by,
            initial_pose=start.pose,
            mode=mode,
            residual_tol_mm=_PLANT_RESIDUAL_TOL_MM,
            retry_above_mm=0.5,
            max_iter=200,
            engine=use,
        )

    def _forward_true(lengths: np.ndarray, commanded: np.ndarray, use: str) -> np.ndarray | None:
        # the commanded mode shows in the nominal lengths (the true pairs differ)
        commanded = pkm5.steps_to_lengths(pkm5.lengths_to_steps(commanded[None, :], moved_by), geometry)[0]
        mode = pkm5.detect_mode(commanded[None, :], MODE_TOL_MM)[0]
        start = _nominal_start(commanded, mode, use)
        if start.residual_mm[0] <= NOMINAL_FIT_MM:
            fk = _fit_true(lengths, start, mode, use)
        else:
            # lengths no pose of the documented geometry has: a compensated command (a calibrated geometry gives
            # each leg of a pair its own length). The robot stays in translation when its legs fit a translation
            # pose, else it turns in the rotation mode that fits them best.
            fk = _fit_true(lengths, _nominal_start(commanded, "translation", use), "translation", use)
            if not (fk.converged[0] and fk.residual_mm[0] <= TRANSLATION_FIT_MM):
                fits = [_fit_true(lengths, _nominal_start(commanded, m, use), m, use) for m in ("alpha", "beta")]
                fk = min(fits, key=lambda f: (not f.converged[0], f.residual_mm[0]))
        return pose_deg_from_rad(fk.pose[0]) if fk.converged[0] else None

    model = (
        ErrorModel.ideal(6, 5)
        if ideal
        else ErrorModel.draw(PKM5_ERRORS, 6, seed, np.asarray(geometry.leg_length_offset_mm))
    )
    if true_geometry is not None:
        model = dataclasses.replace(
            model, offset=np.zeros(6), scale=np.zeros(6), pose_gain=np.zeros((5, 5)), pose_offset=np.zeros(5)
        )
    home_fk = _home_pose(geometry)
    return Plant(
        joints_of,
        forward,
        model,
        pose_deg_from_rad(home_fk.pose[0]),
        seed,
        warm_up=None if loader is None else loader.warm,
    )
