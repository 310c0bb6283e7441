"""The handlers of the ``cvn`` subcommands (:mod:`.cli`): ``demo``, ``scenes``, ``run``,
``report``, ``export``, ``sweep``; each takes the parsed arguments and returns an exit code.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from pathlib import Path

from .cli_messages import EXIT, _err, _info
from .cli_scene_run import _process, _process_sweep


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


def _load(names: Sequence[str]):
    from .scenes.schema import load_scene

    return [load_scene(n) for n in names]


def _default_scenes():
    from .scenes.schema import builtin_names, load_scene

    return [s for s in (load_scene(n) for n in builtin_names()) if s.report.default]


def _sweep(args: argparse.Namespace) -> int:
    from .scenes.grid import parse_set, with_overrides

    (scene,) = _load([args.scene])
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


def _index(args: argparse.Namespace, note: str | None = None) -> None:
    from .report.readme import update_readme
    from .report.writer import write_index

    write_index(Path(args.out) / "reports", note=note)
    # the generated blocks of <out>/README.md (the repository's README), when it has them
    update_readme(Path(args.out) / "README.md", Path(args.out) / "reports")


def _run(args: argparse.Namespace) -> int:
    (scene,) = _load([args.scene])
    code = _process(args, scene, report=not args.no_report, force_export=False)
    if code == EXIT["ok"] and not args.no_report:
        _index(args)
    return code


def _report(args: argparse.Namespace) -> int:
    scenes = _load(args.scenes) if args.scenes else _default_scenes()
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

    (scene,) = _load([args.scene])
    if scene.sweep is not None:
        raise SceneError(
            scene.source,
            "sweep",
            "",
            "a sweep has no meshes of its own (its points compute training runs only); "
            "export one variant: a scene file without [sweep] and with its values",
        )
    return _process(args, scene, report=False, force_export=True)
