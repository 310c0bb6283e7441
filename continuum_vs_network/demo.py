"""The demo: the paper's network with one source spring clamped, relaxed by every method."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import _validate as check
from .network.builders import paper_network, strain_tunable
from .network.equilibrium import METHODS, EquilibriumError, relax

__all__ = ["DemoRow", "format_table", "run_demo"]


@dataclass(frozen=True)
class DemoRow:
    """One method's result on the demo problem."""

    method: str
    converged: bool
    residual: float
    relative_residual: float
    clamp_error: float
    energy: float
    iterations: int
    seconds: float
    note: str = ""


def run_demo(
    seed: int = 0,
    *,
    strain: float | None = None,
    paper_seconds: float = 5.0,
    methods: Sequence[str] | None = None,
) -> tuple[list[DemoRow], dict]:
    """Relax the paper's network (N=10, S=18) with one source clamped, with every method.

    The source is a strain-tunable spring and its strain is drawn from N(5, 1) as in the
    paper (Sec. 7.1) unless ``strain`` is given. ``method="paper"`` runs for
    ``paper_seconds`` and is reported with the residual it reached.

    ``methods`` (default: every method of ``relax``) chooses the rows. A method that cannot
    run here (``"paper"`` without torch) gives a row with ``converged=False`` and the reason.

    Returns the rows and a dict describing the problem (seed, source, strain, force scale).
    """
    seed = check.seed("seed", seed)
    if strain is not None:
        strain = check.real("strain", strain, low=-1, low_open=True)
    paper_seconds = check.real("paper_seconds", paper_seconds, low=0, low_open=True)
    if methods is None:
        methods = list(METHODS)
    if isinstance(methods, str) or not methods:
        raise check.ArgumentError("methods", methods, f"a non-empty list from {list(METHODS)}")
    methods = [check.choice("methods entry", m, METHODS) for m in methods]
    rng = np.random.default_rng(seed)
    net = paper_network(rng)
    candidates = np.flatnonzero(strain_tunable(net))
    source = int(rng.choice(candidates))
    strain = float(rng.normal(5.0, 1.0)) if strain is None else float(strain)
    clamped = {source: float(net.clamp_length(source, strain))}
    rows = []
    for method in methods:
        budget = paper_seconds if method == "paper" else 60.0
        try:
            eq = relax(net, clamped=clamped, method=method, max_seconds=budget)
            note = ""
        except EquilibriumError as err:
            if err.state is None:
                rows.append(_missing(method, err.reason))
                continue
            eq = err.state
            note = err.reason.split(" (wanted")[0].removeprefix(f"{method}: ")
        except ImportError as err:  # the paper's method needs torch
            rows.append(_missing(method, f"cannot run here: {err}"))
            continue
        rows.append(
            DemoRow(
                method=method,
                converged=eq.converged,
                residual=eq.residual,
                relative_residual=eq.relative_residual,
                clamp_error=eq.clamp_error,
                energy=eq.energy,
                iterations=eq.iterations,
                seconds=eq.seconds,
                note=note,
            )
        )
    info = {"seed": seed, "source": source, "strain": strain, "force_scale": net.force_scale}
    return rows, info


def _missing(method: str, note: str) -> DemoRow:
    nan = float("nan")
    return DemoRow(method, False, nan, nan, nan, nan, 0, 0.0, note)


def format_table(rows: list[DemoRow], info: dict) -> str:
    """A plain-text table of the demo rows."""
    head = (
        f"Paper network (N=10, S=18), seed {info['seed']}: spring {info['source']} clamped at "
        f"strain {info['strain']:.3f}; force scale F = mean(k) mean(L) = {info['force_scale']:.4g}"
    )
    cols = f"{'method':8} {'converged':>9} {'residual':>10} {'relative':>10} "
    cols += f"{'clamp err':>10} {'energy':>14} {'iters':>7} {'seconds':>9}"
    lines = [head, "", cols, "-" * len(cols)]
    for r in rows:
        lines.append(
            f"{r.method:8} {r.converged!s:>9} {r.residual:10.2e} {r.relative_residual:10.2e} "
            f"{r.clamp_error:10.2e} {r.energy:14.8g} {r.iterations:7d} {r.seconds:9.4f}"
            + (f"  ({r.note})" if r.note else "")
        )
    return "\n".join(lines)
