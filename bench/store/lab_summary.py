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
The server does two passes over the samples (barycentres, then distances to them) in one statement.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import asdict, dataclass

__all__ = ["PoseGroup", "pose_summary"]

_SAMPLE_KEY = "run_uuid, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm"
_GROUP_KEY = "bench, robot, week, pose, velocity_pct, cmd_x_mm, cmd_y_mm, cmd_z_mm"

#: Pass 1 sums per run and pose (small), pooled per group into barycentres; pass 2 joins each sample to its
#: group's barycentre (a hash of a few hundred rows) for the distances l_j. The samples are read once, into the
#: narrow ``s``; a missing velocity becomes NaN, which equals NaN in PostgreSQL (joinable, unlike NULL).
_SUMMARY_SQL = """
WITH rk AS (
    SELECT uuid AS run_uuid, bench, robot,
           date_trunc('week', started_utc::timestamptz AT TIME ZONE 'UTC')::date AS week
    FROM bench.runs r WHERE true {where}),
s AS MATERIALIZED (
    SELECT run_uuid, coalesce(pose, '') AS pose, coalesce(velocity_pct, 'NaN') AS velocity_pct,
           cmd_x_mm, cmd_y_mm, cmd_z_mm, x_mm, y_mm, z_mm
    FROM bench.samples
    WHERE kind = 'pose' AND x_mm IS NOT NULL AND y_mm IS NOT NULL AND z_mm IS NOT NULL AND cmd_x_mm IS NOT NULL
      AND cmd_y_mm IS NOT NULL AND cmd_z_mm IS NOT NULL AND run_uuid IN (SELECT run_uuid FROM rk)),
p AS (
    SELECT {sample_key}, sum(x_mm) AS sx, sum(y_mm) AS sy, sum(z_mm) AS sz, count(*) AS n
    FROM s GROUP BY {sample_key}),
m AS (
    SELECT {group_key}, sum(sx) / sum(n) AS bx, sum(sy) / sum(n) AS by, sum(sz) / sum(n) AS bz, sum(n) AS n,
           row_number() OVER () AS g
    FROM p JOIN rk USING (run_uuid) GROUP BY {group_key}),
link AS (
    SELECT {p_sample_key}, m.g, m.bx, m.by, m.bz FROM p JOIN rk USING (run_uuid) JOIN m USING ({group_key})),
d AS (
    SELECT link.g, avg(l) AS l_mean, stddev_samp(l) AS s_l
    FROM s JOIN link USING ({sample_key}),
         LATERAL (SELECT sqrt((s.x_mm - link.bx) ^ 2 + (s.y_mm - link.by) ^ 2 + (s.z_mm - link.bz) ^ 2) AS l) AS dist
    GROUP BY link.g)
SELECT m.bench, m.robot, m.week, nullif(m.pose, ''), nullif(m.velocity_pct, 'NaN'), m.cmd_x_mm, m.cmd_y_mm,
       m.cmd_z_mm, m.n, m.bx, m.by, m.bz,
       sqrt((m.bx - m.cmd_x_mm) ^ 2 + (m.by - m.cmd_y_mm) ^ 2 + (m.bz - m.cmd_z_mm) ^ 2), d.l_mean,
       d.l_mean + 3 * d.s_l
FROM m JOIN d USING (g)
ORDER BY m.bench, m.robot, m.week, m.pose, m.velocity_pct, m.cmd_x_mm, m.cmd_y_mm, m.cmd_z_mm
"""
#: For this query only: the narrow copy of the samples in memory; a hash join against the few hundred groups
#: (the planner, misjudging the groups' number, would sort a million rows for a merge join); no JIT (its
#: compilation costs more than it saves here).
_SETTINGS = {"work_mem": "256MB", "enable_mergejoin": "off", "enable_nestloop": "off", "jit": "off"}


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
    p_sample_key = ", ".join(f"p.{name.strip()}" for name in _SAMPLE_KEY.split(","))
    sql = _SUMMARY_SQL.format(where=" ".join(clauses), sample_key=_SAMPLE_KEY, group_key=_GROUP_KEY,
                              p_sample_key=p_sample_key)
    rows = lab.query(sql, args, settings=_SETTINGS)
    return [PoseGroup(bench=r[0], robot=r[1], week=r[2], pose=r[3], velocity_pct=r[4], commanded_mm=(r[5], r[6], r[7]),
                      n=int(r[8]), barycentre_mm=(r[9], r[10], r[11]), ap_mm=r[12], l_mean_mm=r[13], rp_mm=r[14])
            for r in rows]
