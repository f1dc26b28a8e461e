"""The records the run store reads back (runs, samples, calibrations), the run statuses, and the JSON and time
text every stored row uses."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import msgspec

from bench.errors import BenchError, ConfigError

__all__ = [
    "INTERRUPTED",
    "RUN_STATUSES",
    "CalibrationRecord",
    "DuplicateSample",
    "RunRecord",
    "SampleRecord",
    "to_json",
    "utc_now",
]

#: The closed set of stored run statuses.
RUN_STATUSES = ("running", "completed", "failed", "aborted")
#: The status a stored ``running`` run reads as when no live process owns it (derived when read, never stored).
INTERRUPTED = "interrupted"


class DuplicateSample(BenchError):
    """A sample for a step that already has one: resuming must skip stored steps, never store them twice."""


@dataclass(frozen=True)
class RunRecord:
    """One stored run, as read back from the ``runs`` table."""

    id: int
    uuid: str
    bench: str
    campaign: str | None
    protocol_name: str
    protocol_version: str
    robot: str
    config: dict[str, Any]
    settings: dict[str, Any]
    calibration_ids: tuple[int, ...]
    software_version: str
    git_sha: str
    status: str
    reason: str | None
    started_utc: str
    ended_utc: str | None
    n_samples: int

    @property
    def simulated(self) -> bool:
        """True for a run on simulators (the simulated rig or a station's rehearsal): its settings name the
        simulator it ran on."""
        return "simulator" in self.settings

    def as_dict(self) -> dict[str, Any]:
        """Plain, JSON-ready form (used by ``bench runs --json``), with ``simulated``."""
        out = dict(self.__dict__)
        out["calibration_ids"] = list(self.calibration_ids)
        out["simulated"] = self.simulated
        return out

    @classmethod
    def from_row(cls, row: Sequence[Any], *, run_id: int, calibration_ids: tuple[int, ...]) -> RunRecord:
        """A run read from a store: ``row`` in the order the local and the lab's run queries select (local id, uuid,
        bench, campaign, protocol name and version, robot, config and settings JSON, calibrations JSON, software
        version, git sha, status, reason, started, ended, sample count); the caller numbers the run and its
        calibrations."""
        return cls(
            id=run_id,
            uuid=row[1],
            bench=row[2],
            campaign=row[3],
            protocol_name=row[4],
            protocol_version=row[5],
            robot=row[6],
            config=from_json(row[7]),
            settings=from_json(row[8]),
            calibration_ids=calibration_ids,
            software_version=row[10],
            git_sha=row[11],
            status=row[12],
            reason=row[13],
            started_utc=row[14],
            ended_utc=row[15],
            n_samples=int(row[16]),
        )


@dataclass(frozen=True)
class SampleRecord:
    """One raw sample: the step that produced it, where and when, its values (unit in every key) and raw data."""

    run_id: int
    step_index: int
    kind: str
    pose: str | None
    cycle: int | None
    t_s: float
    wall_utc: str
    values: dict[str, float]
    raw: Any


@dataclass(frozen=True)
class CalibrationRecord:
    """One version of a named calibration (e.g. ``mouse_xy``), with its parameters and the run it came from."""

    id: int
    uuid: str
    name: str
    version: int
    created_utc: str
    params: dict[str, Any]
    source_run_id: int | None
    notes: str


def utc_now() -> str:
    """Now, as the ISO UTC text every stored time uses (microseconds)."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


#: msgspec's strict decoder: 5-6x the standard library's speed on a path sample's series (1.56 -> 0.28 s for a run of
#: 1.16 M points, benchmarks/bench_path_report.py), floats parsed exactly (correctly rounded, as ``float()``).
_DECODER = msgspec.json.Decoder()


def from_json(text: str | bytes) -> Any:
    """Stored JSON text parsed: the same value as ``json.loads(text)``, or its ``ValueError``.

    msgspec parses what it accepts exactly as ``json.loads`` does (floats correctly rounded, integers of any size,
    the last of repeated keys; ``tests/test_store_json.py`` holds it to that); what it refuses but the standard
    library reads (``NaN``, ``Infinity``, ``1e400``: never written by :func:`to_json`; a lone surrogate, which it
    writes escaped) goes to ``json.loads``, so a value or an error is never different, only faster.
    """
    try:
        return _DECODER.decode(text)
    except ValueError:  # msgspec.DecodeError, or a lone surrogate that str -> UTF-8 cannot encode
        return json.loads(text)


def to_json(value: Any, field: str) -> str:
    """``value`` as stored JSON (sorted keys, finite numbers only); ``ConfigError`` names ``field`` otherwise."""
    try:
        return json.dumps(value, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"store: {field} = {value!r:.80}, expected JSON-serialisable finite values ({exc})") from exc
