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

:mod:`.cli_parser` declares the command line (options and help texts); this module runs it:
exit codes and messages, :func:`main` (the boundary checks and the error handling), the
subcommand handlers, running a scene or a sweep. Both import only the standard library;
each command imports what it uses when it runs.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
import traceback
from collections.abc import Sequence
from pathlib import Path

from .cli_parser import build_parser

__all__ = ["EXIT", "build_parser", "main"]

# -- exit codes and messages ---------------------------------------------------------------
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

_DEBUG_ENV = "CVN_DEBUG"
_MAX_WORKERS_PER_CPU = 4  # more processes than this only compete for the same cores


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


# -- the entry point -----------------------------------------------------------------------
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
        return int(_COMMANDS[args.command](args))
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


# -- the subcommands: each takes the parsed arguments and returns an exit code -------------
def _demo(args: argparse.Namespace) -> int:
    from .demo import format_table, run_demo

    rows, info = run_demo(
        args.seed, strain=args.strain, paper_seconds=args.paper_seconds, methods=args.methods
    )
    print(format_table(rows, info))
    failed = [r.method for r in rows if not r.converged]
    if failed:
        _err(f"demo: {', '.join(failed)} did not converge")
        return EXIT["not_converged"]
    return EXIT["ok"]


def _scenes(args: argparse.Namespace) -> int:
    from .scenes.schema import builtin_names, key_reference, load_scene

    if args.keys:
        print(key_reference())
        return EXIT["ok"]
    scenes = [load_scene(name) for name in builtin_names()]
    width = max(len(s.name) for s in scenes)
    kinds = [s.kind + (" sweep" if s.sweep else "") for s in scenes]
    kind_width = max(len(k) for k in kinds)
    print(f"{'scene':{width}}  {'kind':{kind_width}}  default  description")
    for s, kind in zip(scenes, kinds):
        print(
            f"{s.name:{width}}  {kind:{kind_width}}  "
            f"{'yes' if s.report.default else 'no':7}  "
            f"{s.description}"
        )
    print(
        "\n`cvn report` runs the default set; `cvn run NAME` or `cvn report NAME ...` any "
        "scene; `cvn sweep NAME` a sweep (also with --set KEY=V1,V2 on any learning scene); "
        "`cvn scenes --keys` lists every key a scene file may set."
    )
    return EXIT["ok"]


def _load(name: str):
    from .scenes.schema import load_scene

    return load_scene(name)


def _index(args: argparse.Namespace, note: str | None = None) -> None:
    from .report.readme import update_readme
    from .report.writer import write_index

    write_index(Path(args.out) / "reports", note=note)
    # the generated blocks of <out>/README.md (the repository's README), when it has them
    update_readme(Path(args.out) / "README.md", Path(args.out) / "reports")


def _run(args: argparse.Namespace) -> int:
    code = _process(args, _load(args.scene), report=not args.no_report, force_export=False)
    if code == EXIT["ok"] and not args.no_report:
        _index(args)
    return code


def _report(args: argparse.Namespace) -> int:
    from .scenes.schema import builtin_names

    if args.scenes:
        scenes = [_load(n) for n in args.scenes]
    else:
        scenes = [s for s in map(_load, builtin_names()) if s.report.default]
    if args.workers is None:  # one per core; serial if a local cluster cannot start
        from .scenes.executor import default_workers

        args.workers, args.serial_fallback = default_workers(), True
    t0 = time.perf_counter()
    first_failure = EXIT["ok"]
    for scene in scenes:
        code = _process(args, scene, report=True, force_export=False)
        if code != EXIT["ok"] and first_failure == EXIT["ok"]:
            first_failure = code
    total = time.perf_counter() - t0
    note = None
    if not args.scenes:
        note = (
            f"Last `cvn report` (default set: {', '.join(s.name for s in scenes)}) took "
            f"{total:.0f} s with {args.workers} worker process(es)."
        )
    _index(args, note)
    _info(args, f"{len(scenes)} scene(s) in {total:.1f} s; index {Path(args.out) / 'reports'}")
    return first_failure


def _export(args: argparse.Namespace) -> int:
    from .scenes.schema import SceneError

    scene = _load(args.scene)
    if scene.sweep is not None:
        raise SceneError(
            scene.source,
            "sweep",
            "",
            "a sweep has no meshes of its own (its points compute training runs only); "
            "export one variant: a scene file without [sweep] and with its values",
        )
    return _process(args, scene, report=False, force_export=True)


def _sweep(args: argparse.Namespace) -> int:
    from .scenes.grid import parse_set, with_overrides

    scene = _load(args.scene)
    if scene.sweep is None:  # a sweep of a plain scene: its own folders, not the scene's
        scene = dataclasses.replace(scene, name=f"{scene.name}_sweep")
    zips = [[k.strip() for k in z.split(",")] for z in args.zip or []]
    scene = with_overrides(
        scene, parse_set(args.set or []), zip_groups=zips, threshold=args.threshold
    )
    code = _process_sweep(args, scene, report=not args.no_report)
    if code == EXIT["ok"] and not args.no_report and not args.dry_run:
        _index(args)
    return code


#: The handler of each subcommand (:func:`.cli_parser.build_parser` declares them).
_COMMANDS = {
    "demo": _demo,
    "scenes": _scenes,
    "run": _run,
    "report": _report,
    "export": _export,
    "sweep": _sweep,
}


