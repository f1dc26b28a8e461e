"""Typed value columns and the lab-wide AP/RP summary on a real PostgreSQL server: the server's figures equal
bench.metrology's on the same samples; a version-1 lab store is migrated in place."""

from __future__ import annotations

import json
import math
import sqlite3
from collections import defaultdict
from datetime import date

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url  # noqa: E402, F401  (fixtures)

from bench.cli import main  # noqa: E402
from bench.metrology.iso9283 import pose_accuracy, pose_repeatability  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LAB_SCHEMA_VERSION, LabStore, sync_store  # noqa: E402
from bench.store.lab_copy import TYPED_COLUMNS  # noqa: E402
from bench.store.lab_summary import pose_summary  # noqa: E402
from bench.store.record_checksum import seal_run
from bench.store.sample_checksum import CHECKED_COLUMNS, sample_checksum

COMMANDS = {"P1": (110.0, 0.0, 320.0), "P2": (60.5, -40.25, 300.0)}
#: (bench, robot, start of the run); 2026-11-02 and 2026-11-04 share the ISO week of Monday 2026-11-02.
RUNS = (
    ("bench-a", "pkm5", "2026-11-02T08:00:00.000000+00:00"),
    ("bench-a", "pkm5", "2026-11-04T23:59:00.000000+00:00"),
    ("bench-a", "pkm5", "2026-11-09T00:00:01.000000+00:00"),
    ("bench-b", "delta4", "2026-11-03T12:00:00.000000+00:00"),
)


def make_campaigns(tmp_path, seed=9283):
    """Two stores; per run, 3 cycles x 2 poses x 2 velocities (one of them unset) with scattered attained
    positions, a partial laser-grid pose (no z), an arrival sample and one lone pose (n = 1). Returns the paths and
    every pose sample as (bench, robot, started, pose, velocity, xyz)."""
    rng = np.random.default_rng(seed)
    samples, paths = [], {}
    for bench, robot, started in RUNS:
        path = paths.setdefault(bench, tmp_path / f"{bench}.db")
        with Store(path, bench=bench) as store:
            run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot=robot, config={})
            step = 0
            for cycle in range(1, 4):
                for pose, command in COMMANDS.items():
                    for velocity in (50.0, None):
                        xyz = tuple(float(c + rng.normal(0.02, 0.01)) for c in command)
                        values = {
                            **dict(zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), command)),
                            **dict(zip(("x_mm", "y_mm", "z_mm"), xyz)),
                        }
                        if velocity is not None:
                            values["velocity_pct"] = velocity
                        store.add_sample(run_id, step, values=values, pose=pose, cycle=cycle, t_s=step * 0.5)
                        samples.append((bench, robot, started, pose, velocity, xyz))
                        step += 1
            store.add_sample(
                run_id,
                step,
                values={"cmd_x_mm": 110.0, "cmd_y_mm": 0.0, "cmd_z_mm": 320.0, "x_mm": 200.0, "y_mm": 9.0},
                pose="P1",
                cycle=4,
                t_s=99.0,
            )
            store.add_sample(
                run_id,
                step + 1,
                kind="arrival",
                values={"cmd_x_mm": 110.0, "cmd_y_mm": 0.0, "cmd_z_mm": 320.0, "x_mm": 1.0, "y_mm": 2.0, "z_mm": 3.0},
                pose="P1",
                cycle=4,
                t_s=100.0,
            )
            store.add_sample(
                run_id,
                step + 2,
                values={"cmd_x_mm": 1.0, "cmd_y_mm": 2.0, "cmd_z_mm": 3.0, "x_mm": 1.5, "y_mm": 2.0, "z_mm": 3.0},
                pose="P9",
                t_s=101.0,
            )
            samples.append((bench, robot, started, "P9", None, (1.5, 2.0, 3.0)))
        db = sqlite3.connect(path)
        with db:
            db.execute("UPDATE runs SET started_utc = ? WHERE id = ?", (started, run_id))
            seal_run(db, run_id)  # an edit by hand, sealed as bench seals its own
        db.close()
    return paths, samples


