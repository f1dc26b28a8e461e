"""Simulated controllers in-process: the firmware state machines, the seeded error model, and the size of the
simulated errors against the documents' measured figures (pkm5.md §6.8, delta4-lasergrid.md §7.2)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.robots import delta4_wire as dwire
from bench.robots import pkm5_kinematics as kin
from bench.robots import pkm5_wire as wire
from bench.simulators import pkm5_plant
from bench.simulators.delta4 import Delta4SimDevice
from bench.simulators.delta4 import build_plant as delta4_plant
from bench.simulators.error_model import ErrorMagnitudes, ErrorModel, JointMemory
from bench.simulators.pkm5 import Pkm5SimDevice
from bench.simulators.pty import TruthLog, read_last_truth
from motion import delta4


def still(steps, load_kg):
    return np.zeros(5)


def lines(data):
    return [wire.decode_line(line) for line in data.split(b"\n") if line]


@pytest.fixture
def pkm5_device():
    device = Pkm5SimDevice(still, speed_factor=10.0)
    assert lines(device.tick(0.0)) == ["BOOT #0 bench-pkm5 3 1.0.0-sim"]
    return device


def send(device, body, now_s):
    return lines(device.feed(wire.encode_line(body), now_s))


def test_pkm5_move_runs_in_scaled_time_and_reports_done(pkm5_device):
    assert send(pkm5_device, "MOVE 2800 800 800 800 1600 1600 200 #1", 0.0) == ["ERR #1 6 DISABLED"]
    assert send(pkm5_device, "ENABLE #2", 0.0) == ["OK #2 ENABLE"]
    # 2000 steps at 200 steps/s = 10 s, run 10x faster -> 1000 ms
    assert send(pkm5_device, "MOVE 2800 800 800 800 1600 1600 200 #3", 0.0) == ["OK #3 MOVE 1000"]
    assert send(pkm5_device, "POS #4", 0.5) == ["OK #4 POS 1800 800 800 800 1600 1600 MOVING"]
    assert send(pkm5_device, "SETPOS 1 2 3 4 5 6 #5", 0.5) == ["ERR #5 7 BUSY"]
    assert lines(pkm5_device.tick(0.99)) == []
    assert lines(pkm5_device.tick(1.0)) == ["DONE #3 2800 800 800 800 1600 1600"]


def test_pkm5_stop_ends_the_move_where_it_is(pkm5_device):
    send(pkm5_device, "ENABLE #1", 0.0)
    send(pkm5_device, "MOVE 2800 2800 2800 2800 1600 1600 200 #2", 0.0)
    assert send(pkm5_device, "STOP #3", 0.25) == [
        "ERR #2 8 STOPPED 1300 1300 1300 1300 1600 1600",
        "OK #3 STOP 1300 1300 1300 1300 1600 1600",
    ]
    assert lines(pkm5_device.tick(5.0)) == []


@pytest.mark.parametrize(
    "raw, reply",
    [
        (b"POS #1*00\n", "ERR #0 2 CHECKSUM"),
        (wire.encode_line("JUMP #4"), "ERR #4 1 SYNTAX"),
        (wire.encode_line("MOVE 1 2 3 4 5 6 0 #5"), "ERR #5 4 ARGUMENT"),
        (wire.encode_line("MOVE 99999 2 3 4 5 6 200 #6"), "ERR #6 5 LIMIT"),
        (b"A" * 300 + b"\n", "ERR #0 3 TOO_LONG"),
    ],
)
def test_pkm5_refusals_carry_their_code(pkm5_device, raw, reply):
    send(pkm5_device, "ENABLE #9", 0.0)
    assert lines(pkm5_device.feed(raw, 0.0)) == [reply]


def test_pkm5_line_split_across_reads_is_joined(pkm5_device):
    line = wire.encode_line("ID #7")
    assert pkm5_device.feed(line[:3], 0.0) == b""
    assert lines(pkm5_device.feed(line[3:], 0.0)) == ["OK #7 ID bench-pkm5 3 1.0.0-sim"]


def test_pkm5_simulator_only_commands(pkm5_device):
    assert send(pkm5_device, "SIMLOAD 2450 #1", 0.0) == ["OK #1 SIMLOAD"] and pkm5_device.load_kg == 2.45
    assert send(pkm5_device, "SIMTRUE #2", 0.0) == ["OK #2 SIMTRUE 0.0000 0.0000 0.0000 0.0000 0.0000"]


def test_pkm5_truth_log_gets_each_settled_pose(tmp_path):
    path = tmp_path / "truth.jsonl"
    device = Pkm5SimDevice(
        lambda steps, load: np.array([1.0, 2.0, 3.0, 4.0, float(steps[0])]),
        truth=TruthLog(path, ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg")),
    )
    device.feed(wire.encode_line("SETPOS 900 800 800 800 1600 1600 #1"), 0.0)
    entry = read_last_truth(path)
    assert entry["seq"] == 1 and entry["pose"] == [1.0, 2.0, 3.0, 4.0, 900.0]
    assert entry["commanded"] == [900, 800, 800, 800, 1600, 1600]


def test_the_newest_truth_entry_is_read_from_the_log_s_tail_past_a_line_being_written(tmp_path):
    path = tmp_path / "truth.jsonl"
    log = TruthLog(path, ("x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg"))
    assert read_last_truth(path) is None
    for k in range(200):  # ~60 kB: far more than the tail that is read
        log.record([k] * 6, [k + 0.123456789, 0.0, 300.0, 0.0, 0.0], 0.0)
    assert path.stat().st_size > 40_000
    entry = read_last_truth(path)
    assert entry["seq"] == 200 and entry["pose"][0] == 199.123456789
    with path.open("a") as handle:
        handle.write('{"seq": 201, "pose": [1.0, ')  # the simulator is writing the next one
    assert read_last_truth(path)["seq"] == 200
    path.write_text('{"seq": 1, "pose": [2.0]}\n' + "x" * 9000)  # nothing complete in the tail: the whole file
    assert read_last_truth(path) == {"seq": 1, "pose": [2.0]}


def delta_device(**kwargs):
    return Delta4SimDevice(
        lambda q, load: np.zeros(3), dwire.LegacyVbMapping(), home_servo_deg=np.full(4, 71.66), **kwargs
    )


def test_delta4_references_while_stopped_are_stored_and_z_follows_start():
    device = delta_device(speed_factor=1.0)
    assert device.feed(b"P174XQ170XR099XS105X", 0.0) == b"" and list(device.references) == [174, 170, 99, 105]
    assert device.tick(5.0) == b""  # stopped: no z, no reports
    device.feed(b"E", 10.0)
    # worst servo 129.65 - 71.66 = 57.99 deg: ln(57.99 / (140/255)) / 4 s + 10 x 2 ms = 1.1863 s
    assert device.tick(10.0) == b"hv"
    assert b"z" not in device.tick(11.18)
    assert device.tick(11.19).startswith(b"z")


def test_delta4_malformed_messages_are_discarded_and_t_is_ignored():
    device = delta_device()
    device.feed(b"E", 0.0)
    device.feed(b"P12Q100XR1234XS9X T P300X", 0.0)
    assert list(device.references) == [96, 100, 96, 9]  # home bytes round_half_up(71.66 * 255/190) = 96


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 3), st.integers(0, 18000), st.binary(max_size=12))
def test_delta4_fine_references_set_the_angle_on_the_tick_whatever_came_before(servo, value, noise):
    """F<n><ddddd>X after any bytes (ended by X, which ends any message) sets servo n to value x 0.01 deg on the
    firmware's 0.01125 deg tick: the nearest tick within half a tick; the byte references of the others stay."""
    device = delta_device()
    device.feed(b"E" + noise.replace(b"G", b"") + b"X", 0.0)
    before = device.reference_deg.copy()
    device.feed(dwire.format_fine_command(servo, value), 0.0)
    tick = 180 / 16000
    assert abs(device.reference_deg[servo] - value / 100) <= tick / 2 + 1e-9
    assert device.reference_deg[servo] / tick == pytest.approx(round(device.reference_deg[servo] / tick), abs=1e-6)
    others = [i for i in range(4) if i != servo]
    assert list(device.reference_deg[others]) == list(before[others])
    assert device.feed(b"C", 0.0).endswith(b"c01125X")


