"""Kinematic calibration of a robot, from a stored run to the geometry a run commands by.

- :mod:`bench.calibration.identify`: a stored calibration run -> the identified geometry with its uncertainties
  (``bench calibrate``), refused with the reason when the data cannot support it; how a run of each robot becomes
  the problem it solves is :mod:`bench.calibration.problems`, the text it prints :mod:`bench.calibration.summary`;
- :mod:`bench.calibration.compensate`: which stored calibration is in force for a run, and the geometry it gives.

The numbers are pure computation elsewhere: the robots' error models in ``motion/<robot>/calibration.py``, the fits,
the multi-start search and the campaign plan in :mod:`bench.metrology` (``kinematic_*``); the report's calibration
page is :mod:`bench.reports.calibration`.
"""
