"""Station files, the one rig builder, and hardware-shaped runs: every device a simulator process reached through the
hardware path (ptys and FIFOs, the pkm5 simulator answering its SIM verbs as the firmware does)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.cli import main
from bench.errors import ConfigError
from bench.launch import RigRequest, open_rig
from bench.metrology.uncertainty import resolution_uncertainty
from bench.protocols import Runner, load_protocol
from bench.protocols.plan import iterate, required_capabilities
from bench.rigs.registration import CHECK_RETURNS
from bench.rigs.station import load_station, parse_station
from bench.robots import pkm5_wire as wire
from bench.simulators.pkm5 import Pkm5SimDevice
from bench.steps import Capture, Move
from bench.store import Store

ROOT = Path(__file__).resolve().parents[1]
STATIONS = ROOT / "examples" / "stations"
EXAMPLES = ROOT / "examples"

MINIMAL = {"robot": {"kind": "pkm5"}, "controller": {"port": "/dev/ttyACM0"}}
#: The simulators' speed factor of the rehearsals here; a rig built on one gets it too (as bench.launch does), so
#: the registration's settles are the simulated robot's, not a second of real time per rig.
REHEARSAL_SPEED = 20000


def _station(**tables):
    return {**MINIMAL, **tables}


def test_every_example_station_parses_with_the_capabilities_of_its_devices():
    caps = {path.stem: load_station(path).capabilities() for path in STATIONS.glob("*.toml")}
    assert caps == {
        "pkm5_mice": {"assembled", "pose", "mouse_counts", "arrival", "reading"},
        "pkm5_actuator_bench": {"actuator_bench", "reading"},
        "delta4_lasergrid": {"assembled", "pose", "grid_hit"},
        "pkm5_camera": {"assembled", "pose", "reading"},
        "delta4_camera": {"assembled", "pose"},
    }
    mice = load_station(STATIONS / "pkm5_mice.toml")
    assert (
        mice.controller.baud == 115200 and mice.sensor("mice").cpi == 800 and mice.identity.robot_serial == "PKM5-0001"
    )
    assert load_station(STATIONS / "delta4_lasergrid.toml").controller.baud == 9600
    camera = load_station(STATIONS / "pkm5_camera.toml").sensor("camera")
    assert Path(camera.calibration) == STATIONS / "camera-plane.json"  # relative to the station file


@pytest.mark.parametrize(
    "tables, message",
    [
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "dpi": 800}),
            "unknown key 'mice.dpi', expected one of calibration, cpi, grab, noise_counts, xy, xz, xz_mount",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "xz_mount": "rails"}),
            'mice.xz_mount = \'rails\', expected "platform" (on the end effector: sees x and z) or "guided" (on '
            "vertical guides: sees z only)",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "cpi": 1e20}),
            "mice.cpi = 1e+20, expected a mouse's resolution in counts per inch, 100 to 50000",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "xz_mount": True}),
            'mice.xz_mount = True, expected "platform"',
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "calibration": 0}),
            "mice.calibration = 0, expected a stored mouse calibration version, an integer >= 1",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "calibration": "v3"}),
            "mice.calibration = 'v3', expected a stored mouse calibration version, an integer >= 1",
        ),
        (_station(mice={"xy": "/dev/input/a"}), "mice.xz missing, expected the x-z mouse's event device"),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/a"}),
            "mice.xz = '/dev/input/a', expected a device of its own (mice.xy names it too)",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "cpi": "800"}),
            "mice.cpi = '800', expected a finite number > 0",
        ),
        (
            _station(mice={"xy": "/dev/input/a", "xz": "/dev/input/b", "cpi": -5}),
            "mice.cpi = -5, expected a finite number > 0",
        ),
        (
            {"robot": {"kind": "scara"}, "controller": {"port": "/dev/ttyACM0"}},
            "robot.kind = 'scara', expected one of pkm5, delta4",
        ),
        ({"robot": {"kind": "pkm5"}}, '[controller] missing, expected a table (port = "/dev/ttyUSB0")'),
        (_station(controller={"port": 5}), "controller.port = 5, expected a serial port, e.g. /dev/ttyUSB0"),
        (_station(controller={"port": "/dev/a", "baud": True}), "controller.baud = True, expected a baud rate"),
        (
            _station(controller={"port": "/dev/a", "baud": 2**63 - 1}),  # overflowed pySerial's ioctl: a traceback
            "controller.baud = 9223372036854775807, expected a baud rate, an integer from 50 to 4,000,000",
        ),
        (_station(controller={"port": "/dev/a", "baud": -1}), "controller.baud = -1, expected a baud rate"),
        (_station(calliper={"kind": "serial", "port": "/dev/c", "baud": 0}), "calliper.baud = 0, expected a baud"),
        (_station(calliper={"kind": "serial"}), "calliper.port missing, expected the calliper's serial port"),
        (_station(laser_grid={}), "[laser_grid] with robot.kind = 'pkm5', expected robot.kind = 'delta4'"),
        (_station(mouse={}), "unknown table [mouse], expected one of [station], [robot], [controller], [mice]"),
        (_station(**{"mice\n": {}}), "unknown table [mice\\n], expected one of [station]"),  # was two lines
        (
            {"robot": {"kind": "delta4"}, "controller": {"port": "/dev/a"}, "mice": {"xy": "/dev/b", "xz": "/dev/c"}},
            "[mice] with robot.kind = 'delta4', expected robot.kind = 'pkm5' (the mice are mounted on the pkm5's",
        ),
        (_station(camera={"device": "/dev/video0", "calibration": "p.json", "frames": 0}), "camera.frames = 0"),
        (
            _station(calliper={"kind": "serial", "port": "/dev/ttyACM0"}),
            "calliper.port = '/dev/ttyACM0', expected a device of its own (controller.port names it too)",
        ),
    ],
)
def test_bad_station_files_are_one_line_naming_the_key_the_value_and_what_was_expected(tables, message):
    with pytest.raises(ConfigError) as error:
        parse_station(tables, source="s.toml")
    text = str(error.value)
    assert text.startswith("s.toml: ") and message in text and "\n" not in text


def test_a_bad_station_file_on_the_command_line_is_one_line_and_exit_2(tmp_path, capsys):
    station = tmp_path / "bad.toml"
    station.write_text('[robot]\nkind = "pkm5"\n[controller]\nport = "/dev/x"\n[mice]\nxy = 3\nxz = "/dev/y"\n')
    assert main(["station", "check", str(station)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"bench: error: {station}: mice.xy = 3, expected the x-y mouse's event device"
    station.write_text("[robot\n")
    assert main(["run", str(EXAMPLES / "iso9283_pose_quick.toml"), "--station", str(station)]) == 2
    assert "not a valid TOML station file" in capsys.readouterr().err


def test_a_protocol_needing_what_the_station_lacks_is_refused_before_anything_opens(tmp_path, capsys):
    store = tmp_path / "b.db"
    code = main(
        [
            "run",
            str(EXAMPLES / "actuator_accuracy.toml"),
            "--station",
            str(STATIONS / "pkm5_mice.toml"),
            "--sim",
            "--store",
            str(store),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert "controller.fixture = 'assembled', expected 'actuator-bench' for protocol 'actuator_accuracy'" in err
    code = main(
        [
            "run",
            str(EXAMPLES / "mouse_calibration.toml"),
            "--station",
            str(STATIONS / "pkm5_camera.toml"),
            "--store",
            str(store),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.endswith("protocol 'mouse_calibration' needs mouse_counts (add [mice])")
    with Store(store) as opened:
        assert opened.runs() == []  # nothing was started, nothing stored


def test_protocols_ask_for_what_their_own_plans_capture():
    needs = {path.stem: required_capabilities(load_protocol(path)) for path in EXAMPLES.glob("*.toml")}
    assert needs["iso9283_pose"] == {"assembled", "pose"}
    assert needs["iso9283_stabilisation"] == {"assembled", "arrival"}
    # the example reads a calliper after every move (reference = "calliper"): it asks for readings too
    assert needs["mouse_calibration"] == {"assembled", "mouse_counts", "reading"}
    assert needs["actuator_accuracy"] == {"actuator_bench", "reading"}
    assert needs["payload_ladder"] == {"assembled", "reading"}
    assert needs["lasergrid_hits"] == {"assembled", "grid_hit"}


def test_station_check_names_every_device_and_fails_for_the_missing_one(tmp_path, capsys):
    assert main(["station", "check", str(STATIONS / "pkm5_mice.toml"), "--sim", "--json"]) == 0
    checks = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [c["key"] for c in checks] == ["controller.port", "mice.xy", "mice.xz", "calliper"]
    assert all(c["ok"] for c in checks), checks
    assert checks[0]["detail"] == "bench-pkm5 firmware 1.0.0-sim, protocol v3"
    # the same station on this machine, where its devices do not exist
    assert main(["station", "check", str(STATIONS / "pkm5_mice.toml")]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("controller.port  problem ") and "no such device" in lines[0]
    assert "fix: plug the controller in" in lines[0]
    assert "mice.xy          problem" in lines[1] and "ls -l /dev/input/by-id" in lines[1]
    assert lines[3].startswith("calliper         ok")


def test_station_check_explains_a_permission_problem(tmp_path, capsys):
    import os

    if os.geteuid() == 0:
        pytest.skip("root opens any file: the permission check needs an unprivileged user")
    device = tmp_path / "event-mouse"
    device.write_bytes(b"")
    device.chmod(0)
    station = tmp_path / "s.toml"
    station.write_text(
        f'[robot]\nkind = "pkm5"\n[controller]\nport = "/dev/none"\n[mice]\nxy = "{device}"\nxz = "/dev/none2"\n'
    )
    assert main(["station", "check", str(station)]) == 1
    assert "permission denied -> fix: add yourself to the 'input' group" in capsys.readouterr().out


def test_the_hardware_only_simulator_refuses_its_sim_verbs_as_the_firmware_does():
    device = Pkm5SimDevice(lambda steps, load: np.zeros(5), sim_verbs=False)
    device.feed(b"", 0.0)  # BOOT
    reply = device.feed(wire.format_command("SIMTRUE", (), 7), 0.0)
    assert reply == wire.format_reply("ERR", 7, int(wire.ErrorCode.SYNTAX), "SYNTAX")


def _truth(path: str) -> np.ndarray:
    return np.array([json.loads(line)["pose"] for line in Path(path).read_text().splitlines()])


def _rehearsed_run(store: Store, station: Path, protocol_file: Path, *, operator=None, speed=REHEARSAL_SPEED):
    protocol = load_protocol(protocol_file)
    rig = open_rig(
        RigRequest(station=str(station), simulate=True, seed=3, speed_factor=speed),
        store,
        robot=protocol.robot,
        fixture=getattr(protocol, "fixture", "assembled"),
        requires=required_capabilities(protocol),
        protocol=protocol.name,
        operator=operator,
    )
    try:
        if operator is not None and hasattr(operator, "truth_path"):
            operator.truth_path = rig.simulator.truth_log
        result = Runner(rig, store, progress=False).run(protocol)
        truth = _truth(rig.simulator.truth_log)
    finally:
        rig.close()
    return result, truth


def _offset_from_truth(samples, truth: np.ndarray, protocol_file: Path) -> np.ndarray:
    """Each pose sample of a rehearsed run of ``protocol_file`` less the true pose it was taken at (mm, (n, 3)): the
    truth log has one rest per move, in plan order, after the registration's check moves."""
    measured = np.array([[s.values[k] for k in ("x_mm", "y_mm", "z_mm")] for s in samples])
    moves, at_capture = 0, []
    for step in iterate(load_protocol(protocol_file)):
        moves += isinstance(step, Move)
        if isinstance(step, Capture):
            at_capture.append(moves - 1)
    checks = 2 * CHECK_RETURNS  # the registration's check moves come first (bench.rigs.registration)
    assert len(truth) == checks + moves
    return measured - truth[checks:][at_capture, :3]


