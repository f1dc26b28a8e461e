"""Lab-wide pose accuracy and repeatability, computed by the PostgreSQL server from the typed value columns.

One row per group of pose samples that ISO 9283 would pool: the same bench, robot, week (ISO week, Monday 00:00 UTC,
of the run's start), pose name, commanded velocity (``velocity_pct``, or none) and commanded position. Per group, as
:func:`bench.metrology.iso9283.pose_accuracy` and :func:`~bench.metrology.iso9283.pose_repeatability` compute them
(ISO 9283:1998 clauses 7.2.1 and 7.2.2):

.. math::

    \\bar p = \\frac1n \\sum_j p_j, \\quad AP_P = \\lVert \\bar p - p_c \\rVert, \\quad
    l_j = \\lVert p_j - \\bar p \\rVert, \\quad RP_l = \\bar l + 3 \\sqrt{\\frac{\\sum_j (l_j - \\bar l)^2}{n - 1}}

Only samples of kind ``pose`` with all three measured axes count (a laser-grid screen that did not decode leaves an
axis absent: such samples are not partial poses here). RP needs n >= 2 and is None below that, with the reason.

Two passes over the samples, each a parallel scan in the server: sums per run and pose key (a few hundred rows
back), pooled here into each group's barycentre; then, with the barycentres sent back as arrays, the distances
l_j summarised per group (``avg``, ``stddev_samp``: PostgreSQL's Youngs-Cramer accumulation).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import asdict, dataclass

__all__ = ["PoseGroup", "pose_summary"]

_POSE_SAMPLES = """kind = 'pose' AND x_mm IS NOT NULL AND y_mm IS NOT NULL AND z_mm IS NOT NULL
    AND cmd_x_mm IS NOT NULL AND cmd_y_mm IS NOT NULL AND cmd_z_mm IS NOT NULL"""

_RUNS_SQL = """SELECT uuid, bench, robot, date_trunc('week', started_utc::timestamptz AT TIME ZONE 'UTC')::date
FROM bench.runs r WHERE true {where}"""

#: Pass 1: sums per run and pose key; a missing pose or velocity becomes '' or NaN (NaN equals NaN in PostgreSQL).
_SUMS_SQL = """
SELECT run_uuid, coalesce(pose, ''), coalesce(velocity_pct, 'NaN'), cmd_x_mm, cmd_y_mm, cmd_z_mm,
       sum(x_mm), sum(y_mm), sum(z_mm), count(*)
FROM bench.samples
WHERE {pose_samples} AND run_uuid = ANY(%s::uuid[])
GROUP BY 1, 2, 3, 4, 5, 6"""

#: Pass 2: l_j against its group's barycentre, summarised per group ``g``.
_DISTANCES_SQL = """
SELECT k.g, avg(l), stddev_samp(l)
FROM bench.samples s
     JOIN unnest(%s::uuid[], %s::text[], %s::float8[], %s::float8[], %s::float8[], %s::float8[], %s::float8[],
                 %s::float8[], %s::float8[], %s::int[]) AS k(run_uuid, pose, velocity_pct, cx, cy, cz, bx, by, bz, g)
       ON s.run_uuid = k.run_uuid AND coalesce(s.pose, '') = k.pose
          AND coalesce(s.velocity_pct, 'NaN') = k.velocity_pct AND s.cmd_x_mm = k.cx AND s.cmd_y_mm = k.cy
          AND s.cmd_z_mm = k.cz,
     LATERAL (SELECT sqrt((s.x_mm - k.bx) ^ 2 + (s.y_mm - k.by) ^ 2 + (s.z_mm - k.bz) ^ 2) AS l) AS distance
WHERE {pose_samples}
GROUP BY k.g"""

#: For these queries only: a hash join against the few hundred keys and hash aggregation (the planner cannot
#: estimate the join of a parameter array and would sort a million rows); no JIT (compiling costs more than it saves).
_SETTINGS = {"enable_mergejoin": "off", "enable_nestloop": "off", "enable_sort": "off", "jit": "off",
             "work_mem": "64MB"}


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


def _group_key(run: tuple, pose: str, velocity: float, cx: float, cy: float, cz: float) -> tuple:
    """The group of a run and pose key: the run's (bench, robot, week), the pose, the velocity (None for the
    server's NaN, which as a dict key would never equal itself) and the command."""
    return (*run, pose, None if math.isnan(velocity) else velocity, cx, cy, cz)


def pose_summary(lab, *, since: str | None = None, until: str | None = None, bench: str | None = None,
                 robot: str | None = None) -> list[PoseGroup]:
    """The :class:`PoseGroup` rows of the lab store ``lab`` (a :class:`bench.store.lab.LabStore`), for runs started
    at or after ``since`` and before ``until`` (ISO dates or times, UTC), of ``bench`` and ``robot`` when given."""
    clauses, args = [], []
    for clause, value in (("r.started_utc >= %s", since), ("r.started_utc < %s", until), ("r.bench = %s", bench),
                          ("r.robot = %s", robot)):
        if value is not None:
            clauses.append(f"AND {clause}")
            args.append(value)
    runs = {uuid: (run_bench, run_robot, week)
            for uuid, run_bench, run_robot, week in lab.query(_RUNS_SQL.format(where=" ".join(clauses)), args)}
    if not runs:
        return []
    sums = lab.query(_SUMS_SQL.format(pose_samples=_POSE_SAMPLES), (list(runs),), settings=_SETTINGS)
    pooled: dict[tuple, list[float]] = {}
    for run_uuid, pose, velocity, cx, cy, cz, sx, sy, sz, n in sums:
        totals = pooled.setdefault(_group_key(runs[run_uuid], pose, velocity, cx, cy, cz), [0.0, 0.0, 0.0, 0])
        totals[0] += sx
        totals[1] += sy
        totals[2] += sz
        totals[3] += n
    keys = sorted(pooled, key=lambda key: (key[:4], key[4] is None, key[4] or 0.0, key[5:]))
    index = {key: g for g, key in enumerate(keys)}
    barycentres = {key: (sx / n, sy / n, sz / n) for key, (sx, sy, sz, n) in pooled.items()}
    rows = [(run_uuid, pose, velocity, cx, cy, cz, *barycentres[key], index[key])
            for run_uuid, pose, velocity, cx, cy, cz, *_ in sums
            for key in [_group_key(runs[run_uuid], pose, velocity, cx, cy, cz)]]
    distances = {g: (l_mean, s_l) for g, l_mean, s_l in lab.query(
        _DISTANCES_SQL.format(pose_samples=_POSE_SAMPLES.replace("kind", "s.kind")), [list(c) for c in zip(*rows)],
        settings=_SETTINGS)} if rows else {}
    groups = []
    for key in keys:
        run_bench, run_robot, week, pose, velocity, cx, cy, cz = key
        b = barycentres[key]
        l_mean, s_l = distances[index[key]]
        groups.append(PoseGroup(bench=run_bench, robot=run_robot, week=week, pose=pose or None,
                                velocity_pct=velocity, commanded_mm=(cx, cy, cz),
                                n=pooled[key][3], barycentre_mm=b,
                                ap_mm=math.sqrt((b[0] - cx) ** 2 + (b[1] - cy) ** 2 + (b[2] - cz) ** 2),
                                l_mean_mm=l_mean, rp_mm=None if s_l is None else l_mean + 3.0 * s_l))
    return groups