def test_delta4_stop_ends_reports_and_sensor_hook_formats_hits():
    device = Delta4SimDevice(
        lambda q, load: np.zeros(3),
        dwire.LegacyVbMapping(),
        sensor=lambda pose: ((17, 18), ()),
        home_servo_deg=np.full(4, 71.66),
    )
    device.feed(b"E", 0.0)
    assert device.tick(0.0) == b"H017XH018Xv"
    assert device.tick(0.08) == b"H017XH018Xv"
    device.feed(b"G", 0.1)
    assert device.tick(0.2) == b""


def test_backlash_depends_on_the_approach_direction():
    model = ErrorModel.ideal(1, 1)
    model = ErrorModel(**{**model.__dict__, "backlash": np.array([0.2])})
    memory = JointMemory(np.array([0.0]))
    rng = np.random.default_rng(0)
    from_below = model.true_joints(np.array([5.0]), memory.update(np.array([5.0])), 0.0, rng)
    memory.update(np.array([9.0]))
    from_above = model.true_joints(np.array([5.0]), memory.update(np.array([5.0])), 0.0, rng)
    assert from_above - from_below == pytest.approx([0.2])


def test_load_sag_and_assembly_bias_add_to_the_pose():
    magnitudes = ErrorMagnitudes(0, 0, 0, 0, 0, 0, (0.0, 0.0), (0.0, -0.03), (0.0, 0.0))
    model = ErrorModel.draw(magnitudes, 2, seed=1)
    pose = model.true_pose(np.array([1.0, 300.0]), np.zeros(2), 25.0, np.random.default_rng(0))
    assert pose == pytest.approx([1.0, 300.0 - 0.75])


