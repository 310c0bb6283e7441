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
    """The paper's claims table with computed verdicts; one finding per statement. Returns,
    per solver whose stored states are not equilibria, the note its findings carry."""
    from ...learning.claims import MIN_STEPS, check_claims
    from ...scenes.units_learning import experiments

    L = result.scene.learning
    doc.heading("The paper's claims and what this package measures")
    doc.add(
        "Each claim of the paper is split into its statements and measured on this run; "
        "the verdict follows from the rule in the last column (reproduced / not reproduced "
        "/ contradicted / not comparable). The paper's task error is Eq. 26 with strains "
        "against the *learning* rest length (Eq. 24 as printed): claims about C are judged "
        "on that metric whatever this run's convention, which is "
        f"{CONVENTION_TEXT[L.strain_reference]}. Claims that the task is learned also need "
        "the trained networks not to be decoupled (coupling section), counted per trial: "
        "a trial counts when its own final value meets the claim and its own coupling "
        "verdict is not decoupled. The paper's coupled learning clamps in the `current` "
        "convention, its prospective configuration in the `initial` one (Sec. 7.2: the "
        "rod's length stays fixed while the rest lengths learn), so a GCL run in `initial` "
        "and a GPC run in `current` ran another procedure and their claims are not "
        "comparable. The paper ran 300 steps: a size reached (orders of magnitude, C = 0, "
        f"~50 %, 33 %) is judged only on the trials that completed at least {MIN_STEPS} "
        f"steps, and is not comparable when fewer than half of the trials (or fewer than "
        "3) did; a direction (rises, descends) is judged on every trial."
    )
    notes = _equilibria(doc, h, solvers, L.rules)
    for solver in solvers:
        hs = {r: h(solver, r) for r in L.rules}
        coupling_of = {r: coupling_verdicts(result, f"{solver}/{r}/noise0") for r in L.rules}
        checks = check_claims(hs, experiments(result.scene, solver), coupling=coupling_of)
        if len(solvers) > 1:
            doc.add("", f"**{solver}**", "")
        rows = []
        for c in checks:
            rows.append(
                [
                    c.experiment,
                    c.figures,
                    c.claim,
                    c.metric,
                    fmt(c.measured),
                    f"**{c.verdict}**" + (f" ({c.reason})" if c.reason else ""),
                    c.rule,
                ]
            )
            if solver == solvers[0]:
                doc.finding(
                    Finding(
                        claim=f"paper, {c.figures} ({c.experiment}, {result.scene.name}"
                        + (", non-equilibrium states" if solver in notes else "")
                        + f"): {c.claim}",
                        metric=c.metric,
                        measured={"value": c.measured}
                        | {f"{r} (same metric)": v for r, v in c.references},
                        verdict=c.verdict,
                        rule=c.rule
                        + (f" [{c.reason}]" if c.reason else "")
                        + (f" [{notes[solver]}]" if solver in notes else ""),
                    ),
                    shown=True,  # the claims table below
                )
        doc.table(
            ["run", "figures", "paper's claim", "metric", "measured", "verdict", "rule"], rows
        )
        others = [r for r in L.rules if r not in {c.experiment for c in checks}]
        if others:
            doc.add(
                "Runs without a claim in the paper (references): "
                + ", ".join(f"`{r}`" for r in others)
                + "; their results are in the coupling table and the figures."
            )
    return notes
