"""PKM5 driver, byte-exact against a scripted port: one test per command, then retries, faults and safety.

Pairs are (command, reply) bodies; ``encode_line`` adds the checksum and newline (checked on their own in
test_robots_pkm5_wire.py).
"""

import re
import threading
import time

import numpy as np
import pytest

from bench.errors import ConfigError, LinkError, LinkTimeout, UnreachableTarget
from bench.robots import pkm5_wire as wire
from bench.robots.pkm5 import ControllerError, Identity, Pkm5Controller, Position
from bench.robots.testing import ScriptedPort, expected_exchange
from bench.simulators.client import SimulatorClient


def exchange(pairs, **kwargs):
    kwargs.setdefault("reply_timeout_s", 0.2)
    return expected_exchange(Pkm5Controller, pairs, frame=wire.encode_line, **kwargs)


# pkm5.md §6.8, Table A.11 point 3-1: (110.52, -0.19, 305.5) mm with reconstructed lengths 200.60 / 200.68 / 200.50
# mm; steps = (L - L0) / CR with L0 = 184 / 192 mm and CR = 0.00625 / 0.003125 mm/step (pkm5.md §2.5, §2.6).
POINT_3_1 = (110.52, -0.19, 305.5, 0.0, 0.0)
POINT_3_1_STEPS = (2656, 2656, 2669, 2669, 2720, 2720)


def test_identify():
    with exchange([("ID #1", "OK #1 ID bench-pkm5 1 1.2.0")]) as robot:
        assert robot.identify() == Identity("bench-pkm5", 1, "1.2.0")
        assert robot.settings()["firmware"] == {
            "device": "bench-pkm5",
            "protocol_version": 1,
            "firmware_version": "1.2.0",
        }


def test_identify_negotiates_crc_lines_with_a_version_2_controller():
    v2 = lambda body: wire.encode_line(body, 2)  # noqa: E731
    with exchange(
        [
            ("ID #1", "OK #1 ID bench-pkm5 2 2.0.0"),
            ("PROTOCOL 2 #2", "OK #2 PROTOCOL 2"),
            (v2("POS #3"), v2("OK #3 POS 800 800 800 800 1600 1600 DISABLED")),
        ]
    ) as robot:
        assert robot.identify() == Identity("bench-pkm5", 2, "2.0.0")
        assert robot.position() == Position((800, 800, 800, 800, 1600, 1600), "DISABLED")
        assert robot.settings()["protocol_version"] == 2


def test_lost_protocol_confirmation_starts_again_from_id():
    with exchange(
        [
            ("ID #1", "OK #1 ID bench-pkm5 2 2.0.0"),
            ("PROTOCOL 2 #2", None),
            ("ID #3", "OK #3 ID bench-pkm5 2 2.0.0"),
            ("PROTOCOL 2 #4", "OK #4 PROTOCOL 2"),
        ]
    ) as robot:
        assert robot.identify().protocol_version == 2


def test_position():
    with exchange([("POS #1", "OK #1 POS 800 800 800 800 1600 1600 DISABLED")]) as robot:
        assert robot.position() == Position((800, 800, 800, 800, 1600, 1600), "DISABLED")


def test_enable():
    with exchange([("ENABLE #1", "OK #1 ENABLE")]) as robot:
        robot.enable()


def test_disable():
    with exchange([("DISABLE #1", "OK #1 DISABLE")]) as robot:
        robot.disable()


def test_set_position():
    with exchange([("SETPOS 800 800 800 800 1600 1600 #1", "OK #1 SETPOS")]) as robot:
        robot.set_position([800, 800, 800, 800, 1600, 1600])


def test_stop():
    with exchange([("STOP #1", "OK #1 STOP 1 2 3 4 5 6")]) as robot:
        assert robot.stop() == Position((1, 2, 3, 4, 5, 6), "IDLE")


