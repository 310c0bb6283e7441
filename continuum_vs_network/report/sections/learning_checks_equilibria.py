"""Whether the stored free states of a learning run are equilibria (checks of the
learning section, :mod:`.learning_checks`): residual ranges and the rule.
"""

from __future__ import annotations

import numpy as np

from ..document import Document, fmt, quiet

__all__ = ["EQUILIBRIUM_RESIDUAL", "not_equilibria", "residual_range"]

#: a stored free state is an equilibrium when its largest net force on a free coordinate
#: (``History.residual``) is at most this fraction of the run's force scale: the largest
#: norm of the learning springs' tensions ``|dE^F/dL| = |k (r - L)|`` over the trial's
#: steps (rest-length learning; a converged Newton solve stops at 1e-10 of each node's
#: sum k L, four decades below)
EQUILIBRIUM_RESIDUAL = 1e-6


def _completed(hist, name: str) -> list[np.ndarray]:
    arr = np.asarray(hist.data[name], dtype=float)
    return [arr[i, : min(int(c), hist.steps) + 1] for i, c in enumerate(hist.completed)]


def residual_range(hist, *, relative: bool = False) -> tuple[float, float]:
    """Smallest and largest stored free-state residual over every completed step of every
    trial of a :class:`~continuum_vs_network.learning.history.History`; ``relative``: as a
    fraction of each trial's force scale (:data:`EQUILIBRIUM_RESIDUAL`), only for
    rest-length learning (``settings["dof"] == "rest_length"``). (NaN, NaN when not
    stored or not defined.)"""
    nan = (float("nan"), float("nan"))
    if "residual" not in hist.data:
        return nan
    rows = _completed(hist, "residual")
    if relative:
        if hist.settings.get("dof") != "rest_length" or "energy_gradient_free" not in hist.data:
            return nan
        scales = [quiet(np.nanmax, g) if g.size else np.nan
                  for g in _completed(hist, "energy_gradient_free")]  # fmt: skip
        rows = [r / s for r, s in zip(rows, scales) if np.isfinite(s) and s > 0]
    vals = np.concatenate(rows) if rows else np.empty(0)
    vals = vals[np.isfinite(vals)]
    if not vals.size:
        return nan
    return float(vals.min()), float(vals.max())


def not_equilibria(hist) -> bool:
    """True when some stored free state of ``hist`` is not an equilibrium: its residual is
    above :data:`EQUILIBRIUM_RESIDUAL` of the force scale (False when that is not
    defined)."""
    hi = residual_range(hist, relative=True)[1]
    return bool(np.isfinite(hi) and hi > EQUILIBRIUM_RESIDUAL)


def _equilibria(doc: Document, h, solvers, rules) -> dict[str, str]:
    """A sentence on every solver whose stored states are not equilibria; returns, per such
    solver, the note its claims' findings carry."""
    from ..document import SOLVER_NAMES

    notes = {}
    for solver in solvers:
        if not any(not_equilibria(h(solver, r)) for r in rules):
            continue
        ranges = [residual_range(h(solver, r)) for r in rules]
        lo = min((a for a, _ in ranges), default=float("nan"))
        hi = max((b for _, b in ranges), default=float("nan"))
        rel = [residual_range(h(solver, r), relative=True) for r in rules]
        rlo = min((a for a, _ in rel if np.isfinite(a)), default=float("nan"))
        rhi = max((b for _, b in rel if np.isfinite(b)), default=float("nan"))
        rest = [s for s in solvers if s != solver]
        others = []
        for s in rest:
            rr = [residual_range(h(s, r)) for r in rules]
            others.append(f"{SOLVER_NAMES.get(s, s)}: {fmt(min(a for a, _ in rr))} to "
                          f"{fmt(max(b for _, b in rr))}")  # fmt: skip
        first = [
            f"{SOLVER_NAMES.get(s, s)} {fmt(float(np.ravel(h(s, rules[0]).target_strain)[0]))}"
            for s in solvers
            if "target_strain" in h(s, rules[0]).data
        ]
        doc.add(
            "",
            f"**The states of {SOLVER_NAMES.get(solver, solver)} are not equilibria.** The "
            "largest net force on a free coordinate of its stored free states ranges from "
            f"{fmt(lo)} to {fmt(hi)} over every step of every trial, {fmt(rlo)} to "
            f"{fmt(rhi)} of the run's force scale (the largest norm of the learning springs' "
            f"tensions |dE/dL|; an equilibrium: at most {EQUILIBRIUM_RESIDUAL:g} of it)"
            + (f"; {'; '.join(others)}" if others else "")
            + ". "
            + (
                "The first target's free-state strain of trial 0 at step 0 (the same "
                f"network): {', '.join(first)}. "
                if len(first) > 1
                else ""
            )
            + "Its verdicts below are about the paper's procedure on non-equilibrium "
            "states, not about the physics of equilibrium networks.",
        )
        notes[solver] = (
            f"states not equilibria: residual {fmt(lo)} to {fmt(hi)}, {fmt(rlo)} to "
            f"{fmt(rhi)} of the force scale > {EQUILIBRIUM_RESIDUAL:g}; a verdict on the "
            "procedure, not on equilibrium physics"
        )
    return notes
