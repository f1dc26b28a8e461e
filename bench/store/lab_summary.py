"""Lab-wide pose accuracy and repeatability, computed by the PostgreSQL server from pose tables that sync keeps.

One row per group of pose samples that ISO 9283 would pool: the same bench, robot, week (ISO week, Monday 00:00 UTC,
of the run's start), pose name, commanded velocity (``velocity_pct``, or none) and commanded position. Per group, as
:func:`bench.metrology.iso9283.pose_accuracy` and :func:`~bench.metrology.iso9283.pose_repeatability` compute them
(ISO 9283:1998 clauses 7.2.1 and 7.2.2):

.. math::

    \\bar p = \\frac1n \\sum_j p_j, \\quad AP_P = \\lVert \\bar p - p_c \\rVert, \\quad
    l_j = \\lVert p_j - \\bar p \\rVert, \\quad RP_l = \\bar l + 3 \\sqrt{\\frac{\\sum_j (l_j - \\bar l)^2}{n - 1}}

Only samples of kind ``pose`` with all three measured axes count (a laser-grid screen that did not decode leaves an
axis absent: such samples are not partial poses here). RP needs n >= 2 and is None below that, with the reason.

Kept at sync time (lab schema 3), by a statement trigger on ``bench.samples`` that sees each COPY's or INSERT's new
rows (so every path that stores a sample, and only samples stored, counts once); bench never changes or deletes a
synced sample, but a hand-made ``UPDATE`` or ``DELETE`` refolds the runs it touched (``TRUNCATE`` empties them):

- ``bench.pose_keys``: one row per run and pose key (pose, velocity, commanded position) with the sums of the
  attained x, y, z and their count; pooled here into each group's barycentre (a few hundred rows read, no scan);
- ``bench.pose_point_sets`` (lab schema 5): the attained points of the pose samples, one row per key and statement
  that stored some (x, y, z as three arrays: about 24 bytes a point where ``bench.samples`` holds about 290 a
  sample; a row per point, schema 3 and 4's ``bench.pose_points``, cost the sync 2.4 us a sample of the server's
  CPU, the arrays 0.6-1.0), unnested in one scan with the barycentres sent as arrays indexed by key to summarise the
  distances l_j per group (``avg``, ``stddev_samp``: PostgreSQL's Youngs-Cramer accumulation).

l_j needs the group's barycentre, which runs synced later can move, so it cannot be kept at sync time; and sums of
squares would cancel (positions near 300 mm, spreads near 1e-3 mm), so the distance pass stays exact per sample.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Protocol

from bench.store.lab_records import RUN_CHECK_SQL, refuse_damaged_run

__all__ = ["POSE_TABLES_BACKFILL", "POSE_TABLES_DDL", "PoseGroup", "pose_summary"]

_POSE_SAMPLES = """kind = 'pose' AND x_mm IS NOT NULL AND y_mm IS NOT NULL AND z_mm IS NOT NULL
    AND cmd_x_mm IS NOT NULL AND cmd_y_mm IS NOT NULL AND cmd_z_mm IS NOT NULL"""

#: The runs a summary groups, with each run's checked columns (:data:`bench.store.lab_records.RUN_CHECK_SQL`): its
#: bench, robot and start, which the groups are keyed by, are checked against the checksum its bench stored.
_RUNS_SQL = f"""SELECT r.uuid, r.bench, r.robot,
    date_trunc('week', r.started_utc::timestamptz AT TIME ZONE 'UTC')::date, r.local_id, {RUN_CHECK_SQL}
