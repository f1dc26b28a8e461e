"""delta4 driver and wire protocol: byte mappings against delta4-lasergrid.md §5.6/§5.8, byte-exact exchanges,
token framing fuzzed with hypothesis."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, LinkTimeout, UnreachableTarget
from bench.robots import delta4_wire as wire
from bench.robots.delta4 import Delta4Controller
from bench.robots.link import WireProtocolError
from bench.robots.testing import ScriptedPort, expected_exchange

# delta4-lasergrid.md §5.6 "Move to TV4": Fig. 60 angles and the bytes the VB formula gives for them.
TV4_WHOLE_DEG = (60.0, 54.0, 91.0, 95.0)
TV4_EXACT_DEG = (59.5102, 54.0404, 90.6811, 94.6176)


def exchange(pairs, **kwargs):
    return expected_exchange(Delta4Controller, pairs, **kwargs)


def test_legacy_mapping_reproduces_the_documented_tv4_bytes():
    mapping = wire.LegacyVbMapping()
    assert list(mapping.to_bytes(np.array(TV4_WHOLE_DEG))) == [81, 72, 122, 128]  # 127.5 rounds half up
    assert list(mapping.to_bytes(np.array(TV4_EXACT_DEG))) == [80, 73, 122, 127]
    # §5.8: 160 deg -> 214.7 -> 215, 30 deg -> 40.3 -> 40
    assert list(mapping.to_bytes(np.array([160.0, 30.0, 30.0, 30.0]))) == [215, 40, 40, 40]


def test_calibrated_mapping_spans_the_stops_in_both_directions():
    forward = wire.CalibratedMapping()
    assert list(forward.to_bytes(np.array([30.0, 170.0, 100.0, 65.0]))) == [0, 255, 128, 64]  # 127.5 -> 128
    literal = wire.CalibratedMapping(direction=(-1, -1, -1, -1))
    assert list(literal.to_bytes(np.array([30.0, 170.0, 100.0, 65.0]))) == [255, 0, 128, 191]
    np.testing.assert_allclose(forward.to_deg(np.array([0, 255, 51, 204])), [30, 170, 58, 142])


def test_calibrated_mapping_refuses_bad_stops():
    with pytest.raises(ValueError, match="expected 4 \\(low, high\\) pairs"):
        wire.CalibratedMapping(stops_deg=((30, 20),) * 4)


def test_servo_command_is_three_digits_and_x():
    assert wire.format_servo_command(0, 135) == b"P135X"  # §5.4: 135 -> '1' '3' '5' 'X'
    assert wire.format_servo_command(3, 7) == b"S007X"


def test_start_sends_e_and_returns_the_first_report():
    with exchange([("E", "hv")]) as robot:
        frame = robot.start()
    assert (frame.horizontal, frame.vertical, frame.raw) == ((), (), b"hv") and robot.started


def test_stop_sends_g():
    with exchange([("G", None)]) as robot:
        robot.stop()
        assert not robot.started


def test_move_servos_sends_the_four_references_and_acknowledges_z():
    with exchange([("P080XQ073XR122XS127X", "z"), ("z", None)]) as robot:
        result = robot.move_servos(TV4_EXACT_DEG)
    assert result.command_bytes == (80, 73, 122, 127) and result.settled


def test_move_to_converts_the_point_through_motion_delta4():
    # TV4: IK(3.05, -3.99, -15) cm gives the exact angles above (delta4-lasergrid.md §3)
    with exchange([("P080XQ073XR122XS127X", "z"), ("z", None)]) as robot:
        result = robot.move_to((30.5, -39.9, -150.0))
    np.testing.assert_allclose(result.servo_deg, TV4_EXACT_DEG, atol=1e-3)


def test_missing_z_is_reported_but_not_required_by_default():
    with exchange([("P080XQ073XR122XS127X", None)], settle_timeout_s=0.05) as robot:
        assert robot.move_servos(TV4_EXACT_DEG).settled is False


def test_missing_z_raises_when_required_naming_the_command():
    with (
        exchange([("P080XQ073XR122XS127X", None)], settle_timeout_s=0.05) as robot,
        pytest.raises(
            LinkTimeout,
            match=r"scripted://: no reply to 'P080XQ073XR122XS127X' after 0\.0\d+ s, "
            r"expected 'z' \(all servos in place\); received 0 bytes",
        ),
    ):
        robot.move_servos(TV4_EXACT_DEG, require_settled=True)


def test_a_z_already_on_the_wire_is_not_taken_for_the_new_move():
    port = ScriptedPort([("z", None), ("P080XQ073XR122XS127X", None)])  # the stale z is acknowledged first
    port._readable += b"z"
    robot = Delta4Controller(port, settle_timeout_s=0.05)
    assert robot.move_servos(TV4_EXACT_DEG).settled is False


def test_sensor_reports_are_assembled_per_frame():
    with exchange([("E", b"H017XH018XV200XhV033X034Xv017Xv")]) as robot:
        first = robot.start()
        second = robot.read_sensor_frame(0.5)
        third = robot.read_sensor_frame(0.5)
    assert (first.horizontal, first.vertical) == ((17, 18), (200,))  # closed by the next frame's 'h'
    assert (second.horizontal, second.vertical) == ((), (33, 34))
    assert (third.horizontal, third.vertical, third.raw) == ((17,), (), b"017Xv")  # untagged: horizontal first


def test_noise_between_tokens_is_dropped():
    with exchange([("E", b"#\x00H017X?H9999XV001X")]) as robot:
        frame = robot.start()
    assert (frame.horizontal, frame.vertical) == ((17,), (1,))


def test_read_pots_sends_a_and_converts_the_counts_on_the_adc_scale():
    # TV4's whole-degree angles on the pot scale (delta4-lasergrid.md §5.8 b): round_half_up(255 (theta - 30) / 140)
    with exchange([("A", b"hp055Xq044XvH017Xr111Xp000Xq044Xr111Xs118X")]) as robot:
        reading = robot.read_pots()  # a sensor report around it is kept; a broken answer (p q r p) is dropped
        frame = robot.read_sensor_frame(0.5)
    assert reading.counts == (0, 44, 111, 118) and robot.last_pots == reading
    np.testing.assert_allclose(
        reading.servo_deg, [30.0, 30 + 44 * 140 / 255, 30 + 111 * 140 / 255, 30 + 118 * 140 / 255]
    )
    assert np.all(np.abs(np.array(reading.servo_deg[1:]) - TV4_WHOLE_DEG[1:]) <= 140 / 255 / 2)
    assert (frame.horizontal, frame.vertical) == ((), ())


def test_read_pots_from_firmware_without_readback_names_the_query():
    with (
        exchange([("A", None)]) as robot,
        pytest.raises(
            LinkTimeout,
            match=r"no reply to 'A \(read pots\)'.*"
            r"firmware with pot readback",
        ),
    ):
        robot.read_pots(timeout_s=0.05)


def test_silence_after_start_means_no_delta4_controller():
    with (
        exchange([("E", None)]) as robot,
        pytest.raises(
            LinkTimeout,
            match=r"'E \(start\)'.*expected a sensor "
            r"report \(H<n>X, V<n>X, h or v\)",
        ),
    ):
        robot.start(verify_timeout_s=0.05)


@pytest.mark.parametrize(
    "angles, message",
    [
        ((20.0, 90, 90, 90), r"servo 1: theta_R = 20\.000 deg, expected within \[30, 160\] deg \(mapping legacy_vb\)"),
        ((90, 90, 90, 165.0), r"servo 4: theta_R = 165\.000 deg"),
        ((90, 90, 90), "expected 4 finite angles"),
    ],
)
def test_out_of_range_servo_angles_are_refused_before_a_byte_is_sent(angles, message):
    with exchange([]) as robot, pytest.raises(UnreachableTarget, match=message):
        robot.move_servos(angles)


def test_calibrated_mapping_accepts_up_to_170_degrees():
    with exchange([("P128XQ128XR128XS255X", "z"), ("z", None)], mapping=wire.CalibratedMapping()) as robot:
        assert robot.move_servos((100, 100, 100, 170)).settled


def test_unreachable_point_is_refused_before_a_byte_is_sent():
    with (
        exchange([]) as robot,
        pytest.raises(
            UnreachableTarget,
            match=r"point_mm = \(0\.0, 0\.0, -300\.0\): "
            r"unreachable",
        ),
    ):
        robot.move_to((0.0, 0.0, -300.0))


def test_shutdown_sends_g_and_closes():
    port = ScriptedPort([("G", None)])
    with Delta4Controller(port):
        pass
    assert port.unused == [] and not port.is_open


def test_settings_and_repr():
    robot = Delta4Controller(ScriptedPort([]), settle_timeout_s=1.5)
    assert robot.settings() == {
        "driver": "Delta4Controller",
        "port": "scripted://",
        "baudrate": 115200,
        "mapping": {"name": "legacy_vb", "degrees_per_span": 190.0, "limits_deg": [30.0, 160.0]},
        "settle_timeout_s": 1.5,
        "frame_gap_s": 0.03,
        "pot_scale": {"name": "calibrated", "stops_deg": [[30.0, 170.0]] * 4, "direction": [1, 1, 1, 1]},
        "heartbeat_s": None,
        "fine_reference": {"in_use": False, "reason": "not probed: byte references"},
    }
    assert "mapping={'name': 'legacy_vb'" in repr(robot)
    with pytest.raises(ConfigError, match=r"settle_timeout_s = 0, expected a number in \(0, 600\] s"):
        Delta4Controller(ScriptedPort([]), settle_timeout_s=0)


# Fine servo references (docs/protocol-delta4.md "Fine servo references"): TV4's exact angles in 0.01 deg
TV4_FINE = (5951, 5404, 9068, 9462)


def test_a_controller_answering_c_gets_fine_references_on_its_pwm_tick():
    with exchange([("C", "hvc01125X"), ("F105951XF205404XF309068XF409462X", "z"), ("z", None)]) as robot:
        fine = robot.probe_fine_references()
        assert robot.probe_fine_references() is fine  # cached for the connection: one C on the wire
        result = robot.move_servos(TV4_EXACT_DEG)
        frame = robot.read_sensor_frame(0.5)  # a report read around the answer is kept
    assert (result.fine_values, result.command_bytes, result.settled) == (TV4_FINE, (), True)
    assert (frame.horizontal, frame.vertical) == ((), ())
    assert fine.controller_step_deg == pytest.approx(0.01125)
    # the firmware's pulse: round_half_up(16000 + value * 16000 / 18000) ticks; 5951 -> 5289.8 -> 5290 ticks above
    # 1 ms, i.e. 5290 * 180 / 16000 = 59.5125 deg, within half a tick of the angle asked for
    assert fine.to_deg(np.array([5951]))[0] == pytest.approx(59.5125)
    assert np.all(np.abs(fine.sent_deg(np.array(TV4_EXACT_DEG)) - TV4_EXACT_DEG) <= 0.005 + 0.01125 / 2)
    settings = robot.settings()["fine_reference"]
    assert settings == {
        "in_use": True,
        "probed": True,
        "name": "fine_centidegree",
        "degrees_per_unit": 0.01,
        "controller_step_deg": pytest.approx(0.01125),
        "limits_deg": [30.0, 170.0],
    }
    assert wire.fine_from_settings(settings) == fine


def test_a_controller_silent_to_c_keeps_the_byte_references_and_says_why(caplog):
    with exchange([("C", None), ("P080XQ073XR122XS127X", "z"), ("z", None)]) as robot:
        assert robot.probe_fine_references(timeout_s=0.05) is None
        result = robot.move_servos(TV4_EXACT_DEG)
    assert (result.command_bytes, result.fine_values) == ((80, 73, 122, 127), ())
    reason = "no answer to C within 0.05 s: byte references (legacy_vb, 0.745 deg a step)"
    assert robot.settings()["fine_reference"] == {"in_use": False, "probed": True, "reason": reason}
    assert reason in caplog.text


def test_fine_references_keep_the_byte_window_and_the_firmware_stops_before_sending():
    wide = wire.CalibratedMapping(((25.0, 175.0),) * 4)
    with exchange([("C", "c01125X")], mapping=wide) as robot:
        robot.probe_fine_references()
        with pytest.raises(
            UnreachableTarget,
            match=r"servo 2: theta_R = 172\.000 deg, expected within \[30, 170\] "
            r"deg \(fine references\)",
        ):
            robot.move_servos((90, 172.0, 90, 90))
    with exchange([("C", "c01125X")]) as robot:  # legacy_vb's 160 deg still holds
        robot.probe_fine_references()
        with pytest.raises(UnreachableTarget, match=r"servo 1: theta_R = 165\.000 deg.*mapping legacy_vb"):
            robot.move_servos((165.0, 90, 90, 90))


def test_fine_command_and_capability_tokens():
    assert wire.format_fine_command(0, 7166) == b"F107166X" and wire.format_fine_command(3, 18000) == b"F418000X"
    with pytest.raises(ValueError, match="value 0-18000"):
        wire.format_fine_command(0, 18001)
    assert wire.parse_token(b"c01125X") == wire.Token("c", 1125)
    assert wire.format_capability_reply(0.09) == b"c09000X"
    for bad in (b"c0112X", b"c00000X", b"c123456X"):
        with pytest.raises(WireProtocolError):
            wire.parse_token(bad)
    assert list(_BytesLink(b"c01125Xz").frames()) == [b"c01125X", b"z"]


class _BytesLink(wire.Delta4Link):
    def __init__(self, data):
        super().__init__(None)
        self._pending += data

    def frames(self):
        while (frame := self._take_frame()) is not None:
            yield frame


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=80))
def test_framing_and_token_parser_raise_only_the_protocol_error(data):
    for frame in _BytesLink(data).frames():
        try:
            wire.parse_token(frame)
        except WireProtocolError:
            pass


tokens = st.one_of(
    st.sampled_from([b"z", b"h", b"v"]),
    st.builds(
        lambda k, v: k + b"%03dX" % v, st.sampled_from([b"H", b"V", b"", b"p", b"q", b"r", b"s"]), st.integers(0, 255)
    ),
)


@settings(max_examples=200, deadline=None)
@given(st.lists(tokens, max_size=12))
def test_valid_token_streams_split_back_into_their_tokens(stream):
    assert list(_BytesLink(b"".join(stream)).frames()) == stream
