"""The runner's samples: each stored the moment it is taken, on the store's writer thread, and reported once durable.

A sample's commit starts the moment it is taken and runs on the store's writer thread
(:class:`bench.store.sample_writer.SampleWriter`) while the runner goes on moving and settling; the runner waits for
it (:meth:`SampleRecorder.await_commit`) before anything else, and a sample is reported (counted, shown) only once it
is durable. Sample times ``t_s`` are seconds since the run started in the rig's time base, after the last stored
time of a resumed run, so ``t_s`` never decreases within a run.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from bench.rigs.interfaces import Rig
from bench.store import Store
from bench.store.descriptors import validate_sample
from bench.store.sample_writer import SampleWriter

__all__ = ["SampleRecorder"]

_log = logging.getLogger(__name__)


class SampleRecorder:
    """The samples of one run segment of run ``run_id`` on ``rig``: ``on_durable(sample)`` is called once per sample
    once its commit is durable, with the dict ``Runner``'s ``on_sample`` hook documents."""

    def __init__(self, store: Store, rig: Rig, run_id: int, on_durable: Callable[[dict[str, Any]], None]) -> None:
        self.run_id = run_id
        self._rig = rig
        self._on_durable = on_durable
        self._t_offset_s = max((s.t_s for s in store.samples(run_id)), default=0.0)
        self._t_start = rig.clock()
        self._writer = SampleWriter(store)

    def now_s(self) -> float:
        """Seconds since the run started, in the rig's time base, after the last stored time of a resumed run."""
        return self._t_offset_s + (self._rig.clock() - self._t_start) * self._rig.speed_factor

    def add(
        self,
        index: int,
        values: dict[str, float],
        *,
        kind: str,
        pose: str | None,
        cycle: int | None,
        raw: Any,
    ) -> None:
        """Store the sample of step ``index``, taken now; its commit runs while the runner goes on."""
        t_s = self.now_s()
        validate_sample(kind, values)  # a sample off its descriptor is a bug: refused, never stored
        self.await_commit()  # (done already before the step) one sample in flight at a time, each reported once
        sample = {
            "step_index": index,
            "kind": kind,
            "pose": pose,
            "cycle": cycle,
            "t_s": t_s,
            "values": values,
            "raw": raw,
        }
        self._writer.add(
            self.run_id, index, values=values, kind=kind, pose=pose, cycle=cycle, t_s=t_s, raw=raw, report=sample
        )

    def checkpoint(self) -> None:
        """Queue the store's checkpoint behind the commit in flight (the ``.db`` file alone then holds every
        sample so far)."""
        self._writer.checkpoint()

    def await_commit(self) -> None:
        """Wait until the last sample taken is durable (raising the failure of its commit), then report it."""
        sample = self._writer.wait()
        if sample is not None:
            self._on_durable(sample)

    def close(self) -> Exception | None:
        """Settle the last commit (reported if it succeeded) and close the writer; returns its failure, if any."""
        failure = None
        while True:
            try:
                self.await_commit()
                break
            except KeyboardInterrupt:  # the run is ending already: the commit in flight (ms) settles first
                continue
            except Exception as exc:  # noqa: BLE001 - stored in the run's status and reason
                failure = exc
                _log.error("run %d: the last sample's commit failed: %s: %s", self.run_id, type(exc).__name__, exc)
                break
        self._writer.close()  # nothing in flight any more
        return failure