def test_typed_columns_hold_the_json_numbers(tmp_path, lab_url):
    path = tmp_path / "t.db"
    with Store(path, bench="bench-t") as store:
        run_id = store.start_run(protocol_name="p", protocol_version="1", robot="pkm5", config={})
        store.add_sample(
            run_id, 0, kind="grid_hit", values={"x_mm": 0.1 + 0.2, "load_kg": 3, "step_mm": 1e-300}, t_s=0.0
        )
        store.add_sample(run_id, 1, kind="note", values={"y_mm": True, "z_mm": -0.0}, pose="P\t1", t_s=1.0)
        store.add_sample(run_id, 2, kind="note", values={}, t_s=2.0)
        store.add_sample(run_id, 3, kind="note", values={}, t_s=3.0)
    db = sqlite3.connect(path)  # values no bench writes today, as an old or hand-made file may hold them
    with db:
        db.execute(
            """UPDATE samples SET values_json = '{"x_mm": "12.5", "y_mm": true, "velocity_pct": [1], "load_kg": {"a": 1}, "z_mm": 2}'"""
            " WHERE step_index = 2"
        )
        db.execute("UPDATE samples SET values_json = '[1, 2]' WHERE step_index = 3")
        # as a file written so: each edited sample carries the checksum of what it now holds (bench store check)
        db.create_function("checksum", 8, sample_checksum)
        db.execute(f"UPDATE samples SET checksum = checksum({', '.join(CHECKED_COLUMNS)}) WHERE step_index IN (2, 3)")
    db.close()
    with Store(path) as store:
        sync_store(store, lab_url)
    columns = ", ".join(f'"{name}"' for name in TYPED_COLUMNS)
    with LabStore(lab_url) as lab:
        rows = lab.query(f"SELECT step_index, {columns} FROM bench.samples ORDER BY step_index")
    typed = [{name: value for name, value in zip(TYPED_COLUMNS, row[1:]) if value is not None} for row in rows]
    assert typed == [
        {"x_mm": 0.30000000000000004, "load_kg": 3.0, "step_mm": 1e-300},
        {"y_mm": 1.0, "z_mm": -0.0},
        {"z_mm": 2.0},
        {},
    ]  # a string, boolean, list, object: NULL
    assert math.copysign(1.0, typed[1]["z_mm"]) == -1.0


def expected_groups(samples):
    """bench.metrology's AP and RP per (bench, robot, week, pose, velocity) group of ``samples``."""
    groups = defaultdict(list)
    for bench, robot, started, pose, velocity, xyz in samples:
        day = date.fromisoformat(started[:10])
        week = date.fromordinal(day.toordinal() - day.weekday())
        groups[(bench, robot, week, pose, velocity)].append(xyz)
    out = {}
    for key, points in groups.items():
        command = COMMANDS.get(key[3], (1.0, 2.0, 3.0))
        ap = pose_accuracy(points, command).ap_mm
        rp = pose_repeatability(points).rp_mm if len(points) >= 2 else None
        out[key] = (len(points), ap, rp)
    return out


