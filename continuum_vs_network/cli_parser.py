"""The command line of ``cvn`` (:mod:`.cli`): its subcommands, options and help texts.

:func:`build_parser` only declares them: ``args.command`` names the subcommand, and
:func:`.cli.main` runs its handler. Kept apart from :mod:`.cli` because the help texts
alone are most of its length.
"""

from __future__ import annotations

import argparse

_EPILOG = (
    "exit codes: 0 ok; 1 demo: a method did not converge; 2 bad command line or scene file; "
    "3 a scene's computation failed; 4 writing a report failed; 5 writing meshes failed; "
    "6 the --out folder cannot be used; 7 the scene's result folder is in use by another "
    "run; 70 internal error (a bug; traceback printed); 130 interrupted (rerun to resume). "
    "Errors are one line on stderr; --debug (or CVN_DEBUG=1) prints their tracebacks."
)
_SCENE_HELP = "a scene file (.toml) or the name of a built-in scene"


def _common(
    p: argparse.ArgumentParser, *, report: bool = True, workers_help: str | None = None
) -> None:
    """Options every scene command takes; ``workers_help``: the command chooses its own
    worker count when ``--workers`` is not given (default None), as this help says."""
    p.add_argument(
        "--out",
        default=".",
        metavar="DIR",
        help="root of results/, reports/ and meshes/ (default: current folder)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1 if workers_help is None else None,
        metavar="N",
        help=workers_help
        or "processes for learning trials and lattice sizes (default 1; results agree with 1 "
        "to solver round-off)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bars or messages")
    p.add_argument(
        "--fresh",
        action="store_true",
        help="discard earlier results of the scene instead of resuming",
    )
    if report:
        p.add_argument("--no-render", action="store_true", help="skip pyvista renders")


def build_parser() -> argparse.ArgumentParser:
    from .network.equilibrium import METHODS

    parser = argparse.ArgumentParser(
        prog="cvn",
        description="Mass-spring networks that learn, against an elastic continuum.",
        epilog=_EPILOG,
    )
    parser.add_argument(
        "--debug",
        action="store_true",
        help="print the traceback of every error (also: CVN_DEBUG=1)",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo",
        help="relax the paper's network with every method and print a table",
        epilog="exit codes: 0 every method converged; 1 a method did not (the paper's Adagrad "
        "stalls by design: leave it out with --methods to check the others); 2 bad arguments.",
    )
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    demo.add_argument("--strain", type=float, default=None, help="source strain (default ~N(5,1))")
    demo.add_argument(
        "--paper-seconds", type=float, default=5.0, help="time budget of the paper's Adagrad"
    )
    demo.add_argument(
        "--methods",
        nargs="+",
        choices=list(METHODS),
        default=list(METHODS),
        metavar="METHOD",
        help=f"methods to run (default: all of {', '.join(METHODS)})",
    )

    run = sub.add_parser("run", help="run one scene and write its report", epilog=_EPILOG)
    run.add_argument("scene", help=_SCENE_HELP)
    _common(run)
    run.add_argument("--no-report", action="store_true", help="compute (and export) only")

    report = sub.add_parser(
        "report",
        help="run scenes (default: the default set) and write their reports and the index",
        epilog=_EPILOG,
    )
    report.add_argument(
        "scenes",
        nargs="*",
        metavar="SCENE",
        help="scene files or built-in names (none: the default set)",
    )
    _common(
        report,
        workers_help="processes for learning trials and lattice sizes (default: one per core, "
        "up to 8, when dask.distributed is installed, else 1; results agree with 1 to solver "
        "round-off)",
    )

    export = sub.add_parser(
        "export", help="write a scene's meshes (VTU, PVD) for ParaView", epilog=_EPILOG
    )
    export.add_argument("scene", help=_SCENE_HELP)
    _common(export, report=False)

    sweep = sub.add_parser(
        "sweep",
        help="run a grid of scene variants (a [sweep] table and/or --set) on Dask",
        description="Expand a scene into a grid of variants (cartesian product of the swept "
        "keys), print its size and estimated cost, run every point not already stored "
        "(on a local Dask cluster, or on a running scheduler), and write the tidy table "
        "results/<scene>/table.parquet (and .csv) and reports/<scene>/report.md (<scene>_sweep "
        "for a scene without a [sweep] table of its own).",
        epilog=_EPILOG,
    )
    sweep.add_argument("scene", help=_SCENE_HELP)
    sweep.add_argument(
        "--set",
        action="append",
        metavar="KEY=V1,V2",
        help="sweep KEY (table.key, or seed) over the values (a..b: the integers a to b); "
        "replaces the scene's own axis of that key; repeat for more keys",
    )
    sweep.add_argument(
        "--zip",
        action="append",
        metavar="KEY,KEY",
        help="vary these swept keys together (equal numbers of values) instead of crossing them",
    )
    sweep.add_argument(
        "--threshold",
        type=float,
        default=None,
        metavar="X",
        help="steps_to_threshold counts steps until error <= X x initial error (default 0.1)",
    )
    sweep.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on an existing Dask cluster (tcp://host:8786); its workers must import "
        "this package and see --out",
    )
    sweep.add_argument(
        "--dry-run", action="store_true", help="print the grid and the estimated cost only"
    )
    sweep.add_argument("--no-report", action="store_true", help="compute the table only")
    _common(
        sweep,
        report=False,
        workers_help="local Dask worker processes (default: this machine's cores; 1: serial, "
        "no Dask)",
    )

    scenes = sub.add_parser("scenes", help="list the built-in scenes")
    scenes.add_argument("--keys", action="store_true", help="list every key a scene may set")
    return parser