def test_pkm5_with_mice_on_the_hardware_path_measures_the_true_displacements(tmp_path):
    with Store(tmp_path / "b.db") as store:
        result, truth = _rehearsed_run(store, STATIONS / "pkm5_mice.toml", EXAMPLES / "iso9283_pose_quick.toml")
        assert result.exit_status == "completed" and result.samples == 15, result.reason
        run = store.run(result.run_id)
        settings = run.settings
        samples = [s for s in store.samples(result.run_id) if s.kind == "pose"]
    assert settings["station"]["simulated"] is True and settings["station"]["identity"]["robot_serial"] == "PKM5-0001"
    assert run.bench == "pkm5-bench-1"  # the station's name, the run's key in the lab store
    assert settings["instrument"]["cpi"] == 800 and settings["instrument"]["resolution_mm"] == pytest.approx(0.03175)
    offset = _offset_from_truth(samples, truth, EXAMPLES / "iso9283_pose_quick.toml")
    # registered at the mean return home, so every reading is off by the robot's own home error, and only by it:
    # the spread of that offset is the mice's (a count is 0.032 mm, 0.05 counts of noise)
    assert np.ptp(offset, axis=0).max() < 0.1, offset
    assert np.linalg.norm(offset.mean(axis=0)) < 3.0


def _guided_station(tmp_path: Path) -> Path:
    """examples/stations/pkm5_mice.toml with its x-z mouse on vertical guides (the dissertation's Z mouse)."""
    text = (STATIONS / "pkm5_mice.toml").read_text().replace("[mice]\n", '[mice]\nxz_mount = "guided"\n', 1)
    path = tmp_path / "pkm5_guided.toml"
    path.write_text(text)
    return path


