"""Run ownership: one live process drives a run; a run whose owner is gone reads as ``interrupted``.

The owner of run ``ID`` of store ``bench.db`` holds an exclusive ``flock`` on the sidecar file
``bench.db.run-ID.lock``, which names it in one JSON line (pid, host, since) and whose modification time it
refreshes every :data:`HEARTBEAT_S` seconds (the heartbeat).

Why a lock file beside the store rather than an owner row in it:

- the kernel releases a ``flock`` the instant its process dies, SIGKILL and power loss of a local process
  included, so "the owner is dead" needs no timeout: no guess, no race with a slow but live owner under load;
- ``flock`` locks belong to an open file, not to a process (unlike ``fcntl``/``lockf`` record locks), so one
  process (the desktop app running a run and browsing the store) sees its own runs as owned, and closing another
  descriptor of the file never drops the lock;
- reading who owns a run writes nothing: ``bench runs`` and the results browser stay read-only, and the store's
  schema is unchanged (a backup copy of the ``.db`` is, rightly, owned by nobody).

The heartbeat is for an owner on another host (a store on a network share, where the lock may not be visible):
its run counts as live while its heartbeat is younger than :data:`STALE_AFTER_S`. On this host the lock alone
decides.

Taking a lock file follows the usual unlink-safe pattern: lock, then check that the path still names the locked
file (a releasing owner unlinks it while it holds the lock), else retry.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from bench.errors import BenchError

__all__ = ["HEARTBEAT_S", "STALE_AFTER_S", "Owner", "RunLease", "RunOwned", "lock_path", "owner_of"]

#: Seconds between two heartbeats of an owner.
HEARTBEAT_S = 2.0
#: An owner on another host whose heartbeat is older than this is taken for gone.
STALE_AFTER_S = 30.0
#: How long taking a lock retries while someone holds it: a reader's probe holds it for microseconds.
_PROBE_GRACE_S = 0.5


class RunOwned(BenchError):
    """The run is driven by another live process (named in the message); nothing of it was touched."""


@dataclass(frozen=True)
class Owner:
    """Who holds (or last held) a run: ``alive`` is False when that process is gone."""

    pid: int
    host: str
    since_utc: str
    alive: bool

    def describe(self) -> str:
        return f"pid {self.pid} on {self.host} since {self.since_utc[:19]} UTC"


def lock_path(store_path: str | Path, run_id: int) -> Path:
    """The sidecar lock file of run ``run_id`` of the store at ``store_path``."""
    return Path(f"{store_path}.run-{int(run_id)}.lock")


def _host() -> str:
    return socket.gethostname()


def _read_owner(fd: int) -> dict[str, Any]:
    os.lseek(fd, 0, os.SEEK_SET)
    text = os.read(fd, 4096).decode("utf-8", "replace")
    try:
        data = json.loads(text)
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


def _owner(data: dict[str, Any], alive: bool) -> Owner:
    return Owner(
        pid=int(data.get("pid", 0) or 0),
        host=str(data.get("host", "?")),
        since_utc=str(data.get("since_utc", "?")),
        alive=alive,
    )


def owner_of(store_path: str | Path, run_id: int) -> Owner | None:
    """The owner of run ``run_id``, alive or gone; None when no lock file exists (nobody has held the run since it
    ended cleanly, or it was made before ownership was recorded). Reads only; creates nothing."""
    path = lock_path(store_path, run_id)
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return None
    except OSError:
        return None
    try:
        data = _read_owner(fd)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _owner(data, alive=True)
        fcntl.flock(fd, fcntl.LOCK_UN)
        if not data:
            return None  # created and not yet written, or released: nobody holds it
        fresh = time.time() - os.fstat(fd).st_mtime < STALE_AFTER_S
        return _owner(data, alive=data.get("host") != _host() and fresh)
    finally:
        os.close(fd)


class RunLease:
    """This process's ownership of one run: the held lock file and its heartbeat thread.

    Raises :class:`RunOwned` when another live process owns the run. ``release()`` (idempotent) removes the lock
    file, then unlocks it.
    """

    def __init__(self, store_path: str | Path, run_id: int) -> None:
        self.run_id = int(run_id)
        self.path = lock_path(store_path, run_id)
        self._fd = self._take()
        self.since_utc = datetime.now(UTC).isoformat(timespec="seconds")
        record = json.dumps({"pid": os.getpid(), "host": _host(), "since_utc": self.since_utc}) + "\n"
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, record.encode(), 0)
        os.fsync(self._fd)
        self._stop = threading.Event()
        self._beat = threading.Thread(target=self._heartbeat, name=f"run-{run_id}-heartbeat", daemon=True)
        self._beat.start()

    def _take(self) -> int:
        deadline = time.monotonic() + _PROBE_GRACE_S
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                data = _read_owner(fd)
                os.close(fd)
                if time.monotonic() < deadline:
                    time.sleep(0.01)
                    continue
                owner = _owner(data, alive=True)
                raise RunOwned(
                    f"run {self.run_id}: owned by a live process, {owner.describe()}; left untouched "
                    f"(wait for it to end, or stop it: kill -TERM {owner.pid} on {owner.host})"
                ) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                return fd
            os.close(fd)  # the previous owner unlinked it while we waited: take the new one

    def _heartbeat(self) -> None:
        while not self._stop.wait(HEARTBEAT_S):
            try:
                os.utime(self._fd)
            except OSError as exc:
                if exc.errno != errno.EBADF:
                    raise

    def release(self) -> None:
        if self._fd < 0:
            return
        self._stop.set()
        self._beat.join()
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        os.close(self._fd)
        self._fd = -1
