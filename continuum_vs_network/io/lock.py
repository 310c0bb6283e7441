"""An exclusive lock on a result folder, so that two runs never write into the same one.

The lock is the file ``<folder>/.lock``, held with :class:`filelock.FileLock` (``flock``
on POSIX, ``LockFileEx`` on Windows: the kernel releases it when the holding process dies,
however it dies, so a killed run never leaves a stale lock) and holding the holder's PID
and start time for the message the next run shows. filelock >= 4 is required: 3.x opened
the file with ``O_TRUNC`` before trying the lock, so a losing contender erased that stamp.

A second run on a locked folder does not wait: it raises :class:`FolderBusyError` at once
(the CLI turns it into one line and exit code 7). Locks are re-entrant within a process
(the CLI holds the lock around ``run_scene``, which takes it too).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from filelock import FileLock

__all__ = ["LOCK_NAME", "FolderBusyError", "folder_lock", "pid_alive"]

LOCK_NAME = ".lock"

#: folders this process holds: resolved path -> its (re-entrant) lock
_HELD: dict[str, FileLock] = {}


class FolderBusyError(RuntimeError):
    """The folder is locked by another live run.

    Attributes
    ----------
    folder : pathlib.Path
    holder : dict
        What the holder wrote into the lock file (``pid``, ``started``), possibly empty.
    """

    def __init__(self, folder: Path, holder: dict) -> None:
        self.folder, self.holder = folder, holder
        who = f"process {holder['pid']}" if "pid" in holder else "another process"
        since = f" since {holder['started']}" if "started" in holder else ""
        super().__init__(
            f"{folder} is in use by another cvn run ({who}{since}); wait for it to finish "
            f"or choose another --out"
        )


def pid_alive(pid: int) -> bool:
    """True when a process with this PID exists (it may belong to another user)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OSError:
        return False
    return True


def _read_holder(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8") or "{}")
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _stamp(fd: int) -> None:
    """Write this process's PID and start time into the lock file it has just locked."""
    os.ftruncate(fd, 0)
    os.write(
        fd,
        json.dumps({"pid": os.getpid(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}).encode(),
    )
    os.fsync(fd)


@contextlib.contextmanager
def folder_lock(folder: str | os.PathLike[str]) -> Iterator[Path]:
    """Hold the exclusive lock of ``folder`` (created) for the ``with`` body.

    Raises
    ------
    FolderBusyError
        Another live process holds it.
    OSError
        The folder cannot be created or written (not a folder, read-only, ...).
    """
    from filelock import FileLock, Timeout

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    key = str(folder.resolve())
    # one lock object per folder (its counter makes it re-entrant across call sites); no
    # waiting, no soft (PID-file) fallback, and the file stays for the next holder's stamp
    lock = _HELD.get(key) or FileLock(
        folder / LOCK_NAME,
        timeout=0,
        thread_local=False,
        fallback_to_soft=False,
        preserve_lock_file=True,
        on_acquired=_stamp,
    )
    try:
        lock.acquire()
    except Timeout:
        raise FolderBusyError(folder, _read_holder(folder / LOCK_NAME)) from None
    _HELD[key] = lock
    try:
        yield folder
    finally:
        lock.release()
        if not lock.is_locked:
            del _HELD[key]
