"""Tidy pose tables: parsing errors name row and column; per-pose results match an independent computation."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.errors import ConfigError, InsufficientData
from bench.metrology import pose_stabilisation
from bench.metrology.stabilisation_tables import stabilisation_results, stabilisation_table
from bench.metrology.tables import (
    analyze_distance,
    analyze_poses,
    pose_table,
    read_table_csv,
)

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "data" / "iso9283_example.csv"
HEADER = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm"


def _write(tmp_path, text: str) -> Path:
    path = tmp_path / "samples.csv"
    path.write_text(text)
    return path


def _reference(frame: pd.DataFrame, pose: str) -> tuple[float, float]:
    rows = frame[frame["pose"] == pose]
    p = rows[["x_mm", "y_mm", "z_mm"]].to_numpy()
    c = rows[["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"]].to_numpy()[0]
    bary = p.mean(axis=0)
    ap = float(np.sqrt(((bary - c) ** 2).sum()))
    l = np.sqrt(((p - bary) ** 2).sum(axis=1))
    return ap, float(l.mean() + 3 * np.sqrt(((l - l.mean()) ** 2).sum() / (len(l) - 1)))


def test_example_table_matches_independent_computation():
    raw = pd.read_csv(EXAMPLE, comment="#")
    results = analyze_poses(pose_table(read_table_csv(EXAMPLE)))
    assert [r.label for r in results] == ["P1", "P5", "P4", "P3", "P2"]
    for r in results:
        ap, rp = _reference(raw, r.pose)
        assert r.accuracy.ap_mm == pytest.approx(ap)
        assert r.repeatability.rp_mm == pytest.approx(rp)
        assert r.accuracy.n == 10
        assert r.angle_names == ("a", "b", "c")
        assert r.ap_u.expanded_uncertainty > 0 and r.rp_u.expanded_uncertainty > 0


@settings(max_examples=15, deadline=None)
@given(st.randoms(use_true_random=False))
def test_results_independent_of_row_order(random):
    table = pose_table(read_table_csv(EXAMPLE))
    order = list(range(len(table)))
    random.shuffle(order)
    shuffled = table.iloc[order]
    base = {r.pose: r for r in analyze_poses(table, resamples=50)}
    for r in analyze_poses(shuffled, resamples=50):
        assert r.accuracy.ap_mm == pytest.approx(base[r.pose].accuracy.ap_mm)
        assert r.repeatability.rp_mm == pytest.approx(base[r.pose].repeatability.rp_mm)
        assert r.rp_u == base[r.pose].rp_u  # rows are sorted by cycle before the seeded bootstrap


def test_poses_with_different_cycle_counts(tmp_path):
    rows = [f"A,{j},0,0,0,{0.1 * j},0,0" for j in range(1, 4)] + [f"B,{j},10,0,0,10,{0.2 * j},0" for j in range(1, 6)]
    results = analyze_poses(pose_table(read_table_csv(_write(tmp_path, "\n".join([HEADER, *rows])))))
    assert [(r.pose, r.accuracy.n) for r in results] == [("A", 3), ("B", 5)]
    assert results[0].accuracy.ap_axes_mm == pytest.approx((0.2, 0.0, 0.0))
    assert results[1].accuracy.ap_axes_mm == pytest.approx((0.0, 0.6, 0.0))


def test_varying_conditions_split_the_groups(tmp_path):
    rows = [f"P1,{j},0,0,0,0,0,{0.01 * j},{v}" for v in (100, 50) for j in range(1, 4)]
    results = analyze_poses(pose_table(read_table_csv(_write(tmp_path, "\n".join([HEADER + ",velocity_pct", *rows])))))
    assert [r.label for r in results] == ["P1 (velocity_pct=100)", "P1 (velocity_pct=50)"]


def test_missing_column_is_named(tmp_path):
    path = _write(tmp_path, "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm\nP1,1,0,0,0,0,0\n")
    with pytest.raises(ConfigError, match=r"samples.csv: missing column\(s\) z_mm"):
        pose_table(read_table_csv(path))


def test_non_numeric_cell_names_row_column_and_value(tmp_path):
    path = _write(tmp_path, f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0,0,0,abc,0\n")
    with pytest.raises(ConfigError, match=r"samples.csv: row 2, column y_mm: 'abc' is not a finite number"):
        pose_table(read_table_csv(path))


def test_empty_cell_is_refused(tmp_path):
    path = _write(tmp_path, f"{HEADER}\nP1,1,0,0,0,0,0,\n")
    with pytest.raises(ConfigError, match=r"row 1, column z_mm: '' is not a finite number"):
        pose_table(read_table_csv(path))


def test_changing_command_within_a_pose_is_refused(tmp_path):
    path = _write(tmp_path, f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0.5,0,0,0,0\n")
    with pytest.raises(ConfigError, match=r"row 2, column cmd_y_mm: 0.5 differs from 0 earlier in pose 'P1'"):
        analyze_poses(pose_table(read_table_csv(path)))


def test_repeated_cycle_is_refused(tmp_path):
    path = _write(tmp_path, f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,1,0,0,0,0,0,1\n")
    with pytest.raises(ConfigError, match=r"row 2, column cycle: cycle 1 repeated for pose 'P1'"):
        analyze_poses(pose_table(read_table_csv(path)))


def test_pose_with_one_cycle_names_the_pose(tmp_path):
    path = _write(tmp_path, f"{HEADER}\nP1,1,0,0,0,0,0,0\nP1,2,0,0,0,0,0,1\nP2,1,0,0,0,0,0,0\n")
    with pytest.raises(InsufficientData, match=r"pose 'P2': pose repeatability cycles: 1 sample\(s\), at least 2"):
        analyze_poses(pose_table(read_table_csv(path)))


def test_angle_column_without_its_command(tmp_path):
    path = _write(tmp_path, f"{HEADER},a_deg\nP1,1,0,0,0,0,0,0,1\n")
    with pytest.raises(ConfigError, match="column a_deg given without cmd_a_deg"):
        pose_table(read_table_csv(path))


def test_missing_file():
    with pytest.raises(ConfigError, match="no such file"):
        read_table_csv("/nonexistent/samples.csv")


def test_distance_from_table_pairs_by_cycle(tmp_path):
    rows = ["P2,1,0,0,0,0,0,0", "P4,1,100,0,0,99.9,0,0", "P2,2,0,0,0,0.1,0,0", "P4,2,100,0,0,100.2,0,0"]
    result = analyze_distance(pose_table(read_table_csv(_write(tmp_path, "\n".join([HEADER, *rows])))), "P2", "P4")
    assert result.ad_mm == pytest.approx((99.9 + 100.1) / 2 - 100)
    assert result.rd_mm == pytest.approx(3 * np.std([99.9, 100.1], ddof=1))


def test_distance_refuses_unpaired_cycles(tmp_path):
    rows = ["P2,1,0,0,0,0,0,0", "P4,1,100,0,0,99.9,0,0", "P2,2,0,0,0,0.1,0,0", "P4,3,100,0,0,100.2,0,0"]
    table = pose_table(read_table_csv(_write(tmp_path, "\n".join([HEADER, *rows]))))
    with pytest.raises(ConfigError, match=r"cycle\(s\) 2, 3 present at only one of 'P2' and 'P4'"):
        analyze_distance(table, "P2", "P4")


def test_mixed_frames_within_a_pose_are_refused(tmp_path):
    # iso9283.md §10.2 #10: AP refuses inputs with different frame tags.
    path = _write(tmp_path, f"{HEADER},frame\nP1,1,0,0,0,0,0,0,base\nP1,2,0,0,0,0,0,1,tracker\n")
    with pytest.raises(ConfigError, match=r"row 2, column frame: 'tracker' differs from 'base' earlier in pose 'P1'"):
        analyze_poses(pose_table(read_table_csv(path)))


def test_missing_pose_column_is_named(tmp_path):
    path = _write(tmp_path, "cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm\n1,0,0,0,0,0,0\n")
    with pytest.raises(ConfigError, match=r"missing column\(s\) pose"):
        pose_table(read_table_csv(path))


def test_stabilisation_results_per_band_and_pose_in_numeric_cycle_order(tmp_path):
    # eleven arrivals at P1 written in reverse: "10" < "2" as text, so cycles must be ordered as numbers
    distances = [0.3, 0.12, 0.05, 0.0]
    rows = [
        f"P1,{cycle},{0.01 * i:g},{d + 0.001 * cycle:g},0,0"
        for cycle in range(11, 0, -1)
        for i, d in enumerate(distances)
    ]
    rows.append("P2,1,0,5,0,0")  # an arrival of one sample has no t_1: its pose gets the reason, not a figure
    table = stabilisation_table(
        read_table_csv(_write(tmp_path, "pose,cycle,t_s,x_mm,y_mm,z_mm\n" + "\n".join(rows) + "\n"))
    )
    results = stabilisation_results(table, [0.1, 0.5], 0.0)
    assert [cycle for cycle, _, _ in results.series["P1"]] == list(range(1, 12))
    arrivals = [
        (np.arange(4) * 0.01, np.column_stack([np.array(distances) + 0.001 * c, np.zeros(4), np.zeros(4)]))
        for c in range(1, 12)
    ]
    for band in (0.1, 0.5):  # by hand: each arrival is inside the band from its third (0.1) or first (0.5) sample
        assert results.bands[band]["P1"] == pose_stabilisation(arrivals, band_mm=band)
    assert results.bands[0.1]["P1"].mean_time_s == 0.0 and results.bands[0.1]["P1"].cycles[0].first_entry_s == 0.02
    assert results.bands[0.1]["P2"] == results.bands[0.5]["P2"] == "t_s: 1 sample(s), at least 2 required"


def test_stabilisation_table_rows_in_any_order_give_the_same_figures(tmp_path):
    distances = [0.9, 0.3, 0.12, 0.05, 0.2, 0.04, 0.0]  # enters 0.1 mm at the 4th sample, leaves, settles at the 6th
    rows = [f"P1,{cycle},{0.01 * i:g},{d * cycle:g},0,0" for cycle in (1, 2) for i, d in enumerate(distances)]
    shuffled = [rows[i] for i in np.random.default_rng(5).permutation(len(rows))]
    results = []
    for name, lines in (("ordered", rows), ("shuffled", shuffled)):
        path = tmp_path / f"{name}.csv"
        path.write_text("pose,cycle,t_s,x_mm,y_mm,z_mm\n" + "\n".join(lines) + "\n")
        results.append(stabilisation_results(stabilisation_table(read_table_csv(path)), [0.1], 0.0).bands[0.1]["P1"])
    assert results[0] == results[1]
    assert results[0].cycles[0].first_entry_s == 0.03 and results[0].cycles[0].settled_s == 0.05
    assert results[0].cycles[0].overshoot_mm == pytest.approx(0.2)


def test_a_commanded_angle_the_instrument_does_not_measure_leaves_the_position_analysis(tmp_path):
    # a tilted pose measured by the mice (position only), as `bench export` writes it: the same AP/RP as without it
    rows = "P1,1,0,0,0,0.1,0,0\nP1,2,0,0,0,0.3,0.2,0\nP2,1,5,0,0,5,0,0.4\nP2,2,5,0,0,5.2,0,0\n"
    plain = analyze_poses(pose_table(read_table_csv(_write(tmp_path, f"{HEADER}\n{rows}"))))
    tilted_rows = "".join(f"{line},3.5\n" for line in rows.splitlines())
    path = tmp_path / "tilted.csv"
    path.write_text(f"{HEADER},cmd_a_deg\n{tilted_rows}")
    tilted = analyze_poses(pose_table(read_table_csv(path)))
    assert [r.accuracy.ap_mm for r in tilted] == [r.accuracy.ap_mm for r in plain]
    assert plain[1].accuracy.ap_mm > 0 and tilted[0].angle_names == ()