def test_a_guided_x_z_mouse_measures_the_true_positions_of_an_iso_pose_run(tmp_path):
    """The simulator's x-z mouse on vertical guides (its x counts stay 0 apart from noise), the station saying so:
    the run completes and measures the true displacements as a platform mouse does."""
    quick = EXAMPLES / "iso9283_pose_quick.toml"
    with Store(tmp_path / "b.db") as store:
        result, truth = _rehearsed_run(store, _guided_station(tmp_path), quick)
        assert result.exit_status == "completed" and result.samples == 15, result.reason
        settings = store.run(result.run_id).settings
        samples = [s for s in store.samples(result.run_id) if s.kind == "pose"]
    assert settings["station"]["mice"]["xz_mount"] == "guided" and settings["instrument"]["xz_mount"] == "guided"
    assert settings["instrument"]["liveness_x_cross_check"] is False
    assert max(abs(s.raw["counts_xz"][0]) for s in samples) <= 1  # the guided mouse saw no x, over 33 mm of it
    offset = _offset_from_truth(samples, truth, quick)
    assert np.ptp(offset, axis=0).max() < 0.1, offset  # as the platform mouse's run above
    assert np.linalg.norm(offset.mean(axis=0)) < 3.0


def test_a_station_taking_a_guided_x_z_mouse_to_ride_the_platform_is_refused_naming_the_key(tmp_path):
    """The simulated x-z mouse on guides, the station left at its default (on the platform, seeing x): the first move
    with x is refused in a line that names the key, and nothing of that capture is stored."""
    from bench.rigs.builder import build_rig
    from bench.simulators.station import rehearse

    protocol = load_protocol(EXAMPLES / "iso9283_pose_quick.toml")
    rehearsal = rehearse(load_station(_guided_station(tmp_path)), speed_factor=REHEARSAL_SPEED)
    try:
        station = rehearsal.station.with_sensor("mice", xz_mount="platform")  # the simulated mouse stays guided
        with Store(tmp_path / "b.db") as store:
            rig = build_rig(station, store, requires=required_capabilities(protocol), speed_factor=REHEARSAL_SPEED)
            try:
                result = Runner(rig, store, progress=False).run(protocol)
            finally:
                rig.close()
            stored = [s for s in store.samples(result.run_id) if s.kind == "pose"]
    finally:
        rehearsal.close()
    assert result.exit_status == "failed", result.reason
    assert "mouse_xz" in result.reason and 'set [mice] xz_mount = "guided"' in result.reason, result.reason
    assert "\n" not in result.reason and len(stored) < 15


