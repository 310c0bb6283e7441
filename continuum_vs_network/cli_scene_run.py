"""Running scenes for the ``cvn`` command (:mod:`.cli`): one scene (results, meshes, report,
under the lock of its result folder) or one sweep (table and report), each returning an
exit code from :data:`~.cli_messages.EXIT`.
"""

from __future__ import annotations

import argparse
import time
import traceback
from pathlib import Path

from .cli_messages import EXIT, _debug, _err, _info, _os_message


def _process(args: argparse.Namespace, scene, *, report: bool, force_export: bool) -> int:
    """Run one scene, export its meshes and write its report; returns an exit code."""
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
            fresh=getattr(args, "fresh", False),
            command=" ".join(["cvn", *args.argv]),
            log=lambda m: _info(args, m),
        )
    except SceneRunError as err:
        if _debug():
            traceback.print_exception(err.cause)
        _err(f"{err} (completed units are kept; rerun to resume)")
        return EXIT["run"]
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
            fresh=getattr(args, "fresh", False),
            dry_run=getattr(args, "dry_run", False),
            log=lambda m: _info(args, m),
            serial_fallback=getattr(args, "serial_fallback", False),
        )
    except SweepRunError as err:
        if _debug():
            traceback.print_exception(err.cause)
        _err(f"{err} (completed points are kept; rerun to resume)")
        return EXIT["run"]
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
