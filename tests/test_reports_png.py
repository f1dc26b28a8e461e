"""The report's PNGs (bench.reports.png): what Pillow decodes from them, and the deflated rows the PDF embeds."""

from __future__ import annotations

import io
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from bench.reports.png import deflated_rgb, rgb_png


def _rgba(width: int, height: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (height, width, 4), dtype=np.uint8)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 40), st.integers(1, 30), st.integers(0, 2**32 - 1))
def test_pillow_reads_back_the_rgb_of_the_pixels(width, height, seed):
    rgba = _rgba(width, height, seed)
    image = Image.open(io.BytesIO(rgb_png(rgba.tobytes(), width, height, dpi=150)))
    assert image.mode == "RGB" and image.size == (width, height)
    np.testing.assert_array_equal(np.asarray(image), rgba[:, :, :3])
    assert image.info["dpi"] == pytest.approx((150, 150), abs=0.013)  # stored as whole pixels per metre


def test_the_deflated_rows_are_the_pixels_each_row_with_filter_type_none():
    rgba = _rgba(7, 5, 0)
    pixels = deflated_rgb(rgb_png(rgba, 7, 5, dpi=100))
    assert (pixels.width, pixels.height) == (7, 5)
    rows = np.frombuffer(zlib.decompress(pixels.data), dtype=np.uint8).reshape(5, 1 + 3 * 7)
    assert not rows[:, 0].any()
    np.testing.assert_array_equal(rows[:, 1:].reshape(5, 7, 3), rgba[:, :, :3])


@pytest.mark.parametrize("mode", ["RGBA", "L", "P"])
def test_other_pngs_are_left_to_the_slow_way(mode):
    buffer = io.BytesIO()
    Image.new(mode, (4, 3)).save(buffer, format="png")
    assert deflated_rgb(buffer.getvalue()) is None
    assert deflated_rgb(b"GIF89a not a png") is None


def test_pixels_of_another_size_are_refused():
    with pytest.raises(ValueError, match="expected 4 x 3 RGBA"):
        rgb_png(bytes(4 * 4 * 4), 4, 3, dpi=150)