def test_a_hardware_path_run_is_exported_analysed_and_reported_with_equal_numbers(tmp_path, capsys):
    store = tmp_path / "b.db"
    assert (
        main(
            [
                "run",
                str(EXAMPLES / "iso9283_pose_quick.toml"),
                "--station",
                str(STATIONS / "pkm5_mice.toml"),
                "--sim",
                "--store",
                str(store),
                "--no-progress",
                "--seed",
                "4",
            ]
        )
        == 0
    )
    run_id = int(capsys.readouterr().out.split()[-1])
    table = tmp_path / "run.csv"
    assert main(["export", str(run_id), "--store", str(store), "--out", str(table)]) == 0
    with Store(store, read_only=True) as opened:  # the run's instrument term (resolution) and its registration's
        run = opened.run(run_id)
    (registration,) = run.settings["registrations"]
    instrument_u_mm = float(
        np.hypot(
            resolution_uncertainty(run.settings["instrument"]["resolution_mm"], difference=True), registration["u_mm"]
        )
    )
    assert main(["analyze", "iso9283", str(table), "--json", "--instrument-u-mm", str(instrument_u_mm)]) == 0
    analysed = json.loads(capsys.readouterr().out.splitlines()[-1])["poses"]
    out = tmp_path / "reports"
    assert main(["report", str(run_id), "--store", str(store), "--out", str(out)]) == 0
    capsys.readouterr()
    assert (out / f"report_run{run_id}.pdf").stat().st_size > 0
    samples = pd.read_csv(out / f"run{run_id}_samples.csv")
    exported = pd.read_csv(table)
    assert len(samples) == len(exported) == 15
    html = (out / f"report_run{run_id}.html").read_text()
    assert "PKM5-0001" in html and "Parallel robots lab" in html  # page 1 names the station's device under test
    from bench.metrology.formatting import format_value

    for pose, result in analysed.items():  # the report shows the same AP, rounded by its U as everywhere
        shown = format_value(result["AP_mm"], result["U_AP_mm"])
        assert f">{shown}" in html or f" {shown} " in html, (pose, shown)


