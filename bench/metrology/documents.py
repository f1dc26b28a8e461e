"""Numbers the reference documents prescribe for their tests, in one place.

The protocols take them as their defaults and the reports' deviations tables compare a stored run with them, so
both import them from here (reports never import protocols or sensors). Pure constants, mm and kg; each names its
source: 000 is the pkm5 dissertation (shared/reference/pkm5.md), "thesis" the delta robot's
(shared/reference/delta4-lasergrid.md).
"""

from __future__ import annotations

__all__ = [
    "ISO9283_CYCLES",
    "ISO9283_STABILISATION_BANDS_MM",
    "ISO9283_POSE_ORDER",
    "ISO9283_VELOCITIES_PCT",
    "ACTUATOR_REPEATS",
    "ACTUATOR_TRAVELS_MM",
    "GRID_HEIGHTS_MM",
    "GRID_HIT_ATTEMPTS",
    "GRID_OFFSET_MM",
    "GRID_RESOLUTION_MM",
    "GRID_SENSORS",
    "LADDER_KG",
    "LADDER_LIFT_MM",
    "LASERGRID_GUI_PLACEMENT",
    "PAYLOAD_FAILURE_KG",
    "POSITIONING_POSES",
    "POSITIONING_READINGS",
]

# ---- ISO 9283:1998, the test conditions the pose protocols and the deviations tables share ----

#: Cycles per pose for AP/RP, AD/RD and vAP (Table 5).
ISO9283_CYCLES = 30
#: Test velocities, % of the rated velocity (clause 6.7).
ISO9283_VELOCITIES_PCT = (100.0, 50.0, 10.0)
#: Cycle order of the five cube poses, unidirectional (clause 6.10; Figure 5).
ISO9283_POSE_ORDER = ("P1", "P5", "P4", "P3", "P2")
#: Limit bands of the position stabilisation time and overshoot for comparison tests, mm (clauses 7.4, 7.5; A.4).
ISO9283_STABILISATION_BANDS_MM = (0.1, 0.5, 1.0)

# ---- the pkm5 dissertation (000) ----

#: 000 §8.4 (pkm5.md §6.9): commanded travels and repeats per travel of the actuator test.
ACTUATOR_TRAVELS_MM = (10.0, 20.0, 30.0, 40.0, 50.0)
ACTUATOR_REPEATS = 10
#: 000 Table A.14: the payload ladder, kg.
LADDER_KG = (0.45, 1, 1.45, 2, 2.45, 3, 3.45, 5.27, 6.18, 7.08, 8.44, 9.35, 10.26, 12.07, 13.43, 15, 18, 20, 23, 25.23)
#: 000 §8.7: the pure vertical lift of the payload ladder, mm.
LADDER_LIFT_MM = 50.42
#: 000 §8.7.5, Fig. 8-21 (pkm5.md): on reloading at 25 kg the mouse bracket and the end effector failed, kg.
PAYLOAD_FAILURE_KG = 25.0

# ---- the delta thesis, read by the laser grid ----

#: Thesis §8.4.2 (Appendix D1): the three positioning poses, cm -> mm, and the readings per pose.
POSITIONING_POSES = {"P1": (0.0, 0.0, -200.0), "P2": (-70.0, -70.0, -180.0), "P3": (50.0, -50.0, -160.0)}
POSITIONING_READINGS = 15
#: Thesis §8.4.3 (delta4-lasergrid.md §7.3): heights below the base (mm), attempts per sensor and height, sensors
#: tested, and the reference's re-approach offset range (mm; the thesis is silent).
GRID_HEIGHTS_MM = (140.0, 170.0, 200.0)
GRID_HIT_ATTEMPTS = 25
GRID_SENSORS = 16
GRID_OFFSET_MM = (10.0, 20.0)
#: Thesis §3.2.3, §5.5: the laser pattern (BE + G5 + G2.5) over the 10 mm sensor pitch resolves 2.5 mm, so a
#: reading is a lattice point of this step.
GRID_RESOLUTION_MM = 2.5
#: Calibration id of the screens' placement as the legacy GUI draws it (delta4-lasergrid.md §4.3), the default of
#: :class:`bench.sensors.lasergrid.GridGeometry`: a run storing it has no placement measured on the rig (§6.5).
LASERGRID_GUI_PLACEMENT = "lasergrid-gui-default"
