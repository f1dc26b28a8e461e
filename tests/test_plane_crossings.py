"""The station planes' crossings read block by block (bench.metrology.plane_crossings) against the per-station
reading they replace (the reference below, bench's code until issue 34): the same sample, the same fraction to
rounding (the reference summed δ through BLAS, which may fuse), on random paths, integer paths with samples exactly
on a plane (ties between a zero and a sign change), and blocks down to one sample."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bench.errors import InsufficientData
from bench.metrology.iso9283_dynamics import cycle_crossings, station_crossings
from bench.metrology.plane_crossings import plane_crossings


def reference_crossing(path, station, normal):
    """bench's ``_plane_crossing`` until issue 34: one station, every sample."""
    signed = (path - station) @ normal
    crossing = np.flatnonzero(np.signbit(signed[:-1]) != np.signbit(signed[1:]))
    candidates = [(int(i), 0.0) for i in np.flatnonzero(signed == 0.0)]
    candidates += [(int(i), float(signed[i] / (signed[i] - signed[i + 1]))) for i in crossing]
    if not candidates:
        return None
    points = np.array([path[i] + f * (path[min(i + 1, len(path) - 1)] - path[i]) for i, f in candidates])
    return candidates[int(np.argmin(np.sum((points - station) ** 2, axis=1)))]


def _normals(count, rng, dims=3):
    normals = rng.normal(size=(count, dims))
    return normals / np.linalg.norm(normals, axis=1)[:, None]


def _check(path, stations, normals, block):
    index, fraction = plane_crossings(path, stations, normals, block=block)
    for i, (station, normal) in enumerate(zip(stations, normals)):
        expected = reference_crossing(path, station, normal)
        if expected is None:
            assert index[i] == -1 and fraction[i] == 0.0
        else:
            assert (int(index[i]), fraction[i]) == pytest.approx(expected, abs=1e-9)


@settings(max_examples=80, deadline=None)
@example(n=2, m=1, block=1, dims=2, seed=1)  # a box the plane cuts, its segment not
@given(
    st.integers(1, 400),
    st.integers(1, 30),
    st.integers(1, 70),
    st.sampled_from([2, 3]),
    st.integers(0, 2**32 - 1),
)
def test_random_walks_cross_where_the_per_station_reading_says(n, m, block, dims, seed):
    rng = np.random.default_rng(seed)
    path = np.cumsum(rng.normal(size=(n, dims)), axis=0)
    stations = path[rng.integers(0, n, m)] + rng.normal(scale=0.5, size=(m, dims))
    _check(path, stations, _normals(m, rng, dims), block)


@settings(max_examples=80, deadline=None)
@given(
    arrays(float, st.tuples(st.integers(1, 60), st.just(3)), elements=st.integers(-3, 3).map(float)),
    arrays(float, st.tuples(st.integers(1, 12), st.just(3)), elements=st.integers(-3, 3).map(float)),
    st.lists(st.sampled_from([0, 1, 2]), min_size=12, max_size=12),
    st.lists(st.booleans(), min_size=12, max_size=12),
    st.integers(1, 9),
)
def test_samples_exactly_on_a_plane_tie_as_the_per_station_reading_does(path, stations, axes, flips, block):
    """Integer samples and axis-aligned planes: δ exact, zeros and crossings at the same sample, equal distances."""
    normals = np.zeros_like(stations)
    normals[np.arange(len(stations)), axes[: len(stations)]] = np.where(flips[: len(stations)], -1.0, 1.0)
    _check(path, stations, normals, block)


def test_a_path_that_never_reaches_a_plane_and_a_single_sample():
    path = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    index, fraction = plane_crossings(path, np.array([[5.0, 0, 0], [1.5, 0, 0]]), np.eye(3)[[0, 0]])
    assert index.tolist() == [-1, 1] and fraction.tolist() == [0.0, 0.5]
    index, _ = plane_crossings(path[:1], np.array([[0.0, 0, 0], [1.0, 0, 0]]), np.eye(3)[[0, 0]])
    assert index.tolist() == [0, -1]


def test_a_rectangle_crossing_each_plane_twice_keeps_the_crossing_near_the_station():
    """The plane of a station on the bottom edge cuts the top edge too, farther away: the bottom one is kept."""
    corners = np.array([[0.0, 0, 0], [100, 0, 0], [100, 50, 0], [0, 50, 0], [0, 0, 0]])
    path = np.concatenate([np.linspace(a, b, 400, endpoint=False) for a, b in zip(corners[:-1], corners[1:])])
    path += np.random.default_rng(3).normal(scale=0.01, size=path.shape)
    stations = np.column_stack([np.linspace(5, 95, 19), np.zeros(19), np.zeros(19)])
    index, fraction = plane_crossings(path, stations, np.tile([1.0, 0, 0], (19, 1)))
    crossing = path[index] + fraction[:, None] * (path[index + 1] - path[index])
    assert np.all(index < 400) and np.abs(crossing[:, 0] - stations[:, 0]).max() < 1e-9
    _check(path, stations, np.tile([1.0, 0, 0], (19, 1)), 64)


def test_station_and_cycle_crossings_equal_the_per_station_reading():
    rng = np.random.default_rng(11)
    line = np.linspace([0.0, 0, 0], [60.0, 10, 5], 600)
    paths = [line + rng.normal(scale=0.05, size=line.shape) for _ in range(3)]
    stations = np.linspace([5.0, 5 / 6, 5 / 12], [55.0, 55 / 6, 55 / 12], 25)
    normal = (line[-1] - line[0]) / np.linalg.norm(line[-1] - line[0])
    points, where = station_crossings(paths, stations)
    for j, path in enumerate(paths):
        column, missed = cycle_crossings(path, stations)
        assert missed is None and np.array_equal(column, points[:, j])
        for i, station in enumerate(stations):
            k, f = reference_crossing(path, station, normal)
            assert where[i][j] == pytest.approx((k, f), abs=1e-9)
            assert points[i, j] == pytest.approx(path[k] + f * (path[k + 1] - path[k]), abs=1e-9)
    column, missed = cycle_crossings(paths[0][:300], stations)  # stops half way: the stations past it not crossed
    reached = [reference_crossing(paths[0][:300], station, normal) is not None for station in stations]
    assert 0 < sum(reached) < len(stations) and missed == reached.index(False)
    assert np.isnan(column).any(axis=1).tolist() == [not r for r in reached]
    with pytest.raises(InsufficientData, match="never crosses the plane of station"):
        station_crossings([paths[0], paths[1][:300]], stations)
