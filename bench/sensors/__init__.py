"""Sensors of the bench: each yields timestamped readings with units and the calibration in force.

Every sensor satisfies the structural :class:`~bench.sensors.reading.Sensor` protocol (``read() -> Reading``) and
has a simulator that produces the bytes, lines or frames the real device would, from a *true* motion given as
arrays of positions in mm. Modules (imported on demand so that OpenCV and pynput load only when used):

- ``reading``: the ``Reading`` record and the ``Sensor`` protocol;
- ``calibration``: counts -> mm calibration of a mouse (per-axis scales or a 2x2 matrix, with id and date);
- ``input_event``, ``mouse``, ``mouse_sim``: evdev mouse discovery, reader and simulator (kernel ``input_event``
  records);
- ``serial_lines``, ``mouse_mcu``: line framing on a serial port, microcontroller mouse stream ``t,dx,dy[,squal]``;
- ``mouse_pointer``: the dissertation's OS-pointer method (pynput), kept for parity only;
- ``lasergrid``, ``lasergrid_sim``: the delta robot's laser-grid geometry, decoder, sensor and simulator;
- ``calliper``, ``calliper_wedge``, ``calliper_sim``: manual, keyboard-wedge and serial calliper readings, tilt
  from two depths;
- ``camera_spot``, ``camera_sim``: laser-spot detection with OpenCV; synthetic spot and chessboard frames.
"""

from bench.sensors.reading import MalformedSample, Reading, Sensor

__all__ = ["MalformedSample", "Reading", "Sensor"]
