"""The ``cvn`` command.

::

    cvn report [SCENE ...]        run scenes (default: the default set) and write their reports
    cvn run SCENE [--out DIR]     run one scene (a .toml file or a built-in name), write its report
    cvn export SCENE              write the scene's meshes (VTU, PVD series) for ParaView
    cvn scenes [--keys]           list the built-in scenes (--keys: every scene key)
    cvn sweep SCENE [--set K=V,V] run a grid of scene variants on Dask, write its table and report
    cvn demo                      relax the paper's network with every method

Outputs go under ``--out`` (default: the current folder): ``results/<scene>/`` (computed
units and checkpoints: an interrupted run resumes from them), ``reports/<scene>/``,
``meshes/<scene>/``. A scene's result folder is locked while a run uses it: a second run on
the same scene and ``--out`` stops at once with exit code 7 (it does not wait).

Errors: a mistake in the command line, a scene file or the output folder is one line on
stderr (``cvn: ...``) and an exit code from :data:`EXIT`, never a traceback. Anything else
is a bug: its traceback is printed, with exit code 70. ``cvn --debug ...`` (or the
environment variable ``CVN_DEBUG=1``) prints the traceback of every error.

This module is the entry point (:func:`main`: the boundary checks and the error handling);
:mod:`.cli_parser` builds the command line, :mod:`.cli_commands` handles each subcommand,
:mod:`.cli_scene_run` runs a scene or a sweep, :mod:`.cli_messages` holds the exit codes
and messages.
"""

from __future__ import annotations

import os
import sys
import tempfile
import traceback
from collections.abc import Sequence
from pathlib import Path

from .cli_commands import _run as _run
from .cli_messages import _DEBUG_ENV, EXIT, _err, _os_message
from .cli_parser import build_parser

__all__ = ["EXIT", "build_parser", "main"]

_MAX_WORKERS_PER_CPU = 4  # more processes than this only compete for the same cores


class _OutputError(Exception):
    """The --out folder cannot be used."""


def _output_root(out: str) -> Path:
    """The --out folder, created and checked writable; :class:`_OutputError` says why not."""
    path = Path(out)
    try:
        if path.is_symlink():
            try:
                os.stat(path)
            except OSError as err:
                kind = "a symbolic link loop" if err.errno == 40 else "a broken symbolic link"
                raise _OutputError(f"--out {out}: {kind} ({err.strerror})") from None
        if path.exists() and not path.is_dir():
            raise _OutputError(f"--out {out}: not a folder")
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".cvn-write-test.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        raise _OutputError(f"--out {out}: cannot write there ({_os_message(err)})") from None
    return path


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``cvn``; returns the exit code (see :data:`EXIT`)."""
    from ._validate import ArgumentError
    from .scenes.schema import SceneError

    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    args.argv = [a for a in argv if a != "--debug"]
    if args.debug:
        os.environ[_DEBUG_ENV] = "1"
    top = _MAX_WORKERS_PER_CPU * (os.cpu_count() or 1)
    workers = getattr(args, "workers", 1)
    if workers is not None and not 1 <= workers <= top:
        _err(f"--workers must be in 1..{top} ({_MAX_WORKERS_PER_CPU} per CPU), got {args.workers}")
        return EXIT["usage"]
    try:
        if hasattr(args, "out"):
            _output_root(args.out)
        return int(args.func(args))
    except (SceneError, ArgumentError) as err:
        _err(str(err))
        return EXIT["usage"]
    except _OutputError as err:
        _err(str(err))
        return EXIT["output"]
    except KeyboardInterrupt:
        _err("interrupted; rerun the same command to resume")
        return EXIT["interrupted"]
    except OSError as err:  # the file system refused (disk full, permissions, ...)
        _err(_os_message(err))
        return EXIT["output"]
    except MemoryError:
        _err("out of memory; use a smaller scene (the estimate at load was too low)")
        return EXIT["run"]
    except Exception:  # a bug: show it
        traceback.print_exc()
        print(
            "cvn: internal error (a bug; please report it with the traceback above)",
            file=sys.stderr,
        )
        return EXIT["internal"]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
