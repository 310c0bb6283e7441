"""Checks on learning runs: coupling of every trained network, the paper's claims judged by
rule, the read-out noise floor, and captions computed from the data.

This module judges the paper's claims; the other checks are their own modules:
:mod:`.learning_checks_text` (conventions, labels, captions), :mod:`.learning_checks_coupling`,
:mod:`.learning_checks_equilibria`, :mod:`.learning_checks_noise`.
"""

from __future__ import annotations

from ..document import Document, fmt
from ..findings import Finding
from .learning_checks_coupling import _coupling_unit as _coupling_unit
from .learning_checks_coupling import _sweep_figure as _sweep_figure
from .learning_checks_coupling import coupling, coupling_verdicts, trial_outcomes
from .learning_checks_equilibria import EQUILIBRIUM_RESIDUAL as EQUILIBRIUM_RESIDUAL
from .learning_checks_equilibria import _completed as _completed
from .learning_checks_equilibria import _equilibria, not_equilibria, residual_range
from .learning_checks_noise import noise_floor
from .learning_checks_text import CONVENTION_TEXT, curve_caption, direction, error_label
from .learning_checks_text import _last_finite as _last_finite

__all__ = [
    "CONVENTION_TEXT",
    "EQUILIBRIUM_RESIDUAL",
    "claims",
    "coupling",
    "coupling_verdicts",
    "curve_caption",
    "direction",
    "error_label",
    "noise_floor",
    "not_equilibria",
    "residual_range",
    "trial_outcomes",
]


def claims(doc: Document, result, h, solvers) -> dict[str, str]:
    """The paper's claims table with computed verdicts; one finding per statement (only in
    the paper's own setting, ``[learning] paper_setting``; another paper scene says where
    they are judged). Returns, per solver whose stored states are not equilibria, the note
    its findings carry."""
    from ...scenes.units_learning import experiments
    from ..verdicts.claims import MIN_STEPS, check_claims

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