def test_delta4_with_the_laser_grid_on_the_hardware_path(tmp_path):
    with Store(tmp_path / "b.db") as store:
        result, truth = _rehearsed_run(store, STATIONS / "delta4_lasergrid.toml", EXAMPLES / "delta_positioning.toml")
        assert result.exit_status == "completed", result.reason
        samples = [s for s in store.samples(result.run_id) if s.kind == "pose"]
    assert len(samples) == result.samples > 0
    measured = [s for s in samples if s.values.get("horizontal_valid") == 1]
    assert measured, "no screen decoded a single reading"
    for sample in measured:
        position = np.array([sample.values["x_mm"], sample.values["y_mm"]])
        nearest = truth[np.argmin(np.linalg.norm(truth[:, :2] - position, axis=1)), :2]
        assert np.abs(position - nearest).max() < 2.5  # within one grid phase of the true position


def test_a_station_with_two_instruments_opens_the_one_the_protocol_captures_with(tmp_path):
    """A delta4 bench with a camera and the laser grid: a hit-rate run captures grid hits, which only the grid gives
    (the camera measures a plane and refuses them), and a pose run takes the first registered pose instrument."""
    from bench.rigs.builder import build_rig
    from bench.simulators.station import rehearse

    station = parse_station(
        {
            "robot": {"kind": "delta4"},
            "controller": {"port": "/dev/ttyUSB0"},
            "camera": {"device": "/dev/video0", "calibration": "plane.json"},
            "laser_grid": {},
        },
        source="two.toml",
    )
    assert station.capabilities() == {"assembled", "pose", "grid_hit"}
    rehearsal = rehearse(station, speed_factor=REHEARSAL_SPEED)
    try:
        with Store(tmp_path / "b.db") as store:
            hits = required_capabilities(load_protocol(EXAMPLES / "lasergrid_hits.toml"))
            for requires, instrument in ((hits, "laser grid (controller reports)"), ({"assembled", "pose"}, "camera")):
                rig = build_rig(rehearsal.station, store, requires=requires, speed_factor=REHEARSAL_SPEED)
                try:
                    assert rig.instrument.settings()["instrument"].startswith(instrument)
                finally:
                    rig.close()
    finally:
        rehearsal.close()


class _GaugeReader:
    """The person at the actuator bench: zeroes the depth gauge on an actuator and reads it (the simulator's truth
    log is what the gauge shows)."""

    def __init__(self) -> None:
        self.truth_path = ""
        self.zero_mm: dict[int, float] = {}

    def _strokes(self) -> np.ndarray:
        return _truth(self.truth_path)[-1]

    def ask(self, prompt):
        if prompt.field is None:
            if "zero_actuator" in prompt.conditions:
                axis = int(prompt.conditions["zero_actuator"])
                self.zero_mm[axis] = float(self._strokes()[axis - 1])
            return None
        axis = int(prompt.conditions["actuator"])
        return round(float(self._strokes()[axis - 1] - self.zero_mm[axis]), 2)


