"""``bench analyze vap | path | cornering | path-velocity | positioning-time`` through bench.cli.main: values from
hand computations, units in the JSON keys, row order without meaning, one-line errors."""

import json
from pathlib import Path

import numpy as np
import pytest

from bench.cli import main


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _write(path, header, rows, shuffle=False):
    rows = list(rows)
    if shuffle:
        rows = [rows[i] for i in np.random.default_rng(7).permutation(len(rows))]
    path.write_text(
        "\n".join([header, *(",".join(f"{v:g}" if not isinstance(v, str) else v for v in r) for r in rows)]) + "\n"
    )
    return str(path)


def _vap_rows():
    # P1 from +x, -y, +z: barycentres (0.1, 0, 0), (0, -0.2, 0), (0, 0, 0.05); angle a means 0.0, 0.3, 0.1 deg
    clouds = {"+x": ((0.1, 0, 0), 0.0), "-y": ((0, -0.2, 0), 0.3), "+z": ((0, 0, 0.05), 0.1)}
    for direction, ((x, y, z), a) in clouds.items():
        for cycle, noise in enumerate((-0.01, 0.01), start=1):
            yield (f"P1/{direction}", cycle, 0, 0, 0, x + noise, y, z, 0, a + noise)


VAP_HEADER = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm,cmd_a_deg,a_deg"


@pytest.mark.parametrize("shuffle", [False, True])
def test_vap_json_hand_computed(capsys, tmp_path, shuffle):
    path = _write(tmp_path / "vap.csv", VAP_HEADER, _vap_rows(), shuffle)
    code, out, _ = _run(capsys, "analyze", "vap", path, "--json")
    assert code == 0
    p1 = json.loads(out)["poses"]["P1"]
    assert p1["vAP_p_mm"] == pytest.approx(np.hypot(0.1, 0.2))  # +x against -y
    assert sorted(p1["farthest_pair"]) == ["P1/+x", "P1/-y"]
    assert p1["vAP_a_deg"] == pytest.approx(0.3)
    assert p1["n_per_direction"] == [2, 2, 2]


def test_vap_text_and_a_pose_with_one_direction(capsys, tmp_path):
    path = _write(tmp_path / "vap.csv", VAP_HEADER, _vap_rows())
    code, out, _ = _run(capsys, "analyze", "vap", path)
    assert code == 0 and "0.2236" in out and "vAP_a 0.300 deg" in out
    one = _write(tmp_path / "one.csv", VAP_HEADER, [r for r in _vap_rows() if r[0] == "P1/+x"])
    code, _, err = _run(capsys, "analyze", "vap", one)
    assert code == 2
    assert "pose 'P1' has 1 approach direction(s)" in err and len(err.strip().splitlines()) == 1


def _line_cycles(offsets_y, angle_offsets=None, n=21):
    x = np.linspace(0.0, 100.0, n)
    for cycle, dy in enumerate(offsets_y, start=1):
        for i, xi in enumerate(x):
            row = [cycle, 0.1 * i, xi, dy, 0.0]
            if angle_offsets is not None:
                row.append(0.05 * xi + angle_offsets[cycle - 1])
            yield tuple(row)


@pytest.mark.parametrize("shuffle", [False, True])
def test_path_at_rt_and_orientation(capsys, tmp_path, shuffle):
    path = _write(
        tmp_path / "path.csv", "cycle,t_s,x_mm,y_mm,z_mm,a_deg", _line_cycles((0.1, 0.3, 0.2), (0.0, 0.2, 0.1)), shuffle
    )
    stations = _write(
        tmp_path / "stations.csv",
        "station,x_mm,y_mm,z_mm,a_deg",
        [(i + 1, x, 0, 0, 0.05 * x) for i, x in enumerate((10.0, 50.0, 90.0))],
        shuffle,
    )
    code, out, _ = _run(capsys, "analyze", "path", path, "--commanded", stations, "--json")
    assert code == 0
    r = json.loads(out)
    distances = np.array([0.1, 0.1, 0.0])  # from the barycentre y = 0.2
    assert r["AT_mm"] == pytest.approx(0.2)
    assert r["RT_mm"] == pytest.approx(distances.mean() + 3 * distances.std(ddof=1))
    assert r["AT_a_deg"] == pytest.approx(0.1)
    assert r["RT_a_deg"] == pytest.approx(3 * 0.1)
    assert (r["n_cycles"], r["n_stations"]) == (3, 3)
    # U from the path model Monte Carlo (the crossings are the attained y at each station, x and z exact)
    from bench.metrology.uncertainty_figures import path_uncertainty

    crossings = np.zeros((3, 3, 3))
    crossings[:, :, 0] = np.array([10.0, 50.0, 90.0])[:, None]
    crossings[:, :, 1] = [0.1, 0.3, 0.2]
    u = path_uncertainty(crossings, crossings[:, 0] * [1, 0, 0])
    assert (r["U_AT_mm"], r["U_RT_mm"]) == pytest.approx((u.at.expanded_uncertainty, u.rt.expanded_uncertainty))
    assert r["U_AT_mm"] > 0 and r["U_RT_mm"] > 0
    assert r["U_budget"] == "U excludes the instrument: none declared (--instrument-u-mm)"


