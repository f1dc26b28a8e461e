"""Metrology core of bench: the figures a test report prints, as pure functions over raw samples.

ISO 9283 pose characteristics (`iso9283`), time-series and path characteristics (`iso9283_dynamics`),
cornering, path velocity and minimum positioning time (`iso9283_path`), actuator
accuracy after Groover and ISO 230-2 (`actuator`) with its per-actuator table path (`actuator_tables`),
optical-mouse calibration (`mouse_calibration`), the project's payload error (`payload`), GUM uncertainty
(`uncertainty`), pose statistics of partial readings and detection rates with their Wilson interval
(`partial_pose`), the laser grid's hit rates (`hit_rate`) and the tidy-table interface (`tables`).
Units: mm, degrees, s, kg, N. Results are frozen dataclasses; too few samples raise
``bench.errors.InsufficientData``, malformed input ``bench.errors.ConfigError``; a result is never a silent NaN.
bench/reports imports from here.
"""

from bench.metrology.actuator import *
from bench.metrology.actuator import __all__ as _actuator
from bench.metrology.actuator_tables import *
from bench.metrology.actuator_tables import __all__ as _actuator_tables
from bench.metrology.hit_rate import *
from bench.metrology.hit_rate import __all__ as _hit_rate
from bench.metrology.iso9283 import *
from bench.metrology.iso9283 import __all__ as _iso9283
from bench.metrology.iso9283_dynamics import *
from bench.metrology.iso9283_dynamics import __all__ as _dynamics
from bench.metrology.iso9283_path import *
from bench.metrology.iso9283_path import __all__ as _path
from bench.metrology.mouse_calibration import *
from bench.metrology.mouse_calibration import __all__ as _mouse
from bench.metrology.partial_pose import *
from bench.metrology.partial_pose import __all__ as _partial_pose
from bench.metrology.payload import *
from bench.metrology.payload import __all__ as _payload
from bench.metrology.uncertainty import *
from bench.metrology.uncertainty import __all__ as _uncertainty

__all__ = [*_iso9283, *_dynamics, *_path, *_actuator, *_actuator_tables, *_mouse, *_payload, *_uncertainty, *_partial_pose,
           *_hit_rate]