def test_the_actuator_bench_with_typed_readings_on_the_hardware_path(tmp_path):
    protocol = tmp_path / "actuators.toml"
    protocol.write_text(
        'protocol = "actuator_accuracy"\nactuators = [2]\ndistances_mm = [10, 20]\nrepeats = 3\nsettle_s = 0.1\n'
    )
    station = tmp_path / "bench.toml"
    station.write_text((STATIONS / "pkm5_actuator_bench.toml").read_text().replace('kind = "serial"', 'kind = "typed"'))
    with Store(tmp_path / "b.db") as store:
        result, _ = _rehearsed_run(store, station, protocol, operator=_GaugeReader())
        assert result.exit_status == "completed", result.reason
        travels = [s.values["travel_mm"] for s in store.samples(result.run_id) if s.kind == "actuator_travel"]
    assert len(travels) == 6
    # the commanded travels, within the seeded actuator's errors (scale sigma 0.3 %, backlash 0.1 mm, noise 0.05 mm)
    np.testing.assert_allclose(travels, [10, 10, 10, 20, 20, 20], atol=0.5)
    assert np.ptp(travels[:3]) < 0.3 and np.ptp(travels[3:]) < 0.3  # repeatable, as 000 Table A.7


def test_the_builder_closes_what_it_opened_when_a_later_device_fails(tmp_path):
    from bench.errors import LinkError
    from bench.rigs.builder import build_rig
    from bench.robots.link import open_port
    from bench.simulators.station import rehearse

    rehearsal = rehearse(load_station(STATIONS / "pkm5_mice.toml"), speed_factor=REHEARSAL_SPEED)
    try:
        broken = rehearsal.station.with_sensor("mice", xz=str(tmp_path / "gone"))
        with Store(tmp_path / "b.db") as store, pytest.raises(LinkError, match="gone"):
            build_rig(broken, store, requires={"pose"}, speed_factor=REHEARSAL_SPEED)
        # the controller's port was released: it opens again, exclusively, and the controller still answers
        port = open_port(rehearsal.station.controller.port, baudrate=115200, timeout=0.05, exclusive=True)
        from bench.robots.pkm5 import Pkm5Controller

        assert Pkm5Controller(port).identify().device == "bench-pkm5"
        port.close()
    finally:
        rehearsal.close()


def test_a_second_process_cannot_take_a_controller_port_in_use(tmp_path):
    from bench.errors import LinkError
    from bench.rigs.builder import build_rig
    from bench.simulators.station import rehearse

    rehearsal = rehearse(load_station(STATIONS / "pkm5_mice.toml"), speed_factor=REHEARSAL_SPEED)
    try:
        with Store(tmp_path / "b.db") as store:
            rig = build_rig(rehearsal.station, store, requires={"pose"}, speed_factor=REHEARSAL_SPEED)
            try:
                with pytest.raises(LinkError, match="controller.port = .*cannot open it"):
                    build_rig(rehearsal.station, store, requires={"pose"}, speed_factor=REHEARSAL_SPEED)
            finally:
                rig.close()
    finally:
        rehearsal.close()


def test_a_rig_built_where_the_robot_is_not_at_home_homes_it_before_registering(tmp_path, caplog):
    """The robot left at P4 by an earlier run (the controller keeps its position) would be registered there as
    if it were home: every reading 37 mm off. The builder brings it home first."""
    from bench.rigs.builder import build_rig
    from bench.simulators.station import rehearse

    p4 = (126.7, 16.3, 303.7)
    capture = Capture("P4", 1)
    rehearsal = rehearse(load_station(STATIONS / "pkm5_mice.toml"), speed_factor=REHEARSAL_SPEED)
    try:
        with Store(tmp_path / "b.db") as store:
            first = build_rig(rehearsal.station, store, requires={"pose"}, speed_factor=REHEARSAL_SPEED)
            try:
                first.robot.move_to(p4, velocity_pct=100)
                before = np.array([first.instrument.measure(capture).values[k] for k in ("x_mm", "y_mm", "z_mm")])
                truth_before = _truth(rehearsal.truth_path)[-1][:3]
            finally:
                first.close()  # the controller stays at P4
            second = build_rig(rehearsal.station, store, requires={"pose"}, speed_factor=REHEARSAL_SPEED)
            try:
                assert "not at home" in caplog.text
                second.robot.move_to(p4, velocity_pct=100)
                after = np.array([second.instrument.measure(capture).values[k] for k in ("x_mm", "y_mm", "z_mm")])
                truth_after = _truth(rehearsal.truth_path)[-1][:3]
            finally:
                second.close()
    finally:
        rehearsal.close()
    # both rigs measure the true pose with a registration offset that is the robot's own error at home, which
    # differs between two visits by its pose repeatability (RP of a few mm, pkm5.md §6.8), not by the 37-39 mm
    # between P4 and home that a registration at P4 gives
    assert np.linalg.norm((after - truth_after) - (before - truth_before)) < 5.0