def test_path_refuses_different_angle_columns(capsys, tmp_path):
    path = _write(tmp_path / "path.csv", "cycle,t_s,x_mm,y_mm,z_mm,a_deg", _line_cycles((0.1, 0.3), (0, 0)))
    stations = _write(tmp_path / "s.csv", "station,x_mm,y_mm,z_mm", [(1, 10, 0, 0), (2, 90, 0, 0)])
    code, _, err = _run(capsys, "analyze", "path", path, "--commanded", stations)
    assert code == 2 and "expected the same" in err


def test_cornering_json_per_cycle(capsys, tmp_path):
    cut = [(-10, 0), (-1, 0), (0, 1), (0, 10)]
    past = [(-10, 0), (0.5, 0), (0.5, 0.5), (0, 1), (0, 10)]
    rows = [(cycle, 0.1 * i, x, y) for cycle, points in ((1, cut), (2, past)) for i, (x, y) in enumerate(points)]
    path = _write(tmp_path / "corner.csv", "cycle,t_s,x_mm,y_mm", rows, shuffle=True)
    code, out, _ = _run(
        capsys, "analyze", "cornering", path, "--corner", "0,0", "--from=-10,0", "--to", "0,10", "--json"
    )
    assert code == 0
    r = json.loads(out)
    assert [c["CR_mm"] for c in r["cycles"]] == pytest.approx([np.sqrt(0.5), 0.0])
    assert [c["CO_mm"] for c in r["cycles"]] == pytest.approx([0.0, 0.5])
    assert (r["CR_mm"], r["CO_mm"]) == pytest.approx((np.sqrt(0.5), 0.5))
    code, _, err = _run(capsys, "analyze", "cornering", path, "--corner", "0,0,0", "--from=-10,0", "--to", "0,10")
    assert code == 2 and "--corner 0,0,0: 3 coordinates, expected 2" in err


def test_path_velocity_json(capsys, tmp_path):
    # cycle 1 at 50 mm/s, cycle 2 at 52 mm/s, cycle 3 alternates 49/51 mm/s (FV = 2)
    rows = []
    for cycle, speeds in ((1, [50] * 4), (2, [52] * 4), (3, [49, 51, 49, 51])):
        x = np.concatenate([[0.0], np.cumsum(np.array(speeds) * 0.1)])
        rows += [(cycle, 0.1 * i, xi, 0.0) for i, xi in enumerate(x)]
    path = _write(tmp_path / "v.csv", "cycle,t_s,x_mm,y_mm", rows, shuffle=True)
    code, out, _ = _run(capsys, "analyze", "path-velocity", path, "--commanded-mm-s", "50", "--json")
    assert code == 0
    r = json.loads(out)
    means = np.array([50.0, 52.0, 50.0])
    assert r["AV_pct"] == pytest.approx((means.mean() - 50) / 50 * 100)
    assert r["RV_pct"] == pytest.approx(3 * means.std(ddof=1) / 50 * 100)
    assert r["FV_mm_s"] == pytest.approx(2.0)
    from scipy import stats

    from bench.metrology.uncertainty_figures import spread_half_width

    # U(AV): Student's t for 95.45 % at 2 dof on S/sqrt(3); U(RV): the chi pivot's half-width for n = 3
    assert r["U_AV_pct"] == pytest.approx(stats.t.ppf(0.97725, 2) * means.std(ddof=1) / np.sqrt(3) / 50 * 100, rel=1e-4)
    assert r["U_RV_pct"] == pytest.approx(r["RV_pct"] * spread_half_width(3, 0.9545), rel=1e-3)
    assert r["U_budget"] == "U(AV) excludes the instrument: none declared (--instrument-u-pct)"


