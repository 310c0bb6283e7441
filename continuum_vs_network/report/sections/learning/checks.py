"""Checks on learning runs (:mod:`.`): the paper's claims judged by rule, whether the stored
free states are equilibria (residual ranges and the rule), and how the checks word things:
the strain conventions, the task error's label, and captions computed from a curve.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...document import Document, fmt, quiet
from ...findings import Finding
from .coupling import coupling_verdicts

__all__ = [
    "CONVENTION_TEXT",
    "EQUILIBRIUM_RESIDUAL",
    "claims",
    "curve_caption",
    "direction",
    "error_label",
    "not_equilibria",
    "residual_range",
]


def claims(doc: Document, result, h, solvers) -> dict[str, str]:
    """The paper's claims table with computed verdicts; one finding per statement (only in
    the paper's own setting, ``[learning] paper_setting``; another paper scene says where
    they are judged). Returns, per solver whose stored states are not equilibria, the note
    its findings carry."""
    from ....scenes.units_learning import experiments
    from ...verdicts.claims import MIN_STEPS, check_claims

    L = result.scene.learning
    doc.heading("The paper's claims and what this package measures")
    if not L.paper_setting:
        doc.add(
            "The paper's claims are judged in scene `paper`, which runs each rule in the "
            "setting of the author's notebooks. This scene runs "
            f"{CONVENTION_TEXT[L.strain_reference]} for every rule, with the package's "
            "derived update signs: its results are in the coupling table and the figures."
        )
        return _equilibria(doc, h, solvers, L.rules)
    doc.add(
        "Each claim of the paper is split into its statements and measured on the run of its "
        "rule in the paper's own setting (table above). C is Eq. 26 as printed (strains "
        "against the learning L, `error_current`). A claim that the task is learned counts "
        "a trial only when its own final value meets the claim and its own coupling verdict "
        "is not decoupled (coupling section). A size reached (orders of magnitude, C = 0, "
        f"~50 %, 33 %) is judged on the trials that completed at least {MIN_STEPS} steps or "
        "whose learning ran away (judged with their last value: a failure); a direction "
        "(rises, descends) on every trial. Each verdict's rule is listed once below the "
        "table; the cell gives the reason in short."
    )
    notes = _equilibria(doc, h, solvers, L.rules)
    for solver in solvers:
        hs = {r: h(solver, r) for r in L.rules}
        coupling_of = {r: coupling_verdicts(result, f"{solver}/{r}/noise0") for r in L.rules}
        checks = check_claims(hs, experiments(result.scene, solver), coupling=coupling_of)
        if len(solvers) > 1:
            doc.add("", f"**{solver}**", "")
        rows, rules = [], {}
        for c in checks:
            key = rules.setdefault((c.claim, c.rule), f"R{len(rules) + 1}")
            rows.append(
                [
                    c.experiment,
                    c.figures,
                    c.claim,
                    fmt(c.measured),
                    f"**{c.verdict}**" + (f" ({_short(c.reason)})" if c.reason else ""),
                    key,
                ]
            )
            if solver == solvers[0]:
                basis = (
                    "met trivially"
                    if "met trivially" in c.reason
                    else "coupled"
                    if c.verdict == "reproduced" and "not decoupled" in c.reason
                    else ""
                )
                doc.finding(
                    Finding(
                        claim=f"paper, {c.figures} ({c.experiment}, {result.scene.name}"
                        + (", non-equilibrium states" if solver in notes else "")
                        + f"): {c.claim}",
                        metric=c.metric,
                        measured={_measured_name(c.metric): c.measured}
                        | {f"{r} (same metric)": v for r, v in c.references},
                        verdict=c.verdict,
                        rule=c.rule
                        + (f" [{c.reason}]" if c.reason else "")
                        + (f" [{notes[solver]}]" if solver in notes else ""),
                        source="paper",
                        basis=basis,
                    ),
                    shown=True,  # the claims table below
                )
        doc.table(["run", "figures", "paper's claim", "measured", "verdict", "rule"], rows)
        doc.add(
            "Rules: "
            + "; ".join(f"**{k}** ({claim}): {rule}" for (claim, rule), k in rules.items())
            + ". Metrics: "
            + "; ".join(sorted({f"{c.claim}: {c.metric}" for c in checks}))
            + "."
        )
    return notes


#: longest reason shown in a claims-table cell (the finding keeps it whole)
REASON_CHARS = 160


def _short(reason: str) -> str:
    """A claims-table cell's reason, cut at :data:`REASON_CHARS` characters."""
    return reason if len(reason) <= REASON_CHARS else reason[: REASON_CHARS - 3].rstrip() + "..."


def _measured_name(metric: str) -> str:
    """The name of a claim's measured value: a count of trials, or the value itself."""
    return "trials" if metric.startswith("trials") else "value"


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
    from ...document import SOLVER_NAMES

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


#: how a report names each strain convention
CONVENTION_TEXT = {
    "initial": "`initial` (strains against the initial rest lengths: fixed target geometries)",
    "current": "`current` (the paper's literal convention: strains against the learning "
    "rest lengths)",
}


def error_label(strain_reference: str) -> str:
    """``C`` with the rest length its strains are measured against."""
    return "C (Eq. 26, strains vs the " + (
        "initial L)" if strain_reference == "initial" else "learning L)"
    )


def direction(first: float, last: float, *, rel: float = 0.01) -> str:
    """``"rises"``, ``"falls"`` or ``"stays level"`` (within ``rel``) from ``first`` to
    ``last``; ``"is not measured"`` when either is missing."""
    if not (np.isfinite(first) and np.isfinite(last)):
        return "is not measured"
    if abs(last - first) <= rel * max(abs(first), abs(last)):
        return "stays level"
    return "rises" if last > first else "falls"


def _last_finite(row: NDArray) -> float:
    ok = np.flatnonzero(np.isfinite(row))
    return float(row[ok[-1]]) if ok.size else float("nan")


def curve_caption(what: str, row: NDArray) -> str:
    """``"<what> rises from a to b"`` computed from a curve (first and last finite value)."""
    first = float(row[0]) if np.isfinite(row[0]) else float("nan")
    last = _last_finite(row)
    return f"{what} {direction(first, last)} from {fmt(first)} to {fmt(last)}"
