"""Atomic file output: write to a temporary file in the target folder, then rename.

A crash, an exception or a full disk while writing never leaves a half-written file at the
destination: either the complete new file is there, or the old one (or nothing) is.
"""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "remove_stale_temporaries", "write_bytes_atomic", "write_text_atomic"]

_FILE_MODE = 0o644
#: our temporary names: ``.<destination>.<pid>.<8 random characters of mkstemp>.tmp``
_TEMPORARY = re.compile(r"\.(?P<dest>.+)\.(?P<pid>\d+)\.[a-z0-9_]{8}\.tmp")
#: the names of earlier versions, without the PID: ``.<destination>.<8 random>.tmp``
_LEGACY = re.compile(r"\.(?P<dest>.+)\.[a-z0-9_]{8}\.tmp")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    Parent folders are created. The temporary file lives in the same folder as ``path`` (so
    the final :func:`os.replace` is atomic on POSIX and Windows) and has a unique name
    ``.<name>.<pid>.<random>.tmp`` (the writer's PID lets :func:`remove_stale_temporaries`
    tell a dead writer's leftovers from a live one's work). The temporary file is flushed
    to disk (``fsync``) before the rename, and the folder after it. If the ``with`` body
    raises, the temporary file is removed and ``path`` is left untouched.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.

    Yields
    ------
    pathlib.Path
        Where the body must write the complete file.
    """
    dest = Path(path)
    if dest.name in ("", ".", ".."):
        raise ValueError(f"path must name a file, got {str(path)!r}")
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(
        dir=dest.parent, prefix=f".{dest.name}.{os.getpid()}.", suffix=".tmp"
    )
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"nothing was written to the temporary file for {dest}")
        with open(tmp, "rb") as handle:
            os.fsync(handle.fileno())
        os.chmod(tmp, _FILE_MODE)  # mkstemp makes 0o600; give the usual rw-r--r--
        os.replace(tmp, dest)
        _fsync_folder(dest.parent)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _fsync_folder(folder: Path) -> None:
    """Make a rename in ``folder`` durable (POSIX; a no-op where folders cannot be opened)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # pragma: no cover - Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover - file systems without folder fsync
        pass
    finally:
        os.close(fd)


def remove_stale_temporaries(
    folder: str | os.PathLike[str], *, recursive: bool = True, locked: bool = False
) -> int:
    """Remove the temporaries :func:`atomic_path` left behind in ``folder`` when killed.

    Only files named as :func:`atomic_path` names them whose writer process is no longer
    alive (or is this process's own, which has none open when this runs) are removed;
    other files, including other programs' dotfiles, are never touched. With ``locked``
    (the caller holds the folder's lock, so no other run writes there) the PID-less names
    of earlier versions are removed too. Returns the count.
    """
    from .lock import pid_alive

    folder = Path(folder)
    if not folder.is_dir():
        return 0
    removed = 0
    paths = folder.rglob(".*.tmp") if recursive else folder.glob(".*.tmp")
    for path in list(paths):
        if path.is_symlink() or not path.is_file():
            continue
        m = _TEMPORARY.fullmatch(path.name)
        if m is not None:
            pid = int(m["pid"])
            if pid != os.getpid() and pid_alive(pid):
                continue
        elif not (locked and _LEGACY.fullmatch(path.name)):
            continue
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed += 1
    return removed


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; return the path."""
    return write_bytes_atomic(path, text.encode(encoding))