def test_summary_equals_metrology_on_the_same_samples(tmp_path, lab_url, capsys):
    paths, samples = make_campaigns(tmp_path)
    for path in paths.values():
        with Store(path) as store:
            sync_store(store, lab_url)
    expected = expected_groups(samples)
    with LabStore(lab_url) as lab:
        groups = pose_summary(lab)
    got = {(g.bench, g.robot, g.week, g.pose, g.velocity_pct): (g.n, g.ap_mm, g.rp_mm) for g in groups}
    assert sorted(got, key=str) == sorted(expected, key=str)
    assert len(got) == 3 * 5  # (bench-a, week 1) pools two runs; 2 poses x 2 velocities and P9 per week and bench
    for key, (n, ap, rp) in expected.items():
        assert got[key][0] == n
        assert got[key][1] == pytest.approx(ap, rel=1e-12, abs=1e-12)
        assert (got[key][2] is None) if rp is None else got[key][2] == pytest.approx(rp, rel=1e-12, abs=1e-12)
    pooled = got[("bench-a", "pkm5", date(2026, 11, 2), "P1", 50.0)]
    assert pooled[0] == 6 and pooled[2] > 0
    assert [g.rp_refused for g in groups if g.pose == "P9"] == [
        None,
        "RP needs at least 2 cycles, this group has 1",
        "RP needs at least 2 cycles, this group has 1",
    ]

    assert main(["lab", "summary", "--store", lab_url, "--since", "2026-11-03", "--robot", "pkm5", "--json"]) == 0
    listed = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert sorted({(r["week"], r["pose"], r["velocity_pct"]) for r in listed}, key=str) == [
        ("2026-11-02", "P1", 50.0),
        ("2026-11-02", "P1", None),
        ("2026-11-02", "P2", 50.0),
        ("2026-11-02", "P2", None),
        ("2026-11-02", "P9", None),
        ("2026-11-09", "P1", 50.0),
        ("2026-11-09", "P1", None),
        ("2026-11-09", "P2", 50.0),
        ("2026-11-09", "P2", None),
        ("2026-11-09", "P9", None),
    ]
    row = next(r for r in listed if (r["week"], r["pose"], r["velocity_pct"]) == ("2026-11-09", "P2", 50.0))
    assert row["n"] == 3 and row["ap_mm"] == pytest.approx(
        expected[("bench-a", "pkm5", date(2026, 11, 9), "P2", 50.0)][1]
    )
    assert main(["lab", "summary", "--store", lab_url, "--bench", "bench-b"]) == 0
    text = capsys.readouterr().out.splitlines()
    assert text[0].split() == ["bench", "robot", "week", "pose", "velocity_pct", "n", "AP_mm", "RP_mm"]
    assert len(text) == 1 + 5 and all(line.split()[:3] == ["bench-b", "delta4", "2026-11-02"] for line in text[1:])
    assert main(["lab", "summary", "--store", str(tmp_path / "x.db")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"bench: error: --store {tmp_path / 'x.db'}: expected a postgresql://USER:PASSWORD@HOST/DBNAME URL"
    )


def test_version_1_lab_store_is_migrated_with_its_typed_columns_filled(tmp_path, lab_url):
    paths, samples = make_campaigns(tmp_path)
    with Store(paths["bench-b"]) as store:
        sync_store(store, lab_url)
    columns = ", ".join(f'"{name}"' for name in TYPED_COLUMNS)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # back to version 1: no typed columns
        before = conn.execute(f"SELECT step_index, {columns} FROM bench.samples ORDER BY step_index").fetchall()
        for name in TYPED_COLUMNS:
            conn.execute(f'ALTER TABLE bench.samples DROP COLUMN "{name}"')
        conn.execute("UPDATE bench.schema_version SET version = 1")
    with Store(paths["bench-a"]) as store:
        sync_store(store, lab_url)
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT version FROM bench.schema_version") == [(LAB_SCHEMA_VERSION,)]
        bench_b = lab.query(
            f"SELECT step_index, {columns} FROM bench.samples s JOIN bench.runs r"
            " ON r.uuid = s.run_uuid WHERE r.bench = 'bench-b' ORDER BY step_index"
        )
        assert bench_b == before
        _assert_figures(pose_summary(lab), samples)


def _assert_figures(groups, samples):
    got, expected = _figures(groups), _figures_expected(samples)
    assert [key for key, _ in got] == [key for key, _ in expected]
    assert [n for _, (n, _, _) in got] == [n for _, (n, _, _) in expected]
    assert [v for _, f in got for v in f[1:]] == pytest.approx(
        [v for _, f in expected for v in f[1:]], rel=1e-12, abs=1e-12
    )


def _figures(groups):
    return sorted(
        (
            (g.bench, g.robot, str(g.week), g.pose, -1.0 if g.velocity_pct is None else g.velocity_pct),
            (g.n, g.ap_mm, -1.0 if g.rp_mm is None else g.rp_mm),
        )
        for g in groups
    )


def _figures_expected(samples):
    return sorted(
        ((bench, robot, str(week), pose, -1.0 if velocity is None else velocity), (n, ap, -1.0 if rp is None else rp))
        for (bench, robot, week, pose, velocity), (n, ap, rp) in expected_groups(samples).items()
    )


def test_version_2_lab_store_gets_its_pose_tables_from_the_samples_it_holds(tmp_path, lab_url):
    paths, samples = make_campaigns(tmp_path)
    with Store(paths["bench-b"]) as store:
        sync_store(store, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # back to version 2: no pose tables, no trigger
        conn.execute("DROP TRIGGER samples_fold_pose ON bench.samples")
        conn.execute("DROP TABLE bench.pose_point_sets, bench.pose_keys")
        conn.execute("UPDATE bench.schema_version SET version = 2")
    with Store(paths["bench-a"]) as store:
        sync_store(store, lab_url)
        sync_store(store, lab_url)  # nothing new: nothing folded twice
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT version FROM bench.schema_version") == [(LAB_SCHEMA_VERSION,)]
        assert lab.query("SELECT sum(cardinality(x_mm)) FROM bench.pose_point_sets") == [(len(samples),)]
        _assert_figures(pose_summary(lab), samples)


def test_version_4_lab_store_gets_its_points_as_point_sets_folded_in_batches(tmp_path, lab_url):
    paths, samples = make_campaigns(tmp_path)
    with Store(paths["bench-b"]) as store:
        sync_store(store, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:  # back to version 4: one pose_points row per point
        conn.execute(
            "CREATE TABLE bench.pose_points AS SELECT p.key, u.x_mm, u.y_mm, u.z_mm"
            " FROM bench.pose_point_sets p, unnest(p.x_mm, p.y_mm, p.z_mm) AS u (x_mm, y_mm, z_mm)"
        )
        conn.execute("DROP TABLE bench.pose_point_sets")
        conn.execute("UPDATE bench.schema_version SET version = 4")
    with Store(paths["bench-a"]) as store:
        sync_store(store, lab_url, batch_size=5)  # many statements: many point sets per key
    with LabStore(lab_url) as lab:
        assert lab.query("SELECT version FROM bench.schema_version") == [(LAB_SCHEMA_VERSION,)]
        assert lab.query("SELECT to_regclass('bench.pose_points')") == [(None,)]
        assert lab.query("SELECT sum(cardinality(x_mm)), sum(cardinality(z_mm)) FROM bench.pose_point_sets") == [
            (len(samples), len(samples))
        ]
        assert (
            lab.query("SELECT count(*) FROM bench.pose_point_sets")[0][0]
            > lab.query("SELECT count(*) FROM bench.pose_keys")[0][0]
        )
        _assert_figures(pose_summary(lab), samples)


_FINITE = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False, allow_infinity=False)
#: One sample: pose name or none, velocity or none, commanded point (one of two), attained point, or an axis missing.
_POSE_SAMPLE = st.tuples(
    st.sampled_from(["P1", "P2", None]),
    st.sampled_from([50.0, None]),
    st.sampled_from(list(COMMANDS.values())),
    st.tuples(_FINITE, _FINITE, _FINITE),
    st.booleans(),
)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(samples=st.lists(_POSE_SAMPLE, min_size=1, max_size=40), batch_size=st.integers(1, 12))
def test_the_fold_holds_each_pose_sample_once_whatever_the_batches(tmp_path_factory, lab_url, samples, batch_size):
    """Each pose key's count and sums, and its points as a multiset, equal those of the samples, however the sync
    cuts the run into statements (each one point set per key)."""
    path = tmp_path_factory.mktemp("fold") / "bench.db"
    expected: dict[tuple, list[tuple[float, float, float]]] = defaultdict(list)
    with Store(path, bench="bench-f") as store:
        run_id = store.start_run(protocol_name="iso9283_pose", protocol_version="1", robot="pkm5", config={})
        run_uuid = store.run(run_id).uuid
        for step, (pose, velocity, command, xyz, partial) in enumerate(samples):
            values = {**dict(zip(("cmd_x_mm", "cmd_y_mm", "cmd_z_mm"), command)), "x_mm": xyz[0], "y_mm": xyz[1]}
            if not partial:  # a laser-grid screen that did not decode: no z, not a pose point
                values["z_mm"] = xyz[2]
                expected[(pose or "", math.nan if velocity is None else velocity, *command)].append(xyz)
            if velocity is not None:
                values["velocity_pct"] = velocity
            store.add_sample(run_id, step, values=values, pose=pose, cycle=1, t_s=step * 0.5)
        sync_store(store, lab_url, batch_size=batch_size)
    with LabStore(lab_url) as lab:
        keys = lab.query(
            "SELECT id, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm, n, sum_x_mm, sum_y_mm, sum_z_mm"
            " FROM bench.pose_keys WHERE run_uuid = %s",
            (run_uuid,),
        )
        sets = lab.query(
            "SELECT key, x_mm, y_mm, z_mm FROM bench.pose_point_sets WHERE key = ANY(%s)", ([k[0] for k in keys],)
        )
    points: dict[int, list[tuple[float, float, float]]] = defaultdict(list)
    for key, xs, ys, zs in sets:
        points[key].extend(zip(xs, ys, zs))
    got = {}
    for key_id, pose, velocity, cx, cy, cz, n, sx, sy, sz in keys:
        assert n == len(points[key_id])
        assert (sx, sy, sz) == pytest.approx(tuple(map(math.fsum, zip(*points[key_id]))), rel=1e-12, abs=1e-9)
        got[(pose, velocity, cx, cy, cz)] = sorted(points[key_id])

    def comparable(key: tuple) -> tuple:  # NaN (no velocity) never equals itself as a dict key
        return (key[0], -1.0 if math.isnan(key[1]) else key[1], *key[2:])

    assert {comparable(k): v for k, v in got.items()} == {comparable(k): sorted(v) for k, v in expected.items()}


def test_samples_changed_or_deleted_by_hand_are_refolded(tmp_path, lab_url):
    paths, samples = make_campaigns(tmp_path)
    for path in paths.values():
        with Store(path) as store:
            sync_store(store, lab_url)
    with psycopg.connect(lab_url, autocommit=True) as conn:
        conn.execute("UPDATE bench.samples SET x_mm = x_mm + 0.0 WHERE kind = 'pose'")
        with LabStore(lab_url) as lab:
            _assert_figures(pose_summary(lab), samples)
        conn.execute("DELETE FROM bench.samples s USING bench.runs r WHERE r.uuid = s.run_uuid AND r.bench = 'bench-b'")
        with LabStore(lab_url) as lab:
            _assert_figures(pose_summary(lab), [s for s in samples if s[0] != "bench-b"])
        conn.execute("TRUNCATE bench.samples")
        with LabStore(lab_url) as lab:
            assert pose_summary(lab) == []
            assert lab.query("SELECT count(*) FROM bench.pose_point_sets") == [(0,)]
