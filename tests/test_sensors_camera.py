"""Camera laser spot: sub-pixel centroid on synthetic images with known spot positions, blur and noise
(issue 7: error < 0.1 px RMS), chessboard homography calibration, and clear errors for bad images."""

import cv2
import numpy as np
import pytest

from bench.sensors import MalformedSample, Sensor
from bench.sensors.camera_spot import (
    LaserSpotCamera,
    calibrate_from_chessboard,
    detect_spot,
)
from bench.simulators.camera import (
    SpotCameraSimulator,
    apply_homography,
    render_chessboard,
    render_spot,
)

SHAPE = (240, 320)


def true_homography():
    """mm -> px: 3.2 px/mm, rotated 4 deg, shifted, with a slight perspective tilt."""
    angle = np.radians(4.0)
    scale = 3.2
    similarity = np.array(
        [
            [scale * np.cos(angle), -scale * np.sin(angle), 40.0],
            [scale * np.sin(angle), scale * np.cos(angle), 30.0],
            [0.0, 0.0, 1.0],
        ]
    )
    return similarity @ np.array([[1, 0, 0], [0, 1, 0], [1.5e-4, -1e-4, 1.0]])


@pytest.mark.parametrize("sigma_px, noise", [(1.5, 2.0), (2.5, 4.0), (4.0, 6.0)])
def test_centroid_error_is_below_0_1_px_rms(sigma_px, noise):
    rng = np.random.default_rng(11)
    truth = rng.uniform([30, 30], [290, 210], size=(40, 2))
    errors = []
    for u, v in truth:
        image = render_spot(SHAPE, (u, v), sigma_px=sigma_px, peak=170, noise_sigma=noise, rng=rng)
        spot = detect_spot(image)
        errors.append((spot.u_px - u, spot.v_px - v))
    rms = np.sqrt(np.mean(np.sum(np.square(errors), axis=1)))
    assert rms < 0.1
    assert rms > 0.0  # noise is present: a perfect zero would mean the test is not measuring anything


def test_centroid_on_a_colour_frame_uses_the_red_channel():
    grey = render_spot(SHAPE, (100.3, 50.7), sigma_px=2.0)
    frame = np.zeros(SHAPE + (3,), np.uint8)
    frame[:, :, 2] = grey
    frame[:, :, 1] = render_spot(SHAPE, (200.0, 200.0), sigma_px=2.0)  # a green distractor is ignored
    spot = detect_spot(frame)
    assert (spot.u_px, spot.v_px) == pytest.approx((100.3, 50.7), abs=0.02)


def test_chessboard_homography_recovers_the_plane():
    homography = true_homography()
    board = render_chessboard((300, 400), (9, 6), 10.0, homography)
    calibration = calibrate_from_chessboard(board, (9, 6), 10.0, calibration_id="cam-1", date="2026-11-23")
    assert calibration.rms_mm < 0.05
    points_mm = np.array([[0.0, 0.0], [80.0, 50.0], [33.3, 12.7], [-5.0, 55.0]])
    recovered = calibration.pixel_to_mm(apply_homography(homography, points_mm))
    np.testing.assert_allclose(recovered, points_mm, atol=0.05)


def test_laser_spot_camera_observes_a_true_position_in_mm():
    camera = SpotCameraSimulator(true_homography(), shape=(300, 400), sigma_px=2.5, noise_sigma=3.0)
    calibration = calibrate_from_chessboard(
        camera.chessboard((9, 6), 10.0), (9, 6), 10.0, calibration_id="cam-1", date="2026-11-23"
    )
    truth = {"xy": np.array([42.5, 17.25])}
    sensor = LaserSpotCamera(camera.frame_source(lambda: truth["xy"]), calibration, name="cam-xy")
    assert isinstance(sensor, Sensor)
    for xy in ([42.5, 17.25], [0.0, 0.0], [71.3, 44.9]):
        truth["xy"] = np.array(xy)
        reading = sensor.read()
        assert reading.unit == "mm" and reading.calibration_id == "cam-1"
        assert reading.value == pytest.approx(tuple(xy), abs=0.05)  # 0.05 mm = 0.16 px at 3.2 px/mm
        assert reading.raw == pytest.approx(tuple(apply_homography(true_homography(), xy)[0]), abs=0.1)


def test_bad_images_give_clear_errors():
    with pytest.raises(MalformedSample, match="empty image"):
        detect_spot(np.zeros((0, 0), np.uint8))
    with pytest.raises(MalformedSample, match="no laser spot"):
        detect_spot(np.full(SHAPE, 40, np.uint8))
    with pytest.raises(MalformedSample, match="saturated"):
        detect_spot(render_spot(SHAPE, (100, 100), sigma_px=3.0, peak=400))
    with pytest.raises(MalformedSample, match="stray light"):
        detect_spot(cv2.circle(np.full(SHAPE, 20, np.uint8), (160, 120), 60, 200, -1))
    with pytest.raises(MalformedSample, match="chessboard with \\(9, 6\\) inner corners not found"):
        calibrate_from_chessboard(np.full(SHAPE, 128, np.uint8), (9, 6), 10.0, calibration_id="x")


def test_a_frozen_camera_is_refused_at_its_first_repeated_frame():
    """Drill: the driver hands back its last buffer after the robot moved; the stale spot is refused, never read."""
    from bench.errors import LinkError

    camera = SpotCameraSimulator(true_homography(), shape=(300, 400), sigma_px=2.5, noise_sigma=3.0)
    calibration = calibrate_from_chessboard(
        camera.chessboard((9, 6), 10.0), (9, 6), 10.0, calibration_id="cam-1", date="2026-11-23"
    )
    live = camera.frame_source(lambda: np.array([42.5, 17.25]))
    frames = {"frozen": None}

    def grab():
        if frames["frozen"] is None:
            return live()
        return frames["frozen"].copy()  # a new array with the old bytes, as a driver re-delivers a buffer

    sensor = LaserSpotCamera(grab, calibration, name="cam-xy")
    assert sensor.read().value == pytest.approx((42.5, 17.25), abs=0.05)
    assert sensor.read().value == pytest.approx((42.5, 17.25), abs=0.05)  # same pose, fresh read noise: accepted
    frames["frozen"] = live()
    sensor.read()
    with pytest.raises(LinkError, match=r"^cam-xy: this frame is identical to the previous one, bit for bit"):
        sensor.read()