# -- running a scene or a sweep ------------------------------------------------------------
def _process(args: argparse.Namespace, scene, *, report: bool, force_export: bool) -> int:
    """Run one scene (under the lock of its result folder), export its meshes and write its
    report; returns an exit code."""
    if scene.sweep is not None and not force_export:
        return _process_sweep(args, scene, report=report)
    out = Path(args.out)
    if force_export and scene.export is None:
        scene = scene.with_export()
    from .io.lock import FolderBusyError, folder_lock

    try:
        with folder_lock(out / "results" / scene.name):
            return _process_locked(args, scene, out, report=report)
    except FolderBusyError as err:
        _err(str(err))
        return EXIT["busy"]
    except OSError as err:
        _err(f"scene {scene.name!r}: {_os_message(err)}")
        return EXIT["output"]


def _run_failed(err, units: str) -> int:
    """A scene's or sweep's computation failed (a SceneRunError or SweepRunError)."""
    if _debug():
        traceback.print_exception(err.cause)
    _err(f"{err} (completed {units} are kept; rerun to resume)")
    return EXIT["run"]


def _process_locked(args: argparse.Namespace, scene, out: Path, *, report: bool) -> int:
    """:func:`_process` while the scene's result folder is locked."""
    from .io.atomic import remove_stale_temporaries
    from .scenes.compute import SceneRunError
    from .scenes.meshes import export_meshes
    from .scenes.runner import run_scene

    for folder in (out / "reports" / scene.name, out / "meshes" / scene.name):
        remove_stale_temporaries(folder, locked=True)
    t0 = time.perf_counter()
    try:
        result = run_scene(
            scene,
            out / "results" / scene.name,
            workers=args.workers,
            serial_fallback=getattr(args, "serial_fallback", False),
            progress=not args.quiet,
            fresh=args.fresh,
            command=" ".join(["cvn", *args.argv]),
            log=lambda m: _info(args, m),
        )
    except SceneRunError as err:
        return _run_failed(err, "units")
    _info(args, f"{scene.name}: computed in {time.perf_counter() - t0:.1f} s")
    meshes = []
    if scene.export is not None:
        try:
            meshes = export_meshes(result, out / "meshes" / scene.name)
        except Exception as err:  # the exit code says which stage failed
            _err(f"scene {scene.name!r}: writing meshes failed: {type(err).__name__}: {err}")
            return EXIT["export"]
        _info(args, f"{scene.name}: {len(meshes)} mesh file(s) in {out / 'meshes' / scene.name}")
    if report:
        from .report.writer import write_report

        try:
            path = write_report(
                result,
                out / "reports" / scene.name,
                meshes=meshes,
                render=False if args.no_render else None,
            )
        except Exception as err:  # the exit code says which stage failed
            _err(f"scene {scene.name!r}: writing the report failed: {type(err).__name__}: {err}")
            return EXIT["report"]
        _info(args, f"{scene.name}: report {path}")
    return EXIT["ok"]


def _process_sweep(args: argparse.Namespace, scene, *, report: bool) -> int:
    """Run a sweep (a scene with a [sweep] table), write its table and report."""
    from .io.lock import FolderBusyError
    from .scenes.executor import ExecutorUnavailable
    from .scenes.sweep import SweepRunError, run_sweep

    out = Path(args.out)
    t0 = time.perf_counter()
    try:
        result = run_sweep(
            scene,
            out / "results" / scene.name,
            workers=args.workers,
            scheduler=getattr(args, "scheduler", None),
            progress=not args.quiet,
            fresh=args.fresh,
            dry_run=getattr(args, "dry_run", False),
            log=lambda m: _info(args, m),
            serial_fallback=getattr(args, "serial_fallback", False),
        )
    except SweepRunError as err:
        return _run_failed(err, "points")
    except FolderBusyError as err:
        _err(str(err))
        return EXIT["busy"]
    except (ImportError, ExecutorUnavailable) as err:  # no Dask/pandas; no scheduler there
        _err(str(err))
        return EXIT["usage"]
    if result is None:  # --dry-run
        return EXIT["ok"]
    _info(args, f"{scene.name}: {len(result.points)} points in {time.perf_counter() - t0:.1f} s")
    _info(args, f"{scene.name}: table {out / 'results' / scene.name / 'table.parquet'} (and .csv)")
    if report:
        from .report.writer import write_sweep_report

        try:
            path = write_sweep_report(
                result, out / "reports" / scene.name, command=_sweep_command(args, scene)
            )
        except Exception as err:  # the exit code says which stage failed
            _err(f"sweep {scene.name!r}: writing the report failed: {type(err).__name__}: {err}")
            return EXIT["report"]
        _info(args, f"{scene.name}: report {path}")
    return EXIT["ok"]


def _sweep_command(args: argparse.Namespace, scene) -> str:
    """The command that regenerates a sweep (its scene, and any --set / --zip settings)."""
    from .scenes.schema import builtin_names

    name = scene.name.removesuffix("_sweep")
    target = name if name in builtin_names() else scene.source
    extra = [f"--set {s}" for s in getattr(args, "set", None) or []]
    extra += [f"--zip {z}" for z in getattr(args, "zip", None) or []]
    return " ".join(["cvn sweep", target, *extra])


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