def test_same_seed_same_robot_other_seed_other_robot():
    steps = np.array(kin.steps_for_pose((110.52, -0.19, 305.5, 0, 0)))
    first, second, other = pkm5_plant.build_plant(5), pkm5_plant.build_plant(5), pkm5_plant.build_plant(6)
    assert np.array_equal(first(steps, 0.0), second(steps, 0.0))
    assert not np.allclose(first(steps, 0.0), other(steps, 0.0))


def test_ideal_pkm5_plant_attains_the_commanded_pose_within_step_quantisation():
    # Table A.11 point 3-1; one step is 0.00625 mm (legs 1-4) / 0.003125 mm (legs 5-6)
    steps = np.array(kin.steps_for_pose((110.52, -0.19, 305.5, 0, 0)))
    pose = pkm5_plant.build_plant(0, ideal=True)(steps, 0.0)
    np.testing.assert_allclose(pose, [110.52, -0.19, 305.5, 0, 0], atol=0.01)


# Table A.11 (pkm5.md §6.8): the 15 translation test points, mm
TABLE_A11 = np.array(
    [
        (170.67, -91.43, 268.83),
        (171.83, -98.75, 264.29),
        (163.49, -86.82, 275.46),
        (167.59, -36.14, 293.74),
        (174.87, -47.07, 293.64),
        (151.93, -71.93, 292.72),
        (110.52, -0.19, 305.5),
        (99.12, -18.53, 345.4),
        (177.3, 19.54, 294.36),
        (139.28, 33.52, 312.11),
        (142.83, 46.43, 302.21),
        (145.77, 67.62, 304.64),
        (160.7, 86.19, 281.34),
        (130.6, 91.48, 297.3),
        (130.06, 105.95, 292.9),
    ]
)


def ap_rp(attained, commanded):
    """ISO 9283 AP and RP (pkm5.md §6.8 Eqs. 8.4-8.14), computed here independently of bench.reports."""
    barycentre = attained.mean(axis=0)
    spread = np.linalg.norm(attained - barycentre, axis=1)
    return np.linalg.norm(barycentre - commanded), spread.mean() + 3 * spread.std(ddof=1)


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_pkm5_campaign_errors_are_of_the_documents_order(seed):
    """Document (000 §8.6.5): AP 1.17-1.91 mm, RP 1.56-2.71 mm over these points, 10 cycles from home."""
    plant, home = pkm5_plant.build_plant(seed), kin.home_steps()
    figures = []
    for point in TABLE_A11:
        steps = np.array(kin.steps_for_pose((*point, 0, 0)))
        attained = []
        for _ in range(10):
            plant(home, 0.0)
            attained.append(plant(steps, 0.0)[:3])
        figures.append(ap_rp(np.array(attained), point))
    ap, rp = np.array(figures).T
    assert 0.5 < np.median(ap) < 2.5 and ap.max() < 4.0
    assert 1.0 < np.median(rp) < 3.0 and rp.max() < 4.0


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_delta4_positioning_errors_are_of_the_documents_order(seed):
    """Document (delta4-lasergrid.md §7.2): axial maxima 2/3/3 mm, spatial maximum about 4 mm, 3 poses x 15."""
    plant, home = delta4_plant(seed)
    mapping, errors = dwire.LegacyVbMapping(), []
    for point in [(0.0, 0.0, -200.0), (-70.0, -70.0, -180.0), (50.0, -50.0, -160.0)]:
        servo = mapping.to_deg(mapping.to_bytes(delta4.inverse_kinematics(np.array([point])).servo_deg[0]))
        for _ in range(15):
            plant(home, 0.0)
            errors.append(plant(servo, 0.0) - point)
    errors = np.array(errors)
    assert np.all((1.5 < np.abs(errors).max(axis=0)) & (np.abs(errors).max(axis=0) < 4.5))
    assert 2.5 < np.linalg.norm(errors, axis=1).max() < 5.5


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=40), max_size=8))
def test_simulated_controllers_survive_arbitrary_input(chunks):
    pkm5_device, delta = Pkm5SimDevice(still), delta_device()
    for i, chunk in enumerate(chunks):
        for line in pkm5_device.feed(chunk + b"\n", float(i)).splitlines():
            reply = wire.parse_reply(line)  # whatever came in, what goes out is well-formed
            assert reply.kind in ("OK", "ERR", "BOOT", "DONE")
        out = delta.feed(chunk, float(i)) + delta.tick(float(i) + 0.5)
        assert set(out) <= set(b"zhvHVpqrscX0123456789")  # pqrs: the answer to the pot query A; c: to C
