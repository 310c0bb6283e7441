"""Atomic file output: write to a temporary file in the target folder, then rename.

A crash, an exception or a full disk while writing never leaves a half-written file at the
destination: either the complete new file is there, or the old one (or nothing) is.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "write_bytes_atomic", "write_text_atomic"]

_FILE_MODE = 0o644


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    Parent folders are created. The temporary file lives in the same folder as ``path`` (so
    the final :func:`os.replace` is atomic on POSIX and Windows) and has a name starting with
    ``.`` and ending in ``.tmp``. If the ``with`` body raises, the temporary file is removed
    and ``path`` is left untouched.

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
    fd, tmp_name = tempfile.mkstemp(dir=dest.parent, prefix=f".{dest.name}.", suffix=".tmp")
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
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; return the path."""
    return write_bytes_atomic(path, text.encode(encoding))