FROM bench.runs r WHERE true {{where}}"""

#: The pose key of a sample: a missing pose or velocity becomes '' or NaN (NaN equals NaN in PostgreSQL).
_KEY = (
    "run_uuid, coalesce(pose, '') AS pose, coalesce(velocity_pct, 'NaN') AS velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm"
)
_SAME_KEY = """k.run_uuid = {s}.run_uuid AND k.pose = coalesce({s}.pose, '')
    AND k.velocity_pct = coalesce({s}.velocity_pct, 'NaN') AND k.cmd_x_mm = {s}.cmd_x_mm AND k.cmd_y_mm = {s}.cmd_y_mm
    AND k.cmd_z_mm = {s}.cmd_z_mm"""

#: Fold the pose samples of ``{source}`` (new rows, or all of bench.samples for a migration) into the pose tables
#: in one statement that reads ``{source}`` once: per key, the sums and the attained points as arrays (one
#: aggregation); the sums added to the keys that exist, new keys inserted for the others (only those missing, so
#: that key ids stay dense: a conflicting insert uses up an id; the ``ON CONFLICT`` adds the sums when another sync
#: of the same run inserted the key meanwhile); then one ``bench.pose_point_sets`` row per key with its arrays.
#: (Schema 4 inserted one ``bench.pose_points`` row per sample and read ``{source}`` twice: 2.4 us a sample of the
#: server's 8.0, measured by ``benchmarks/bench_sync_costs.py``.)
_FOLD_SQL = f"""
WITH batch AS MATERIALIZED (
    SELECT {_KEY}, sum(x_mm) AS sum_x_mm, sum(y_mm) AS sum_y_mm, sum(z_mm) AS sum_z_mm, count(*) AS n,
           array_agg(x_mm) AS x_mm, array_agg(y_mm) AS y_mm, array_agg(z_mm) AS z_mm
    FROM {{source}} AS s WHERE {_POSE_SAMPLES} GROUP BY 1, 2, 3, 4, 5, 6
), added_to AS (
    UPDATE bench.pose_keys k SET sum_x_mm = k.sum_x_mm + a.sum_x_mm, sum_y_mm = k.sum_y_mm + a.sum_y_mm,
                                 sum_z_mm = k.sum_z_mm + a.sum_z_mm, n = k.n + a.n
    FROM batch AS a
    WHERE {_SAME_KEY.format(s="a")}
    RETURNING k.id, k.run_uuid, k.pose, k.velocity_pct, k.cmd_x_mm, k.cmd_y_mm, k.cmd_z_mm
), inserted AS (
    INSERT INTO bench.pose_keys AS k (run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm, sum_x_mm,
                                      sum_y_mm, sum_z_mm, n)
    SELECT run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm, sum_x_mm, sum_y_mm, sum_z_mm, n
    FROM batch AS a WHERE NOT EXISTS (SELECT FROM bench.pose_keys k WHERE {_SAME_KEY.format(s="a")})
    ON CONFLICT (run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm) DO UPDATE
        SET sum_x_mm = k.sum_x_mm + EXCLUDED.sum_x_mm, sum_y_mm = k.sum_y_mm + EXCLUDED.sum_y_mm,
            sum_z_mm = k.sum_z_mm + EXCLUDED.sum_z_mm, n = k.n + EXCLUDED.n
    RETURNING k.id, k.run_uuid, k.pose, k.velocity_pct, k.cmd_x_mm, k.cmd_y_mm, k.cmd_z_mm
)
INSERT INTO bench.pose_point_sets (key, x_mm, y_mm, z_mm)
SELECT k.id, a.x_mm, a.y_mm, a.z_mm
FROM (SELECT * FROM added_to UNION ALL SELECT * FROM inserted) AS k JOIN batch AS a ON {_SAME_KEY.format(s="a")};
"""

#: Lab schema 3: the pose tables and the trigger that keeps them (see the module docstring).
POSE_TABLES_DDL = (
    """
CREATE TABLE IF NOT EXISTS bench.pose_keys (
    id serial PRIMARY KEY,
    run_uuid uuid NOT NULL REFERENCES bench.runs (uuid),
    pose text NOT NULL,
    velocity_pct double precision NOT NULL,
    cmd_x_mm double precision NOT NULL,
    cmd_y_mm double precision NOT NULL,
    cmd_z_mm double precision NOT NULL,
    sum_x_mm double precision NOT NULL,
    sum_y_mm double precision NOT NULL,
    sum_z_mm double precision NOT NULL,
    n bigint NOT NULL,
    UNIQUE (run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm)
);
DROP TABLE IF EXISTS bench.pose_points;  -- schemas 3 and 4: one row per point (refilled as point sets below)
CREATE TABLE IF NOT EXISTS bench.pose_point_sets (
    key integer NOT NULL,  -- a bench.pose_keys id; no foreign key: its check per row would slow every sync
    x_mm double precision[] NOT NULL,  -- the attained points of one statement's samples of that key
    y_mm double precision[] NOT NULL,
    z_mm double precision[] NOT NULL
);
-- Out of line uncompressed: pglz finds little to compress in measured coordinates and costs the sync its time.
ALTER TABLE bench.pose_point_sets ALTER COLUMN x_mm SET STORAGE EXTERNAL, ALTER COLUMN y_mm SET STORAGE EXTERNAL,
    ALTER COLUMN z_mm SET STORAGE EXTERNAL;
CREATE OR REPLACE FUNCTION bench.fold_new_pose_samples() RETURNS trigger LANGUAGE plpgsql AS $fold$
BEGIN
"""
    + _FOLD_SQL.format(source="new_samples")
    + """
    RETURN NULL;
END
$fold$;
CREATE OR REPLACE FUNCTION bench.refold_changed_pose_samples() RETURNS trigger LANGUAGE plpgsql AS $refold$
BEGIN
    DELETE FROM bench.pose_point_sets p USING bench.pose_keys k
        WHERE p.key = k.id AND k.run_uuid IN (SELECT run_uuid FROM old_samples);
    DELETE FROM bench.pose_keys WHERE run_uuid IN (SELECT run_uuid FROM old_samples);
