"""The ``cvn`` command."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

__all__ = ["main"]


def _demo(args: argparse.Namespace) -> int:
    from .demo import format_table, run_demo

    rows, info = run_demo(args.seed, strain=args.strain, paper_seconds=args.paper_seconds)
    print(format_table(rows, info))
    return 0 if all(r.converged for r in rows if r.method != "paper") else 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cvn", description="Mass-spring networks that learn, against an elastic continuum."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo", help="relax the paper's network with every method and print a table"
    )
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    demo.add_argument("--strain", type=float, default=None, help="source strain (default ~N(5,1))")
    demo.add_argument(
        "--paper-seconds", type=float, default=5.0, help="time budget of the paper's Adagrad"
    )
    demo.set_defaults(func=_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``cvn``; returns the exit code."""
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