def test_move_steps_waits_for_done():
    with exchange(
        [("MOVE 2656 2656 2669 2669 2720 2720 200 #1", ["OK #1 MOVE 9300", "DONE #1 2656 2656 2669 2669 2720 2720"])]
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS


def test_move_to_pose_sends_the_steps_of_the_reference_lengths():
    with exchange(
        [("MOVE 2656 2656 2669 2669 2720 2720 150 #1", ["OK #1 MOVE 100", "DONE #1 2656 2656 2669 2669 2720 2720"])]
    ) as robot:
        assert robot.move_to_pose(POINT_3_1, speed_steps_s=150) == POINT_3_1_STEPS


def test_sim_true_pose():
    with exchange([("SIMTRUE #1", "OK #1 SIMTRUE 110.5 -0.25 305.125 0.5 -0.25")]) as robot:
        np.testing.assert_array_equal(SimulatorClient(robot).true_pose(), [110.5, -0.25, 305.125, 0.5, -0.25])


def test_sim_set_load():
    with exchange([("SIMLOAD 2450 #1", "OK #1 SIMLOAD")]) as robot:
        SimulatorClient(robot).set_load(2.45)


class WritesCounted(ScriptedPort):
    """A scripted port that keeps each write, to see how many commands went out together."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.writes: list[bytes] = []

    def write(self, data: bytes) -> int:
        self.writes.append(bytes(data))
        return super().write(data)


def _trace_pairs(first_tag: int, indices, reply=lambda tag, index: f"OK #{tag} SIMTRACE 40 {index} {index}.5 0 0 0 0"):
    return [(f"SIMTRACE 250 0 100 {index} #{tag}", reply(tag, index)) for tag, index in enumerate(indices, first_tag)]


def test_query_many_keeps_as_many_commands_in_flight_as_the_receive_buffer_holds():
    # 9 lines of 27 bytes (243) fill the 256-byte receive buffer; the tenth (29 bytes with tag 10) would overflow
    # it: its tag is skipped and it opens the next batch
    port = WritesCounted(_trace_pairs(1, range(1, 10)) + _trace_pairs(11, range(10, 12)), wire.encode_line)
    robot = Pkm5Controller(port, reply_timeout_s=0.2)
    replies = robot.query_many("SIMTRACE", [(250, 0, 100, index) for index in range(1, 12)])
    assert [reply.fields[3] for reply in replies] == [f"{index}.5" for index in range(1, 12)]
    assert [len(write) for write in port.writes] == [9 * 27, 2 * 29] and not port.unused
    with pytest.raises(ConfigError, match="query_many: verb = 'MOVE'"):
        robot.query_many("MOVE", [])


def test_a_pipelined_query_refused_as_noise_goes_on_one_command_at_a_time():
    refused = _trace_pairs(
        1,
        [1, 2, 3],
        lambda tag, index: "ERR #1 2 CHECKSUM" if tag == 1 else f"OK #{tag} SIMTRACE 40 {index} stale 0 0 0 0",
    )
    again = _trace_pairs(4, [1, 2, 3])
    again[0] = (b"\n" + wire.encode_line(again[0][0]), again[0][1])  # after noise, a newline first
    with exchange(refused + again) as robot:
        replies = robot.query_many("SIMTRACE", [(250, 0, 100, index) for index in (1, 2, 3)])
    assert [(reply.tag, reply.fields[3]) for reply in replies] == [(4, "1.5"), (5, "2.5"), (6, "3.5")]


def test_stale_and_corrupted_lines_are_dropped():
    with exchange(
        [
            (
                "POS #1",
                [
                    "BOOT #0 bench-pkm5 1 1.0.0",
                    "DONE #77 1 2 3 4 5 6",
                    b"OK #1 POS garbage*00\n",
                    "OK #1 POS 1 2 3 4 5 6 IDLE",
                ],
            )
        ]
    ) as robot:
        assert robot.position().steps == (1, 2, 3, 4, 5, 6)


def test_query_is_retried_after_a_timeout_with_a_new_tag():
    with exchange([("POS #1", None), ("POS #2", "OK #2 POS 1 2 3 4 5 6 IDLE")], retries=1) as robot:
        assert robot.position().state == "IDLE"


def test_late_reply_to_the_abandoned_attempt_is_ignored():
    with exchange(
        [("ID #1", None), ("ID #2", ["OK #1 ID bench-pkm5 1 old", "OK #2 ID bench-pkm5 1 new"])], retries=1
    ) as robot:
        assert robot.identify().firmware_version == "new"


def test_retries_are_bounded_and_the_timeout_names_everything():
    with exchange([("POS #1", None), ("POS #2", None)], retries=1) as robot, pytest.raises(LinkTimeout) as caught:
        robot.position()
    assert re.search(
        r"scripted://: no reply to 'POS' after 0\.2\d* s, expected 'OK #2 \.\.\.' from a "
        r"bench-pkm5 controller; received 0 bytes",
        str(caught.value),
    )


def test_error_reply_raises_controller_error_with_its_code():
    with exchange([("ENABLE #1", "ERR #1 7 BUSY")]) as robot, pytest.raises(ControllerError, match="7 BUSY") as c:
        robot.enable()
    assert c.value.code == wire.ErrorCode.BUSY


def test_wrong_device_identity_is_refused():
    with (
        exchange([("ID #1", "OK #1 ID other-robot 3 9.9")]) as robot,
        pytest.raises(LinkError, match=r"answered 'ID other-robot 3 9.9', expected 'ID bench-pkm5 1 "),
    ):
        robot.identify()


def test_a_device_talking_nonsense_gives_a_timeout_that_says_so():
    with (
        exchange([("ID #1", b"Hello from a GPS\r\n$GPGGA,1*00\r\n")], retries=0) as robot,
        pytest.raises(
            LinkTimeout,
            match=r"dropped 2 invalid or stale lines, first b'Hello from a GPS\\r' "
            r"\(is this a bench-pkm5\?\)",
        ),
    ):
        robot.identify()


@pytest.mark.parametrize(
    "pose, reason",
    [
        ((110.52, -0.19, 405.5, 0, 0), r"leg 1 length 293\.837 mm outside \(184, 244\) mm"),
        ((111.31, 0, 310, 10, 10), "compound rotation"),
        ((110.52, -0.19, 305.5), r"expected 5 finite numbers"),
    ],
)
def test_unreachable_pose_is_refused_before_a_byte_is_sent(pose, reason):
    with exchange([]) as robot, pytest.raises(UnreachableTarget, match=reason):
        robot.move_to_pose(pose)


def test_a_proved_target_is_remembered_per_geometry_and_a_refused_one_is_checked_every_time(monkeypatch):
    import dataclasses

    from bench.robots import pkm5_kinematics
    from motion import pkm5

    solves = []
    solve = pkm5.inverse_kinematics

    def counting(poses, geometry, *args, **kwargs):
        solves.append(geometry)
        return solve(poses, geometry, *args, **kwargs)

    monkeypatch.setattr(pkm5, "inverse_kinematics", counting)
    pkm5_kinematics._proved_steps.cache_clear()
    longer = dataclasses.replace(
        pkm5.DEFAULT_GEOMETRY, leg_length_offset_mm=tuple(v + 0.5 for v in pkm5.DEFAULT_GEOMETRY.leg_length_offset_mm)
    )
    assert pkm5_kinematics.steps_for_pose(POINT_3_1) == POINT_3_1_STEPS
    assert pkm5_kinematics.steps_for_pose(list(POINT_3_1)) == POINT_3_1_STEPS  # the same pose: no second solve
    assert len(solves) == 1
    other = pkm5_kinematics.steps_for_pose(POINT_3_1, longer)  # another geometry proves it again, with its steps
    assert len(solves) == 2 and other != POINT_3_1_STEPS
    for _ in range(2):
        with pytest.raises(UnreachableTarget, match="leg 1 length"):
            pkm5_kinematics.steps_for_pose((110.52, -0.19, 405.5, 0, 0))
    assert len(solves) == 4


def test_steps_outside_the_leg_window_are_refused_before_a_byte_is_sent():
    # 9601 steps = 184 + 60.00625 mm, just past the 244 mm workspace limit of legs 1-4 (pkm5.md §2.4)
    with exchange([]) as robot, pytest.raises(UnreachableTarget, match=r"leg 1 length 244\.006 mm"):
        robot.move_steps([9601, 9601, 800, 800, 1600, 1600])


def test_steps_must_be_six_integers():
    with exchange([]) as robot, pytest.raises(ConfigError, match="expected 6 integers"):
        robot.move_steps([1.5, 2, 3, 4, 5, 6])


def test_lost_move_acceptance_asks_the_position_and_waits_for_done():
    with exchange(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", b"OK #1 MOVE 9\x00300*00\n"),
            (
                b"\n" + wire.encode_line("POS #2"),  # after noise: a resynchronising newline first
                ["OK #2 POS 1000 1000 1000 1000 1800 1800 MOVING", "DONE #1 2656 2656 2669 2669 2720 2720"],
            ),
        ]
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS


def test_lost_move_acceptance_with_the_robot_elsewhere_raises():
    with (
        exchange(
            [
                ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", None),
                ("POS #2", "OK #2 POS 800 800 800 800 1600 1600 IDLE"),
            ],
            heartbeat_s=60,
        ) as robot,
        pytest.raises(
            LinkError,
            match=r"MOVE #1 not confirmed: the controller is IDLE at \(800, 800, 800, 800, "
            r"1600, 1600\), expected a move to \(2656, ",
        ),
    ):
        robot.move_steps(POINT_3_1_STEPS)


def test_the_heartbeat_flows_while_a_lost_move_acceptance_is_awaited():
    """Issue 31 item 10: waiting up to reply_timeout_s for a lost ``OK MOVE`` must not starve the firmware's
    150 ms link watchdog: a POS heartbeat goes out within the wait (beat 50 ms, wait 300 ms); the move's DONE
    arrives after it (without the beat the driver would ask POS after 300 ms and read the DONE as a stale line)."""
    with exchange(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", None),
            ("POS #2", "DONE #1 2656 2656 2669 2669 2720 2720"),
        ],  # the heartbeat, then the DONE
        reply_timeout_s=0.3,
        heartbeat_s=0.05,
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS


def test_missing_done_sends_stop_and_raises():  # a DONE deadline shorter than the heartbeat: one POS at the end
    with (
        exchange(
            [
                ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "OK #1 MOVE 10"),
                ("POS #2", "OK #2 POS 900 900 900 900 1700 1700 MOVING"),
                ("STOP #3", "OK #3 STOP 900 900 900 900 1700 1700"),
            ],
            move_margin_s=0.03,
        ) as robot,
        pytest.raises(LinkTimeout, match=r"no reply to 'MOVE' after 0\.0\d+ s, expected 'DONE #1 \.\.\.'"),
    ):
        robot.move_steps(POINT_3_1_STEPS)


def test_a_lost_done_is_recovered_at_the_deadline_when_pos_shows_the_target():
    with exchange(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "OK #1 MOVE 10"),
            ("POS #2", "OK #2 POS 2656 2656 2669 2669 2720 2720 IDLE"),
        ],
        move_margin_s=0.03,
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS  # and no STOP


def test_a_done_destroyed_by_noise_is_recovered_by_the_heartbeats_pos(caplog):
    with exchange(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", ["OK #1 MOVE 10", b"DONE #1 26\x0056 2*00\n"]),
            (b"\n" + wire.encode_line("POS #2"), "OK #2 POS 2656 2656 2669 2669 2720 2720 IDLE"),
        ]
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS
    # the heartbeat's own POS reply stood for the DONE (inside the wait), not the one last look at the deadline
    recovered = [r for r in caplog.records if "DONE lost" in r.getMessage()]
    assert [r.funcName for r in recovered] == ["_await"]


def test_a_heartbeat_showing_the_robot_elsewhere_is_no_done():
    with exchange(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "OK #1 MOVE 10"),
            ("POS #2", ["OK #2 POS 2000 2000 2000 2000 2000 2000 IDLE", "DONE #1 2656 2656 2669 2669 2720 2720"]),
        ],
        move_margin_s=1.0,
    ) as robot:
        assert robot.move_steps(POINT_3_1_STEPS) == POINT_3_1_STEPS


def test_a_query_refused_as_noise_is_sent_again_after_a_newline():
    with exchange(
        [("POS #1", "ERR #1 1 SYNTAX"), (b"\n" + wire.encode_line("POS #2"), "OK #2 POS 1 2 3 4 5 6 IDLE")], retries=1
    ) as robot:
        assert robot.position().steps == (1, 2, 3, 4, 5, 6)


def test_a_move_refused_as_noise_is_never_sent_again():
    with (
        exchange([("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "ERR #1 1 SYNTAX")], retries=3) as robot,
        pytest.raises(ControllerError, match="controller refused 'MOVE' with error 1 SYNTAX"),
    ):
        robot.move_steps(POINT_3_1_STEPS)


class CtrlCWhileWaitingPort(ScriptedPort):
    """Raises KeyboardInterrupt the first time the driver waits on an empty line (as Ctrl-C would)."""

    armed = True

    def read(self, size=1):
        if not self.in_waiting and self.armed and not self.unused[0][0].startswith(b"MOVE"):
            self.armed = False
            raise KeyboardInterrupt
        return super().read(size)


def test_ctrl_c_during_a_move_sends_stop_then_propagates():
    port = CtrlCWhileWaitingPort(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "OK #1 MOVE 60000"),
            ("STOP #2", ["ERR #1 8 STOPPED 900 900 900 900 1700 1700", "OK #2 STOP 900 900 900 900 1700 1700"]),
        ],
        wire.encode_line,
    )
    robot = Pkm5Controller(port, reply_timeout_s=0.2)
    with pytest.raises(KeyboardInterrupt):
        robot.move_steps(POINT_3_1_STEPS)
    assert port.unused == []


def test_context_exit_on_error_stops_and_closes():
    port = ScriptedPort([("STOP #1", "OK #1 STOP 1 2 3 4 5 6")], wire.encode_line)
    with pytest.raises(RuntimeError), Pkm5Controller(port, reply_timeout_s=0.2):
        raise RuntimeError("operator abort")
    assert port.unused == [] and not port.is_open


def test_shutdown_on_a_dead_link_still_closes_within_the_deadline():
    port = ScriptedPort([("STOP #1", None)], wire.encode_line)
    Pkm5Controller(port, reply_timeout_s=0.05).shutdown()
    assert not port.is_open


def test_settings_and_repr_show_every_setting():
    robot = Pkm5Controller(ScriptedPort([]), speed_steps_s=300, retries=1)
    settings = robot.settings()
    assert settings == {
        "driver": "Pkm5Controller",
        "port": "scripted://",
        "baudrate": 115200,
        "protocol_version": 1,
        "speed_steps_s": 300,
        "reply_timeout_s": 1.0,
        "retries": 1,
        "move_margin_s": 2.0,
        "fixture": "assembled",
        "firmware": None,
    }
    assert repr(robot).startswith(
        "Pkm5Controller(port='scripted://', baudrate=115200, protocol_version=1, speed_steps_s=300"
    )


@pytest.mark.parametrize(
    "name, value",
    [("speed_steps_s", 0), ("speed_steps_s", 5000), ("retries", -1), ("reply_timeout_s", "1"), ("heartbeat_s", 0)],
)
def test_settings_are_checked_on_construction(name, value):
    with pytest.raises(ConfigError, match=f"{name} = {value!r}, expected a number in"):
        Pkm5Controller(ScriptedPort([]), **{name: value})


def test_a_geometry_that_is_not_the_frozen_geometry_is_proved_again_each_time():
    # an object hashed by identity (any plain class) may change between two calls: remembering its proof would
    # send the steps of the geometry it had before
    import dataclasses

    from bench.robots import pkm5_kinematics
    from motion import pkm5

    class Editable:  # e.g. a calibration being edited: attributes of a geometry it holds
        def __init__(self, geometry):
            self.geometry = geometry

        def __getattr__(self, name):
            return getattr(self.__dict__["geometry"], name)

    longer = dataclasses.replace(
        pkm5.DEFAULT_GEOMETRY, leg_length_offset_mm=tuple(v + 0.5 for v in pkm5.DEFAULT_GEOMETRY.leg_length_offset_mm)
    )
    editable = Editable(pkm5.DEFAULT_GEOMETRY)
    assert pkm5_kinematics.steps_for_pose(POINT_3_1, editable) == POINT_3_1_STEPS
    editable.geometry = longer
    assert pkm5_kinematics.steps_for_pose(POINT_3_1, editable) == pkm5_kinematics.steps_for_pose(POINT_3_1, longer)
    assert pkm5_kinematics.steps_for_pose(POINT_3_1, longer) != POINT_3_1_STEPS


def test_a_stop_from_another_thread_is_resent_until_acknowledged():
    """Issue 31 item 11: the first STOP is lost (noise); stop() from another thread sends it again until the waiting
    move reads an acknowledgement, and the move ends STOPPED, not at its target."""
    stopped = "ERR #1 8 STOPPED 900 900 900 900 1700 1700"
    port = ScriptedPort(
        [
            ("MOVE 2656 2656 2669 2669 2720 2720 200 #1", "OK #1 MOVE 9345"),
            (b"\n" + wire.encode_line("STOP #2"), None),  # lost
            (b"\n" + wire.encode_line("STOP #3"), [stopped, "OK #3 STOP 900 900 900 900 1700 1700"]),
        ],
        frame=wire.encode_line,
    )
    robot = Pkm5Controller(port, reply_timeout_s=5.0, heartbeat_s=60)
    outcome = []

    def mover():
        try:
            outcome.append(robot.move_steps(POINT_3_1_STEPS))
        except ControllerError as exc:
            outcome.append(exc.code)

    thread = threading.Thread(target=mover)
    thread.start()
    while len(port.unused) == 3:  # until the MOVE is written (the mover then holds the line)
        threading.Event().wait(0.001)
    assert robot.stop() is None
    thread.join(10)
    assert outcome == [8] and port.unused == []


def test_an_unacknowledged_move_is_not_resent_after_a_stop():
    """Protocol 3 re-sends a MOVE whose OK does not come, but never once stop() was called meanwhile: the re-sent
    MOVE would start a move the operator stopped."""

    def v3(body):
        return wire.encode_line(body, 3)

    port = ScriptedPort(
        [
            ("ID #1", "OK #1 ID bench-pkm5 3 3.0.0"),
            ("PROTOCOL 3 #2", "OK #2 PROTOCOL 3"),
            (v3("MOVE 2656 2656 2669 2669 2720 2720 200 #3"), None),  # its OK lost
            (b"\n" + v3("STOP #4"), v3("OK #4 STOP 800 800 800 800 1600 1600")),
        ],
        frame=wire.encode_line,
    )
    robot = Pkm5Controller(port, reply_timeout_s=0.3, heartbeat_s=60)
    assert robot.identify().protocol_version == 3
    failure = []

    def mover():
        try:
            robot.move_steps(POINT_3_1_STEPS)
        except LinkError as exc:
            failure.append(str(exc))

    thread = threading.Thread(target=mover)
    thread.start()
    while len(port.unused) == 2:  # until the MOVE is written
        threading.Event().wait(0.001)
    assert robot.stop() is None
    thread.join(10)
    assert len(failure) == 1 and "MOVE #3 not re-sent: stop() was called" in failure[0] and port.unused == []