"""
    + _FOLD_SQL.format(source="(SELECT * FROM bench.samples WHERE run_uuid IN (SELECT run_uuid FROM old_samples))")
    + """
    RETURN NULL;
END
$refold$;
CREATE OR REPLACE FUNCTION bench.empty_pose_tables() RETURNS trigger LANGUAGE plpgsql AS $empty$
BEGIN
    TRUNCATE bench.pose_point_sets, bench.pose_keys;
    RETURN NULL;
END
$empty$;
DROP TRIGGER IF EXISTS samples_fold_pose ON bench.samples;
CREATE TRIGGER samples_fold_pose AFTER INSERT ON bench.samples REFERENCING NEW TABLE AS new_samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.fold_new_pose_samples();
DROP TRIGGER IF EXISTS samples_refold_pose_after_delete ON bench.samples;
CREATE TRIGGER samples_refold_pose_after_delete AFTER DELETE ON bench.samples REFERENCING OLD TABLE AS old_samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.refold_changed_pose_samples();
DROP TRIGGER IF EXISTS samples_refold_pose_after_update ON bench.samples;
CREATE TRIGGER samples_refold_pose_after_update AFTER UPDATE ON bench.samples REFERENCING OLD TABLE AS old_samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.refold_changed_pose_samples();
DROP TRIGGER IF EXISTS samples_empty_pose_tables ON bench.samples;
CREATE TRIGGER samples_empty_pose_tables AFTER TRUNCATE ON bench.samples
    FOR EACH STATEMENT EXECUTE FUNCTION bench.empty_pose_tables();
"""
)

#: Lab schemas 2, 3, 4 -> 5: the pose tables (re)filled from the samples the server holds.
POSE_TABLES_BACKFILL = "TRUNCATE bench.pose_point_sets, bench.pose_keys RESTART IDENTITY;" + _FOLD_SQL.format(
    source="bench.samples"
)

_KEYS_SQL = """
SELECT id, run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm, sum_x_mm, sum_y_mm, sum_z_mm, n
FROM bench.pose_keys WHERE run_uuid = ANY(%s::uuid[])"""

#: l_j against its group's barycentre, summarised per group; arrays indexed by key id - first + 1 over the keys'
#: range (group -1: a key of a run not asked for). No NULL in the arrays: a subscript into an array with NULLs
#: walks its null bitmap, one subscript into one without is one offset. The point sets unnested in the select list
#: (zipped, streamed: about 25 % faster than ``ROWS FROM`` in the FROM clause, which copies each set first).
_DISTANCES_SQL = """
SELECT g, avg(l), stddev_samp(l)
FROM (SELECT (%(group)s::int[])[key - %(first)s + 1] AS g,
             sqrt((x - (%(bx)s::float8[])[key - %(first)s + 1]) ^ 2
                  + (y - (%(by)s::float8[])[key - %(first)s + 1]) ^ 2
                  + (z - (%(bz)s::float8[])[key - %(first)s + 1]) ^ 2) AS l
      FROM (SELECT key, unnest(x_mm) AS x, unnest(y_mm) AS y, unnest(z_mm) AS z FROM bench.pose_point_sets
            WHERE key BETWEEN %(first)s AND %(last)s) AS point) AS distance
WHERE g >= 0
GROUP BY g"""

#: For the distance pass only: no JIT (compiling costs more than it saves); hash aggregation in memory, never a
#: sort of every point (chosen, 2.3x slower, while autovacuum has not yet analysed a freshly synced table).
_SETTINGS = {"enable_sort": "off", "jit": "off", "work_mem": "64MB"}


@dataclass(frozen=True)
class PoseGroup:
    """AP and RP of one group of pose samples (see the module docstring); lengths in mm."""

    bench: str
    robot: str
    week: dt.date  #: Monday (UTC) of the ISO week the runs started in
    pose: str | None
    velocity_pct: float | None
    commanded_mm: tuple[float, float, float]
    n: int
    barycentre_mm: tuple[float, float, float]
    ap_mm: float
    l_mean_mm: float
    rp_mm: float | None  #: None when n < 2 (see ``rp_refused``)

    @property
    def rp_refused(self) -> str | None:
        """Why RP is not given, or None."""
        return None if self.rp_mm is not None else f"RP needs at least 2 cycles, this group has {self.n}"

    def as_dict(self) -> dict[str, object]:
        out = asdict(self)
        out["week"] = self.week.isoformat()
        out["rp_refused"] = self.rp_refused
        return out


class LabQueries(Protocol):
    """What the summary needs of a lab store: :meth:`bench.store.lab.LabStore.query`, and its ``path`` (the URL with
    its password hidden) to name it."""

    path: str

    def query(
        self, sql: str, args: Any = (), *, settings: Mapping[str, str] | None = None
    ) -> list[tuple[Any, ...]]: ...


def _group_key(run: tuple[Any, ...], pose: str, velocity: float, cx: float, cy: float, cz: float) -> tuple[Any, ...]:
    """The group of a run and pose key: the run's (bench, robot, week), the pose, the velocity (None for the
    server's NaN, which as a dict key would never equal itself) and the command."""
    return (*run, pose, None if math.isnan(velocity) else velocity, cx, cy, cz)


