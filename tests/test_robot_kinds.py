"""The robot registry (bench.robot_kinds): every robot-specific table of bench reads it, so a new robot is its own
files plus one registration. The toy gantry of tests/toy_robot.py is added through register() alone and then is a
robot to stations, pre-flight, protocols and `bench sim --help`."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.cli import main
from bench.errors import ConfigError
from bench.protocols.kinematics import robot_model
from bench.rigs.station import parse_station
from bench.robot_kinds import ROBOT_KINDS, RobotKind, register, robot_kind, robot_names

TOY = RobotKind(
    name="toy",
    title="Cartesian gantry, 3 DOF (a test's toy)",
    baud=57600,
    model="toy_robot",
    home="toy_robot:home_pose",
    travel_time="toy_robot:travel_s",
    simulator="toy_robot",
    simulator_help="the toy gantry (tests/toy_robot.py)",
)


@pytest.fixture()
def toy():
    register(TOY)
    yield TOY
    del ROBOT_KINDS["toy"]


def test_the_shipped_robots_are_registered_with_their_documented_baud_rates():
    assert robot_names()[:2] == ("pkm5", "delta4")
    assert (robot_kind("pkm5").baud, robot_kind("delta4").baud) == (115200, 9600)  # protocol-pkm5.md, 003 §5.3
    assert robot_kind("pkm5").resolved("home")() == pytest.approx((88.649, 0.0, 300.937, 0.0, 0.0), abs=1e-3)
    with pytest.raises(ConfigError, match="--robot scara: expected one of pkm5, delta4"):
        robot_kind("scara")


def test_a_name_registered_twice_with_another_record_is_refused(toy):
    with pytest.raises(ValueError, match="'toy' is registered already"):
        register(dataclasses.replace(toy, baud=9600))


def test_a_toy_robot_is_a_station_robot_with_its_own_baud_rate(toy, tmp_path):
    station = parse_station({"robot": {"kind": "toy"}, "controller": {"port": "/dev/ttyUSB7"}}, source="toy.toml")
    assert (station.robot, station.controller.baud) == ("toy", 57600)
    with pytest.raises(ConfigError, match="controller.fixture = 'actuator-bench', expected one of the toy's fixtures"):
        parse_station(
            {"robot": {"kind": "toy"}, "controller": {"port": "/dev/ttyUSB7", "fixture": "actuator-bench"}},
            source="toy.toml",
        )


def test_a_toy_robot_is_pre_flighted_by_its_own_model(toy):
    model = robot_model("toy")
    check = model.check(model.as_targets([(10.0, 20.0, 30.0), (150.0, 0.0, 0.0)]))
    assert check.reachable.tolist() == [True, False]
    assert "outside the +-100 mm travel" in check.reason[1]
    # 100 mm at 50 % of 50 mm/s: 4 s, from the toy's own travel model
    seconds = model.move_s(np.array([[0.0, 0.0, 0.0]]), np.array([[100.0, 0.0, 0.0]]), np.array([50.0]))
    assert seconds.tolist() == [4.0]
    assert model.home == (0.0, 0.0, 0.0)


def test_a_toy_robot_runs_a_protocol_dry_run(toy, tmp_path, capsys):
    protocol = tmp_path / "toy_pose.toml"
    protocol.write_text(
        'protocol = "iso9283_pose"\nrobot = "toy"\ncycles = 3\nvelocities_pct = [100]\n'
        "cube_centre_mm = [0, 0, 0]\ncube_side_mm = 100\n"
    )
    assert main(["run", str(protocol), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "protocol iso9283_pose on toy: 16 moves, 15 settles, 15 captures" in out  # 5 poses x 3 cycles, home
    # ISO 9283 6.3: P2-P5 on the cube's diagonals at 10 % of their length from the corners: +-40 mm of a 100 mm cube
    assert "P2  (x -40.00 mm, y -40.00 mm, z -40.00 mm)  singularity proximity 1.000  ok" in out


def test_bench_sim_lists_a_registered_robot(toy, capsys):
    with pytest.raises(SystemExit):
        main(["sim", "--help"])
    assert "the toy gantry (tests/toy_robot.py)" in capsys.readouterr().out