class _SerialDepthGauge:
    """A depth gauge with a data cable on a pseudo-terminal: each request byte ``?`` is answered with the travel
    since the person zeroed it, read from the simulator's truth log (what the gauge's spindle sees)."""

    def __init__(self, truth_path: str) -> None:
        import os
        import threading
        import tty

        self.truth_path, self.axis, self.zero_mm = truth_path, 0, 0.0
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self._slave = slave
        self._running = True
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def zero_on(self, axis: int) -> None:
        self.axis, self.zero_mm = axis, float(_truth(self.truth_path)[-1][axis - 1])

    def _serve(self) -> None:
        import os
        import select

        while self._running:
            if select.select([self.master], [], [], 0.05)[0] and b"?" in os.read(self.master, 64):
                travel = float(_truth(self.truth_path)[-1][self.axis - 1]) - self.zero_mm
                os.write(self.master, f"{travel:+09.2f}\r".encode())

    def close(self) -> None:
        import os

        self._running = False
        self._thread.join(1.0)
        os.close(self.master)
        os.close(self._slave)


class _PersonAtTheGauge:
    """Confirms instructions, and zeroes the gauge when told to (the serial gauge answers the readings)."""

    def __init__(self, gauge: _SerialDepthGauge) -> None:
        self.gauge = gauge

    def ask(self, prompt):
        assert prompt.field is None, f"the serial gauge should have answered {prompt.text!r}"
        if "zero_actuator" in prompt.conditions:
            self.gauge.zero_on(int(prompt.conditions["zero_actuator"]))
        return None


def test_the_actuator_bench_with_a_serial_depth_gauge_on_the_hardware_path(tmp_path):
    import dataclasses

    from bench.rigs.builder import build_rig
    from bench.simulators.station import rehearse

    protocol_file = tmp_path / "actuators.toml"
    protocol_file.write_text(
        'protocol = "actuator_accuracy"\nactuators = [4]\ndistances_mm = [20]\nrepeats = 3\nsettle_s = 0.1\n'
    )
    protocol = load_protocol(protocol_file)
    station = load_station(STATIONS / "pkm5_actuator_bench.toml")
    rehearsal = rehearse(station, speed_factor=REHEARSAL_SPEED)  # the controller; the gauge is this test's own pty
    gauge = _SerialDepthGauge(rehearsal.truth_path)
    try:
        gauge_spec = dataclasses.replace(station.sensor("calliper"), port=gauge.path, request="?", timeout_s=5.0)
        bench_station = dataclasses.replace(
            rehearsal.station, sensors={**rehearsal.station.sensors, "calliper": gauge_spec}
        )
        with Store(tmp_path / "b.db") as store:
            rig = build_rig(
                bench_station,
                store,
                operator=_PersonAtTheGauge(gauge),
                requires=required_capabilities(protocol),
                protocol=protocol.name,
                speed_factor=REHEARSAL_SPEED,
            )
            try:
                result = Runner(rig, store, progress=False).run(protocol)
            finally:
                rig.close()
            assert result.exit_status == "completed", result.reason
            run = store.run(result.run_id)
            travels = [s.values["travel_mm"] for s in store.samples(result.run_id) if s.kind == "actuator_travel"]
            entries = [s.raw for s in store.samples(result.run_id) if isinstance(s.raw, dict) and "field" in s.raw]
    finally:
        gauge.close()
        rehearsal.close()
    assert run.settings["instrument"]["calliper"]["kind"] == "serial"
    # each reading keeps the gauge's line as sent, beside the value read from it
    from bench.sensors.calliper import parse_length

    assert entries and all(parse_length(raw["typed"]) == raw["entered"] for raw in entries), entries[:2]
    assert len(travels) == 3
    np.testing.assert_allclose(travels, 20.0, atol=0.5)
    assert all(round(t, 2) == t for t in travels)  # the gauge's 0.01 mm display, as sent