def test_positioning_time_per_band_and_step(capsys, tmp_path):
    rows = []
    for step, distance in ((1, -10.0), (2, 20.0)):
        for cycle in (1, 2):
            t = np.round(np.arange(0.0, 1.5, 0.01), 6)
            x = np.interp(t, [0.0, 0.2, 1.0, 2.0], [0.0, 0.0, distance, distance])
            rows += [(step, cycle, ti, xi, 0.0, 0.0) for ti, xi in zip(t, x)]
    path = _write(tmp_path / "p.csv", "step,cycle,t_s,x_mm,y_mm,z_mm", rows, shuffle=True)
    code, out, _ = _run(capsys, "analyze", "positioning-time", path, "--band-mm", "0.5", "--json")
    assert code == 0
    steps = json.loads(out)["bands"]["0.5"]
    assert [s["step"] for s in steps] == [1, 2]
    # leaves the band after 0.5 mm of travel, enters the final band 0.5 mm before the end (ramp of 0.8 s)
    for s, distance in zip(steps, (10.0, 20.0)):
        ramp = 0.8 * 0.5 / distance
        assert s["mean_time_s"] == pytest.approx(0.8 - 2 * ramp, abs=0.011)
        assert s["distance_mm"] == pytest.approx(distance)


def test_drift_reports_the_orientation_of_the_pose(capsys):
    import pandas as pd

    from bench.metrology import orientation_drift

    example = Path(__file__).resolve().parents[1] / "examples" / "data" / "iso9283_example.csv"
    code, out, _ = _run(capsys, "analyze", "drift", str(example), "--window-s", "100", "--json")
    assert code == 0
    r = json.loads(out)
    rows = pd.read_csv(example, comment="#")
    rows = rows[rows["pose"] == "P1"]
    names = [a for a in ("a", "b", "c") if f"{a}_deg" in rows.columns]
    assert names  # the example carries angles
    direct = orientation_drift(
        rows["t_s"],
        rows[[f"{a}_deg" for a in names]],
        rows[[f"cmd_{a}_deg" for a in names]].to_numpy()[0],
        window_s=100,
    )
    for i, name in enumerate(names):
        assert r[f"dAP_{name}_deg"] == pytest.approx(direct.dap_deg[i])
        assert r[f"dRP_{name}_deg"] == pytest.approx(direct.drp_deg[i])
        assert r[f"dAP_{name}_deg"] == pytest.approx(
            abs(r["windows"][0][f"AP_{name}_deg"] - r["windows"][1][f"AP_{name}_deg"])
        )


def test_exchangeability_per_pose(capsys, tmp_path):
    header = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm,robot"
    rows = [
        ("P1", c, 0, 0, 0, x + d, 0, 0, robot)
        for robot, x in (("SN1", 0.0), ("SN2", 0.3), ("SN3", 0.1))
        for c, d in ((1, -0.05), (2, 0.05))
    ]
    path = _write(tmp_path / "e.csv", header, rows, shuffle=True)
    code, out, _ = _run(capsys, "analyze", "exchangeability", path, "--json")
    assert code == 0
    p1 = json.loads(out)["poses"]["P1"]
    assert p1["E_mm"] == pytest.approx(0.3)
    assert p1["farthest_pair"] == ["SN1", "SN2"]
    code, _, err = _run(capsys, "analyze", "exchangeability", path, "--by", "mounting")
    assert code == 2 and "missing column mounting" in err


def test_distance_reports_orientation_ad_rd_paired_by_cycle(capsys, tmp_path):
    header = "pose,cycle,cmd_x_mm,cmd_y_mm,cmd_z_mm,x_mm,y_mm,z_mm,cmd_a_deg,a_deg"
    # P2 at a_c = 10°, P4 at a_c = -10°: attained differences 19.8, 20.0, 20.4° (cycle order shuffled in the file)
    rows = [
        ("P2", 1, 0, 0, 0, 0, 0, 0, 10, 9.9),
        ("P4", 1, 10, 0, 0, 10, 0, 0, -10, -9.9),
        ("P2", 2, 0, 0, 0, 0, 0, 0, 10, 10.0),
        ("P4", 2, 10, 0, 0, 10, 0, 0, -10, -10.0),
        ("P2", 3, 0, 0, 0, 0, 0, 0, 10, 10.1),
        ("P4", 3, 10, 0, 0, 10, 0, 0, -10, -10.3),
    ]
    path = _write(tmp_path / "d.csv", header, rows, shuffle=True)
    code, out, _ = _run(capsys, "analyze", "distance", path, "--json")
    assert code == 0
    r = json.loads(out)
    distances = np.array([19.8, 20.0, 20.4])
    assert r["AD_a_deg"] == pytest.approx(distances.mean() - 20.0)
    assert r["RD_a_deg"] == pytest.approx(3 * distances.std(ddof=1))
    assert r["AD_mm"] == pytest.approx(0.0, abs=1e-12)
