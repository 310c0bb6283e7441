"""An exclusive lock on a result folder, so that two runs never write into the same one.

The lock is the file ``<folder>/.lock``, locked with ``fcntl.flock`` (the kernel releases
it when the holding process dies, however it dies, so a killed run never leaves a stale
lock) and holding the holder's PID and start time for the message the next run shows.
Where ``fcntl`` does not exist the file is created with ``O_EXCL`` instead and a lock
whose PID is no longer alive is stale and taken over.

A second run on a locked folder does not wait: it raises :class:`FolderBusyError` at once
(the CLI turns it into one line and exit code 7). Locks are re-entrant within a process
(the CLI holds the lock around ``run_scene``, which takes it too).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import time
from collections.abc import Iterator
from pathlib import Path

__all__ = ["LOCK_NAME", "FolderBusyError", "folder_lock", "pid_alive"]

LOCK_NAME = ".lock"

#: folders this process holds: resolved path -> (file descriptor, depth)
_HELD: dict[str, tuple[int, int]] = {}


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


def _stamp() -> bytes:
    return json.dumps(
        {"pid": os.getpid(), "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    ).encode()


def _acquire(folder: Path) -> int:
    path = folder / LOCK_NAME
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return _acquire_exclusive(path)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise FolderBusyError(folder, _read_holder(path)) from None
        raise
    os.ftruncate(fd, 0)
    os.write(fd, _stamp())
    os.fsync(fd)
    return fd


def _acquire_exclusive(path: Path) -> int:  # pragma: no cover - not POSIX
    for _ in range(2):
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
        except FileExistsError:
            holder = _read_holder(path)
            if pid_alive(int(holder.get("pid", -1))):
                raise FolderBusyError(path.parent, holder) from None
            path.unlink(missing_ok=True)  # stale: its process is gone
            continue
        os.write(fd, _stamp())
        os.fsync(fd)
        return fd
    raise FolderBusyError(path.parent, _read_holder(path))


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
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    key = str(folder.resolve())
    if key in _HELD:
        fd, depth = _HELD[key]
        _HELD[key] = (fd, depth + 1)
    else:
        _HELD[key] = (_acquire(folder), 1)
    try:
        yield folder
    finally:
        fd, depth = _HELD[key]
        if depth > 1:
            _HELD[key] = (fd, depth - 1)
        else:
            del _HELD[key]
            if not _has_fcntl():  # pragma: no cover - not POSIX
                with contextlib.suppress(OSError):
                    (folder / LOCK_NAME).unlink()
            os.close(fd)  # releases the flock


def _has_fcntl() -> bool:
    try:
        import fcntl  # noqa: F401
    except ImportError:  # pragma: no cover - not POSIX
        return False
    return True