@pytest.mark.parametrize(
    "content, message",
    [
        (None, "a folder, expected a protocol file (examples/*.toml)"),
        (b"\xff\xfe\x00binary", "not a text file, expected a protocol TOML file"),
    ],
)
def test_a_protocol_path_that_is_a_folder_or_binary_is_one_line(tmp_path, capsys, content, message):
    path = tmp_path / "p.toml"
    path.mkdir() if content is None else path.write_bytes(content)
    assert main(["run", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"bench: error: {path}: {message}"


def test_station_check_with_one_device_removed_names_that_device_only():
    import os

    from bench.rigs.check import check_station
    from bench.simulators.station import rehearse

    rehearsal = rehearse(load_station(STATIONS / "pkm5_mice.toml"))
    try:
        os.unlink(rehearsal.station.sensor("mice").xz)  # the x-z mouse unplugged
        checks = {check.key: check for check in check_station(rehearsal.station)}
    finally:
        rehearsal.close()
    assert [key for key, check in checks.items() if not check.ok] == ["mice.xz"]
    assert checks["mice.xz"].detail == "no such device" and "by-id" in checks["mice.xz"].fix
    assert checks["mice.xy"].detail.startswith("FIFO or file (not an event device)")


def test_station_check_of_a_delta4_reads_where_the_servos_are_from_their_pots():
    from bench.rigs.check import check_station
    from bench.simulators.station import rehearse

    rehearsal = rehearse(load_station(STATIONS / "delta4_lasergrid.toml"))
    try:
        checks = {check.key: check for check in check_station(rehearsal.station)}
    finally:
        rehearsal.close()
    controller = checks["controller.port"]
    assert controller.ok, controller.line()
    # the simulated controller starts at its home; four pot angles on the 30-170 deg pot scale, 0.549 deg a count
    angles = [float(v) for v in controller.detail.split("pots at ")[1].split(" deg")[0].split(", ")]
    assert len(angles) == 4 and all(30.0 <= a <= 170.0 for a in angles), controller.detail


def test_a_rig_opened_on_a_controller_still_moving_stops_that_move_first(tmp_path):
    # a host killed mid-move leaves the simulated controller (no link watchdog) moving: the next rig must neither
    # fail on ENABLE (BUSY) nor inherit the motion
    import time

    from bench.rigs.builder import build_rig
    from bench.robots import pkm5_wire as wire
    from bench.robots.link import open_port
    from bench.robots.pkm5 import Pkm5Controller
    from bench.simulators.station import rehearse

    # speed factor 200 with a 1 step/s move (the firmware's slowest): the move's 1856 steps last 9.3 s of wall time,
    # while the rig's homing after the stop and its registration moves take a fraction of a second
    speed_factor = 200
    rehearsal = rehearse(load_station(STATIONS / "pkm5_mice.toml"), speed_factor=speed_factor)
    try:
        port = open_port(rehearsal.station.controller.port, baudrate=115200, timeout=0.05, exclusive=True)
        robot = Pkm5Controller(port)
        version = robot.identify().protocol_version
        robot.enable()
        port.write(wire.format_command("MOVE", (2656, 2656, 2669, 2669, 2720, 2720, 1), 99, version))
        port.flush()
        deadline = time.monotonic() + 10
        while robot.position().state != "MOVING":  # the move is under way (9.3 s of wall time)
            assert time.monotonic() < deadline
        port.close()  # the host goes away without a STOP
        with Store(tmp_path / "b.db") as store:
            rig = build_rig(rehearsal.station, store, requires={"pose"}, speed_factor=speed_factor)
            try:
                where = rig.robot.controller.position()
            finally:
                rig.close()
        assert where.state == "IDLE"
    finally:
        rehearsal.close()
