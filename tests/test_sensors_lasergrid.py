"""Laser grid: every decoding example of delta4-lasergrid.md §4.4 (Figs. 10 a-f, 11 a-h), the caption collisions
of §4.7, the blind phases and coverage table of §4.5, the D2 repeatability model of §4.10, and round trips."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError
from bench.sensors import MalformedSample, Sensor
from bench.sensors.lasergrid import (
    LASER_OFFSETS_MM,
    GridFrame,
    GridGeometry,
    LaserGridSensor,
    Screen,
    ScreenStatus,
    decode_frame,
    decode_screen,
    parse_report,
)
from bench.simulators.lasergrid import (
    P_MISS_AT_DISTANCE,
    LaserGridSimulator,
    format_report,
)

GEOMETRY = GridGeometry()
H = GEOMETRY.horizontal
I0, J0 = 7, 7  # BE starts on sensor s(i, j) = s(7, 7), at (-5, -5) mm
START = H.centre_mm(I0, J0)

# (caption, BE net displacement (mm), sensor hit as (di, dj) from s(i, j), laser) -- §4.4 caption table
CAPTIONS = [
    ("10a", (5, 0), (2, 0), "G5-a"),
    ("10b", (-5, 0), (1, 0), "G5-a"),
    ("10c", (0, -5), (0, -2), "G5-b"),
    ("10d", (0, 5), (0, -1), "G5-b"),
    ("10e", (5, 5), (2, -1), "G5-c"),
    ("10f", (-5, -5), (1, -2), "G5-c"),
    ("11a", (2.5, 0), (-2, 0), "G2.5-W"),
    ("11b", (2.5, -2.5), (-2, 2), "G2.5-NW"),
    ("11c", (0, -2.5), (0, 2), "G2.5-N"),
    ("11d", (-2.5, -2.5), (2, 2), "G2.5-NE"),
    ("11e", (-2.5, 0), (2, 0), "G2.5-E"),
    ("11f", (-2.5, 2.5), (2, -2), "G2.5-SE"),
    ("11g", (0, 2.5), (0, -2), "G2.5-S"),
    ("11h", (2.5, 2.5), (-2, -2), "G2.5-SW"),
]


def pose(be_xy, z_mm=-150.0):
    return np.array([be_xy[0], be_xy[1], z_mm])


@pytest.mark.parametrize("caption, shift, cell_shift, laser", CAPTIONS, ids=[c[0] for c in CAPTIONS])
def test_document_captions_simulate_and_decode(caption, shift, cell_shift, laser):
    true_xy = START + shift
    frame = LaserGridSimulator(spot_half_width_mm=0.5).frames(pose(true_xy)[None])[0]
    expected_index = H.index_of_cell(I0 + cell_shift[0], J0 + cell_shift[1])
    assert frame.horizontal == (expected_index,)
    result = decode_frame(GEOMETRY, frame.horizontal, frame.vertical, pose(true_xy))
    assert result.horizontal.status is ScreenStatus.OK and result.horizontal.lasers == (laser,)
    assert result.position_mm[:2] == pytest.approx(tuple(true_xy))
    # a prior off by up to 3 mm on both axes still decodes to the same 2.5 mm position (§4.7: < 3.75 mm)
    for prior_error in ((3.0, -3.0), (-3.0, 3.0)):
        again = decode_frame(GEOMETRY, frame.horizontal, [], pose(true_xy + prior_error))
        assert again.position_mm[:2] == pytest.approx(tuple(true_xy))
        assert again.error_mm[:2] == pytest.approx((-prior_error[0], -prior_error[1]))


@pytest.mark.parametrize("cell_shift, shifts", [((2, 0), ((5, 0), (-2.5, 0))), ((0, -2), ((0, -5), (0, 2.5)))])
def test_colliding_captions_are_resolved_by_the_prior(cell_shift, shifts):
    # §4.7: s(i+2, j) is both Fig. 10 a (+5, 0) and Fig. 11 e (-2.5, 0); s(i, j-2) both 10 c and 11 g
    index = int(H.index_of_cell(I0 + cell_shift[0], J0 + cell_shift[1]))
    for shift in shifts:
        decoded = decode_screen(H, [index], START + shift)
        assert decoded.status is ScreenStatus.OK and decoded.be_mm == pytest.approx(tuple(START + shift))
    midway = decode_screen(H, [index], START + np.mean(shifts, axis=0) + 0.1, prior_uncertainty_mm=5.0)
    assert midway.status is ScreenStatus.AMBIGUOUS


def test_offsets_occupy_twelve_distinct_phases_and_candidates_are_7_5_mm_apart():
    phases = {tuple(p) for p in np.mod(LASER_OFFSETS_MM, 10.0)}
    assert len(phases) == 12
    diffs = LASER_OFFSETS_MM[:, None] - LASER_OFFSETS_MM[None]
    cheb = np.abs(diffs).max(axis=-1)
    assert cheb[cheb > 0].min() == 7.5


@pytest.mark.parametrize("blind", [(2.5, 5), (5, 2.5), (5, 7.5), (7.5, 5)])
def test_blind_phases_report_no_hit_and_keep_the_prior(blind):  # §4.5
    true_xy = START + blind
    frame = LaserGridSimulator(spot_half_width_mm=1.0).frames(pose(true_xy)[None])[0]
    assert frame.horizontal == ()
    result = decode_frame(GEOMETRY, frame.horizontal, [], pose(true_xy))
    assert result.horizontal.status is ScreenStatus.NO_HIT and not result.measured[0]
    assert result.position_mm == pytest.approx(tuple(pose(true_xy)))


@pytest.mark.parametrize(
    "r, hit, multi", [(0.5, 0.12, 0.0), (1.0, 0.48, 0.0), (1.25, 0.75, 0.0), (1.5, 0.84, 0.20), (2.0, 0.96, 0.60)]
)
def test_coverage_table_of_finite_spots(r, hit, multi):  # §4.5 finite-spot table
    u = np.linspace(0, 10, 80, endpoint=False) + 0.0625
    grid = np.array([(START[0] + a, START[1] + b, -150.0) for a in u for b in u])
    frames = LaserGridSimulator(spot_half_width_mm=r).frames(grid)
    counts = np.array([len(f.horizontal) for f in frames])
    assert np.mean(counts >= 1) == pytest.approx(hit, abs=0.015)
    assert np.mean(counts > 1) == pytest.approx(multi, abs=0.015)


def test_round_trip_over_a_fine_grid_is_within_the_resolution():
    rng = np.random.default_rng(7)
    r = 1.5
    xs = np.arange(-40.0, 40.0, 0.5)
    truth = np.array([(x, y, z) for x in xs for y in xs[::4] for z in (-155.0,)])
    priors = truth + rng.uniform(-1.0, 1.0, truth.shape)
    frames = LaserGridSimulator(spot_half_width_mm=r).frames(truth)
    ok = lit = 0
    for true, prior, frame in zip(truth, priors, frames):
        result = decode_frame(GEOMETRY, frame.horizontal, frame.vertical, prior, spot_half_width_mm=r)
        for screen in (result.horizontal, result.vertical):
            assert screen.status in (ScreenStatus.OK, ScreenStatus.NO_HIT, ScreenStatus.AMBIGUOUS), screen.reason
        measured = np.array(result.measured)
        err = np.abs(np.array(result.position_mm) - true)[measured]
        assert np.all(err <= r + 1e-9), (true, result)  # within the detection window: the 2.5 mm step
        ok += result.horizontal.status is ScreenStatus.OK
        lit += len(frame.horizontal) > 0
    assert ok == lit and lit / len(truth) > 0.8  # with a 1 mm prior every lit frame decodes OK


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-50, 50),
    y=st.floats(-50, 50),
    z=st.floats(-200, -120),
    ex=st.floats(-2.5, 2.5),
    ey=st.floats(-2.5, 2.5),
    ez=st.floats(-2.5, 2.5),
)
def test_decoded_axes_are_within_the_spot_half_width(x, y, z, ex, ey, ez):
    r = 1.0
    truth = np.array([x, y, z])
    frame = LaserGridSimulator(spot_half_width_mm=r).frames(truth[None])[0]
    result = decode_frame(GEOMETRY, frame.horizontal, frame.vertical, truth + (ex, ey, ez), spot_half_width_mm=r)
    err = np.abs(np.array(result.position_mm) - truth)
    assert np.all(err[np.array(result.measured)] <= r + 1e-9)
    if result.y_disagreement_mm is not None:
        assert abs(result.y_disagreement_mm) <= 2 * r + 1e-9 and not result.misaligned


def test_vertical_screen_adds_back_the_40_mm_laser_offset():
    truth = np.array([-5.0, -5.0, -150.0])  # vertical BE at (y, z) = (-5, -190): phase (0, 5) -> G5-b
    frame = LaserGridSimulator(spot_half_width_mm=0.5).frames(truth[None])[0]
    v = GEOMETRY.vertical
    assert frame.vertical == (int(v.index_of_cell(7, 2)),)
    result = decode_frame(GEOMETRY, frame.horizontal, frame.vertical, truth + (0.5, 0.5, 2.0))
    assert result.measured == (True, True, True)
    assert result.position_mm == pytest.approx((-5.0, -5.0, -150.0))
    assert result.vertical.lasers == ("G5-b",) and result.y_disagreement_mm == 0.0


def test_hits_that_no_single_position_explains_are_a_fault():
    result = decode_screen(H, [0, 255], START)
    assert result.status is ScreenStatus.FAULT and result.be_mm == tuple(START)
    assert "cannot all be lit by one BE position" in result.reason


def test_index_validation_base_and_lookup_table():
    with pytest.raises(ConfigError, match=r"sensor index = 256, expected 0..255"):
        H.cell_of_index(256)
    one_based = Screen("horizontal", (0, 1), (-75.0, -75.0), index_base=1)
    assert one_based.cell_of_index(1) == (0, 0) and one_based.cell_of_index(256) == (15, 15)
    transposed = np.array([(k // 16, k % 16) for k in range(256)])
    table = Screen("horizontal", (0, 1), (-75.0, -75.0), index_map=transposed)
    assert table.cell_of_index(1) == (0, 1) and int(table.index_of_cell(0, 1)) == 1
    with pytest.raises(ConfigError, match="index_map has shape"):
        Screen("h", (0, 1), (0.0, 0.0), index_map=np.zeros((10, 2), int))


def test_miss_probability_reproduces_appendix_d2_repeatability():
    truth = np.tile(pose(START, -140.0), (8000, 1))
    sim = LaserGridSimulator(spot_half_width_mm=1.0, p_miss=P_MISS_AT_DISTANCE[140.0], seed=1)
    hit_rate = np.mean([len(f.horizontal) == 1 for f in sim.frames(truth)])
    assert hit_rate == pytest.approx(0.9925, abs=0.003)  # 397/400 in Appendix D2 at 14 cm


def test_report_grammar_and_bad_input():
    truth = pose(START + (5, 0))
    frame = LaserGridSimulator(spot_half_width_mm=0.5).frames(truth[None])[0]
    assert format_report(frame) == b"H121XV039X"  # vertical BE at (y, z) = (-5, -190): G5-b on (7, 2)
    blind = LaserGridSimulator(spot_half_width_mm=0.5).frames(pose(START + (2.5, 5), -155.0)[None])[0]
    assert blind.horizontal == () and format_report(blind).startswith(b"h")
    with pytest.raises(ConfigError, match="p_miss = 1.5"):
        LaserGridSimulator(p_miss=1.5)
    with pytest.raises(ConfigError, match="prior_mm"):
        decode_frame(GEOMETRY, [], [], [0.0, np.nan, 0.0])


def test_sensor_observes_a_true_pose_through_the_simulator():
    true = {"xyz": np.array([0.0, -5.0, -150.0])}
    sim = LaserGridSimulator(spot_half_width_mm=1.0)
    sensor = LaserGridSensor(sim.frame_source(lambda: true["xyz"]), lambda: true["xyz"] + (1.0, -1.0, 2.0))
    assert isinstance(sensor, Sensor)
    reading = sensor.read()
    assert reading.valid and reading.value == pytest.approx((0.0, -5.0, -150.0)) and reading.raw == "H:121 V:39"
    assert reading.calibration_id == "lasergrid-gui-default"
    true["xyz"] = np.array([*(START + (2.5, 5)), -155.0])  # blind on the horizontal screen, (5, 0) on the vertical
    blind = sensor.read()
    assert not blind.valid and "horizontal: no-hit" in blind.note and "vertical: ok" in blind.note
    assert blind.value == pytest.approx((-2.5 + 1.0, 0.0, -155.0))  # x keeps the prior; y, z measured


def test_observer_plugs_into_a_simulated_controller_sensor_hook():
    observe = LaserGridSimulator(spot_half_width_mm=1.0, p_miss=0.5, seed=3).observer()
    frames = [observe(np.array([0.0, -5.0, -150.0])) for _ in range(400)]
    assert all(h in ((), (121,)) and v in ((), (39,)) for h, v in frames)
    assert np.mean([len(h) for h, _ in frames]) == pytest.approx(0.5, abs=0.08)  # fresh draws every frame


@given(h=st.sets(st.integers(0, 255), max_size=4), v=st.sets(st.integers(0, 255), max_size=4))
def test_report_grammar_round_trip(h, v):
    frame = GridFrame(tuple(sorted(h)), tuple(sorted(v)))
    assert parse_report(format_report(frame)) == frame


@pytest.mark.parametrize("bad", [b"H12", b"X", b"H1234X", b"hq", b"V-1X"])
def test_malformed_reports_are_refused(bad):
    with pytest.raises(MalformedSample, match="expected H<n>X, V<n>X, h or v"):
        parse_report(bad)


def test_simulated_delta4_controller_reports_what_the_decoder_reads():
    # composition with the simulated ATmega128 controller: its sensor hook is the laser-grid simulator
    from bench.robots import delta4_wire
    from bench.simulators import delta4 as sim_delta4

    plant, home = sim_delta4.build_plant(0, ideal=True)
    device = sim_delta4.Delta4SimDevice(
        plant, delta4_wire.MAPPINGS["legacy_vb"](), home_servo_deg=home, sensor=LaserGridSimulator().observer()
    )
    device.feed(b"E", 0.0)
    report = device.tick(0.0)
    assert report == b"H105XV041X"  # home (0, 0, -150): phase (5, 5) on both screens -> G5-c
    frame = parse_report(report)
    result = decode_frame(GEOMETRY, frame.horizontal, frame.vertical, [1.0, -1.0, -148.0])
    assert result.position_mm == (0.0, 0.0, -150.0) and result.horizontal.lasers == ("G5-c",)
