"""Exit codes and messages of the ``cvn`` command (:mod:`.cli`): :data:`EXIT`, the one-line
error on stderr (with its traceback under ``--debug`` or ``CVN_DEBUG=1``), progress lines.
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback

#: Exit codes.
EXIT = {
    "ok": 0,
    "not_converged": 1,  # cvn demo: a method did not converge
    "usage": 2,  # bad command line or scene file
    "run": 3,  # a scene's computation failed
    "report": 4,  # writing a report failed
    "export": 5,  # writing meshes failed
    "output": 6,  # the --out folder cannot be used (not a folder, not writable, a broken link)
    "busy": 7,  # the scene's result folder is in use by another run
    "internal": 70,  # a bug: the traceback is printed
    "interrupted": 130,
}

_EPILOG = (
    "exit codes: 0 ok; 1 demo: a method did not converge; 2 bad command line or scene file; "
    "3 a scene's computation failed; 4 writing a report failed; 5 writing meshes failed; "
    "6 the --out folder cannot be used; 7 the scene's result folder is in use by another "
    "run; 70 internal error (a bug; traceback printed); 130 interrupted (rerun to resume). "
    "Errors are one line on stderr; --debug (or CVN_DEBUG=1) prints their tracebacks."
)
_DEBUG_ENV = "CVN_DEBUG"


def _debug() -> bool:
    return os.environ.get(_DEBUG_ENV, "") not in ("", "0")


def _err(msg: str) -> None:
    if _debug() and sys.exc_info()[0] is not None:
        traceback.print_exc()
    print("cvn: " + " ".join(str(msg).split("\n")), file=sys.stderr)


def _info(args: argparse.Namespace, msg: str) -> None:
    if not getattr(args, "quiet", False):
        print(msg, file=sys.stderr)


def _os_message(err: OSError) -> str:
    where = f"{err.filename}: " if err.filename else ""
    return f"{where}{err.strerror or err}"
