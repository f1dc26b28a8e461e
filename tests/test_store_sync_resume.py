"""A run resumed after it was synced: the second ``sync_store`` carries everything the resume added (the new
segment's registration in the run's settings, the new segment's samples, the settled status, reason and end, a
calibration made from the run), against a real PostgreSQL server (``postgres_support``; skips with the reason)."""

from __future__ import annotations

import json

import pytest

psycopg = pytest.importorskip("psycopg", reason='the lab store needs psycopg 3 (pip install "psycopg[binary]")')

from postgres_support import lab_server, lab_url  # noqa: E402, F401  (fixtures)
from test_protocols import Answers, BiasedInstrument, RecordingRobot  # noqa: E402

from bench.protocols import Rig, Runner  # noqa: E402
from bench.protocols.iso9283 import PoseAccuracy  # noqa: E402
from bench.store import Store  # noqa: E402
from bench.store.lab import LabStore, rows_checksum, sync_store  # noqa: E402


def _rig(robot: RecordingRobot, registered_utc: str, u_mm: float) -> Rig:
    """A rig whose relative instrument was registered at ``registered_utc`` (what ``bench.rigs.builder`` files)."""
    return Rig(
        robot,
        BiasedInstrument(),
        Answers(),
        speed_factor=1e6,
        sleep=lambda s: None,
        registration={"utc": registered_utc, "u_mm": u_mm, "check_discrepancy_mm": 0.01},
    )


def _server_view(url: str, run_uuid: str) -> tuple:
    """(the run as the server lists it, its sample checksum, pose samples folded in the pose tables, settings)."""
    with LabStore(url) as lab:
        (run,) = [r for r in lab.runs() if r.uuid == run_uuid]
        folded = lab.query("SELECT sum(n) FROM bench.pose_keys WHERE run_uuid = %s", (run_uuid,))[0][0]
        points = lab.query(
            "SELECT sum(cardinality(p.x_mm)) FROM bench.pose_point_sets p JOIN bench.pose_keys k ON k.id = p.key"
            " WHERE k.run_uuid = %s",
            (run_uuid,),
        )[0][0]
        (settings,) = lab.query("SELECT settings_json FROM bench.runs WHERE uuid = %s", (run_uuid,))[0]
        return run, lab.checksum(run_uuid), (int(folded), int(points)), json.loads(settings)


def _records_check(url: str) -> tuple[list[str], list[str]]:
    """The lab's damaged runs and calibrations, and those it could not check (both empty when all is sound)."""
    with LabStore(url) as lab:
        assert lab.query("SELECT count(*) FROM bench.runs WHERE checksum IS NULL") == [(0,)]
        return lab.check_records()


def test_a_run_resumed_after_its_sync_sends_what_the_resume_added(tmp_path, lab_url):
    protocol = PoseAccuracy(cycles=3, velocities_pct=[100, 10], settle_s=0.5)  # 30 pose samples
    with Store(tmp_path / "bench.db", bench="bench-r") as store:
        failed = Runner(_rig(RecordingRobot(fail_after=8), "2026-12-02T09:00:00+00:00", 0.70), store).run(protocol)
        assert (failed.exit_status, failed.samples) == ("failed", 8)
        first = sync_store(store, lab_url)
        (local,) = store.runs()
        run, checksum, folded, settings = _server_view(lab_url, local.uuid)
        assert (first.samples_sent, run, checksum, folded) == (
            8,
            local,
            rows_checksum(store.stored_rows(failed.run_id)),
            (8, 8),
        )
        assert [e["segment"] for e in settings["registrations"]] == [1]
        assert _records_check(lab_url) == ([], [])  # the record and its calibration, against their checksums

        resumed = Runner(_rig(RecordingRobot(), "2026-12-02T10:00:00+00:00", 0.74), store).resume_run(failed.run_id)
        assert (resumed.exit_status, resumed.samples) == ("completed", 30)
        made = store.add_calibration("mouse", {"mm_per_count": 0.0318}, source_run_id=failed.run_id)
        second = sync_store(store, lab_url)
        (local,) = store.runs()
        run, checksum, folded, settings = _server_view(lab_url, local.uuid)
        assert (second.samples_sent, second.calibrations) == (22, 1)
        # the whole run record as the file holds it: status, reason (none now), end, settings with both segments
        assert (run, checksum, folded) == (local, rows_checksum(store.stored_rows(failed.run_id)), (30, 30))
        assert (run.status, run.reason, run.ended_utc is not None) == ("completed", None, True)
        assert [(e["segment"], e["u_mm"], e["from_step"]) for e in settings["registrations"]] == [
            (1, 0.70, 0),
            (2, 0.74, local.settings["registrations"][1]["from_step"]),
        ]
        assert settings == local.settings
        with LabStore(lab_url) as lab:
            assert lab.query("SELECT uuid::text, source_run_uuid::text, params_json FROM bench.calibrations") == [
                (made.uuid, local.uuid, '{"mm_per_count": 0.0318}')
            ]
        assert _records_check(lab_url) == ([], [])  # the record re-sealed by the resume, as the file sealed it
        assert sync_store(store, lab_url).samples_sent == 0  # and a third sync has nothing left to send
    assert _server_view(lab_url, local.uuid)[:3] == (run, checksum, (30, 30))