def pose_summary(
    lab: LabQueries,
    *,
    since: str | None = None,
    until: str | None = None,
    bench: str | None = None,
    robot: str | None = None,
) -> list[PoseGroup]:
    """The :class:`PoseGroup` rows of the lab store ``lab`` (a :class:`bench.store.lab.LabStore`), for runs started
    at or after ``since`` and before ``until`` (ISO dates or times, UTC), of ``bench`` and ``robot`` when given.

    Every run the summary groups is checked first (its record against the checksum its bench stored, lab schema
    5): one changed on the server (its robot, bench or start, which the groups are keyed by, or anything else its
    checksum covers) refuses the summary in one line naming the run
    (:class:`bench.store.record_checksum.DamagedRecord`), as export and report refuse it; ``--bench``, ``--robot``
    and the dates leave it out. The samples' own checksums are not read here (the summary reads the pose point sets
    folded from them at sync): ``bench store check URL`` checks them."""
    clauses, args = [], []
    for clause, value in (
        ("r.started_utc >= %s", since),
        ("r.started_utc < %s", until),
        ("r.bench = %s", bench),
        ("r.robot = %s", robot),
    ):
        if value is not None:
            clauses.append(f"AND {clause}")
            args.append(value)
    runs = {}
    for uuid, run_bench, run_robot, week, local_id, *checked in lab.query(
        _RUNS_SQL.format(where=" ".join(clauses)), args
    ):
        refuse_damaged_run(f"{run_bench}/{local_id}", checked, lab.path)
        runs[uuid] = (run_bench, run_robot, week)
    if not runs:
        return []
    sums = lab.query(_KEYS_SQL, (list(runs),))
    pooled: dict[tuple[Any, ...], list[float]] = {}
    group_of_key: dict[int, tuple[Any, ...]] = {}
    for key_id, run_uuid, pose, velocity, cx, cy, cz, sx, sy, sz, n in sums:
        group = _group_key(runs[run_uuid], pose, velocity, cx, cy, cz)
        group_of_key[key_id] = group
        totals = pooled.setdefault(group, [0.0, 0.0, 0.0, 0])
        totals[0] += sx
        totals[1] += sy
        totals[2] += sz
        totals[3] += n
    keys = sorted(pooled, key=lambda key: (key[:4], key[4] is None, key[4] or 0.0, key[5:]))
    index = {key: g for g, key in enumerate(keys)}
    barycentres = {key: (sx / n, sy / n, sz / n) for key, (sx, sy, sz, n) in pooled.items()}
    distances = {}
    if group_of_key:
        first, last = min(group_of_key), max(group_of_key)
        size = last - first + 1
        arrays: dict[str, list[Any]] = {
            "group": [-1] * size,
            "bx": [0.0] * size,
            "by": [0.0] * size,
            "bz": [0.0] * size,
        }
        for key_id, group in group_of_key.items():
            at = key_id - first
            arrays["group"][at] = index[group]
            arrays["bx"][at], arrays["by"][at], arrays["bz"][at] = barycentres[group]
        distances = {
            g: (l_mean, s_l)
            for g, l_mean, s_l in lab.query(
                _DISTANCES_SQL, {**arrays, "first": first, "last": last}, settings=_SETTINGS
            )
        }
    groups = []
    for key in keys:
        run_bench, run_robot, week, pose, velocity, cx, cy, cz = key
        b = barycentres[key]
        l_mean, s_l = distances[index[key]]
        groups.append(
            PoseGroup(
                bench=run_bench,
                robot=run_robot,
                week=week,
                pose=pose or None,
                velocity_pct=velocity,
                commanded_mm=(cx, cy, cz),
                n=int(pooled[key][3]),
                barycentre_mm=b,
                ap_mm=math.sqrt((b[0] - cx) ** 2 + (b[1] - cy) ** 2 + (b[2] - cz) ** 2),
                l_mean_mm=l_mean,
                rp_mm=None if s_l is None else l_mean + 3.0 * s_l,
            )
        )
    return groups
