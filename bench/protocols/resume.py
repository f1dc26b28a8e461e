"""What a resumed run needs from its stored record: the protocol as it ran, refused when it cannot continue, and
the replies of the samples already stored (:meth:`bench.protocols.runner.Runner.resume_run`)."""

from __future__ import annotations

from typing import Any

from bench.errors import ConfigError
from bench.protocols.base import Protocol, protocol_from_config
from bench.rigs.interfaces import Rig
from bench.store import Store

__all__ = ["resumable_protocol", "stored_replies"]


def resumable_protocol(record: Any, rig: Rig) -> Protocol:
    """The protocol of stored run ``record`` regenerated from its configuration, or ``ConfigError`` when it cannot
    be resumed on ``rig``: completed already, its protocol's version changed since, or other calibrations in force
    (one stored since would change its numbers)."""
    run_id = record.id
    if record.status == "completed":
        raise ConfigError(f"run {run_id}: already completed, nothing to resume")
    protocol = protocol_from_config(record.config, source=f"run {run_id}", stored=True)
    if protocol.version != record.protocol_version:
        raise ConfigError(
            f"run {run_id}: protocol {protocol.name} is now version {protocol.version}, the run "
            f"used version {record.protocol_version}; cannot resume across versions"
        )
    if tuple(sorted(rig.calibration_ids)) != tuple(record.calibration_ids):
        raise ConfigError(
            f"run {run_id}: calibrations in force {sorted(rig.calibration_ids)} differ from "
            f"the run's {list(record.calibration_ids)}; a run resumes only with the calibrations "
            "it started with (a calibration stored since would change its numbers): start a new "
            "run (bench run)"
        )
    return protocol


def stored_replies(store: Store, run_id: int) -> dict[int, Any]:
    """Per step index, what its stored sample sends back to the plan: a prompt's reading, or a capture's values."""
    return {sample.step_index: _reply_of(sample) for sample in store.samples(run_id)}


def _reply_of(sample: Any) -> Any:
    if isinstance(sample.raw, dict) and "field" in sample.raw and "entered" in sample.raw:  # a prompt's reading
        return sample.values[sample.raw["field"]]
    return dict(sample.values)
