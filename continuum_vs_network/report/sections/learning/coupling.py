"""The coupling check of the learning section (:mod:`.`): whether every
trained network's targets are driven by its sources, the per-trial outcome rule, the
source-sweep figure.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ....scenes.results import from_stored
from ....scenes.results.learning import CouplingResult
from ...document import Document, fmt, quiet
from ...figures import COLORS, Panel, Series
from ...findings import Finding

__all__ = ["coupling", "coupling_verdicts", "trial_outcomes"]


def _coupling(result, group: str) -> CouplingResult | None:
    """The coupling of a run's trials (None: not measured)."""
    u = result.units.get(f"coupling/{group}")
    return None if u is None else from_stored(u, CouplingResult)


def coupling_verdicts(result, group: str) -> list[str]:
    """Per-trial coupling verdicts of a run (empty when not measured)."""
    c = _coupling(result, group)
    return list(c.verdicts) if c is not None else []


def coupling(
    doc: Document,
    result,
    h,
    solvers,
    names,
    noise_index: int = 0,
    *,
    notes: dict[str, str] | None = None,
) -> None:
    """A table: for every run, final C/C0, the coupling (source share, verdicts) and what
    was achieved; the sweep figure; one finding per run of the scene's default task.
    ``notes``: per solver whose stored states are not equilibria, the note its findings
    carry (from :func:`.checks.claims`; they are tagged as the claims are)."""
    from ....learning.coupling import COUPLED_AT, DECOUPLED_BELOW, MET_AT
    from ....learning.metrics import final_values, normalised
    from ...verdicts.claims import MIN_STEPS, enough_trials, last_measured

    doc.heading("Are the targets driven by the sources? (coupling of every trained network)")
    doc.add(
        "For every trained network the free state is solved with the source strains scaled "
        "by 0, 0.5, 1, 1.5 and 2 (1: the task; 0: sources off), and the initial network's "
        "and on. With the drive `D = S(1) - S(0)` (`D_0` the initial network's), the offset "
        "`O = S(0) - S_initial(0)` built in at rest and the learned change "
        "`Delta = S(1) - S_initial(1) = (D - D_0) + O` (Delta, not the task error C), the "
        "*source share* is "
        "`min(|D| / (|D| + |O|), clip((D - D_0) . Delta / |Delta|^2, 0, 1))` over the targets: the "
        "first part is small when the targets stopped responding to the sources (a target "
        "that learned its own rest length), the second when the sources' drive was left as "
        "it was and prestress supplied the change (`learning.coupling`). Rule: **coupled** "
        f"if the share is >= {COUPLED_AT:g}, **decoupled** if < {DECOUPLED_BELOW:g}, "
        "**partially coupled** between. "
        f"A trial *learned* the task when its own final C/C0 <= {MET_AT:g} and its own "
        "coupling verdict is not decoupled; a trial that met the task while decoupled met it "
        "*trivially*, which is not a learning success. A run learned the task when a "
        "majority of its trials did (counted per trial, not from two medians); it is "
        f"contradicted when enough trials (half, at least 3) ran >= {MIN_STEPS} steps and "
        "their median C/C0 is >= 1 (fewer: a run cut short, not reproduced).",
    )
    notes = notes or {}
    from ....learning.coupling import coupling_verdict

    rows = []
    for solver in solvers:
        for name in names:
            group = f"{solver}/{name}/noise{noise_index}"
            hist = h(solver, name, noise_index)
            err = hist.task_error(hist.strain_reference)
            final = final_values(normalised(err), hist.completed)
            med = (
                float(np.median(final[np.isfinite(final)])) if np.isfinite(final).any() else np.nan
            )
            c = _coupling(result, group)
            if c is None:
                continue
            share = c.share
            verdicts = list(c.verdicts)
            median_share = quiet(np.nanmedian, share)
            major = coupling_verdict(median_share) if np.isfinite(median_share) else None
            ran = last_measured(hist) >= MIN_STEPS
            tally = trial_outcomes(final, verdicts, ran=ran)
            counts = ", ".join(
                f"{v} {verdicts.count(v)}"
                for v in ("coupled", "partially coupled", "decoupled", "not measured")
                if verdicts.count(v)
            )
            sweep = c.sweep
            on, off = sweep[:, 2, :], sweep[:, 0, :]
            rows.append(
                [
                    name if len(solvers) == 1 else f"{solver}/{name}",
                    hist.strain_reference,
                    fmt(med),
                    f"{fmt(quiet(np.nanmedian, np.abs(on - off)))}",
                    f"{fmt(quiet(np.nanmedian, share))} [{fmt(quiet(np.nanmin, share))}, "
                    f"{fmt(quiet(np.nanmax, share))}]",
                    counts,
                    f"**{tally['outcome']}** ({tally['learned']}/{hist.trials} trials "
                    f"learned, {tally['trivial']} met trivially)",
                ]
            )
            if solver == solvers[0] and major is not None:
                short, long_med = tally["short"], tally["long_median"]
                doc.finding(
                    Finding(
                        claim=f"package check (no claim of the paper; {result.scene.name}"
                        + (", non-equilibrium states" if solver in notes else "")
                        + f"): {name} learns the task through the sources (not trivially)",
                        metric=f"trials whose own final C/C0 ({hist.strain_reference} L) is <= "
                        f"{MET_AT:g} and whose own coupling verdict is not decoupled",
                        measured={
                            "trials learned": tally["learned"],
                            "trials met trivially (decoupled)": tally["trivial"],
                            "trials": hist.trials,
                            "C/C0 (median)": med,
                            "source share (median)": median_share,
                            f"trials with < {MIN_STEPS} steps measured": short,
                        }
                        | (
                            {f"C/C0 (median, trials with >= {MIN_STEPS} steps)": long_med}
                            if np.isfinite(long_med)
                            else {}
                        ),
                        verdict=tally["verdict"],
                        rule=f"per trial: learned if C/C0 <= {MET_AT:g} and not decoupled, met "
                        f"trivially if C/C0 <= {MET_AT:g} and decoupled; reproduced if a majority "
                        "of the trials learned; not comparable if most trials' coupling was not "
                        f"measured; contradicted if at least {enough_trials(hist.trials)} of the "
                        f"{hist.trials} trials ran >= {MIN_STEPS} steps and the median C/C0 over "
                        "those trials is >= 1; not reproduced otherwise"
                        + (
                            f" [{short} of {hist.trials} trials: < {MIN_STEPS} steps measured]"
                            if short
                            else ""
                        )
                        + (f" [{notes[solver]}]" if solver in notes else ""),
                        basis=(
                            "coupled"
                            if tally["learned"] > tally["trivial"]
                            else "met trivially"
                            if tally["trivial"]
                            else ""
                        ),
                    ),
                    shown=True,  # the outcome column of the coupling table
                )
    if not rows:
        doc.add(
            "",
            "**Not measured**: the scene sets `measure = false` (the rules' own work only), "
            "so no result of this report can be told from a trivial solution.",
        )
        return
    doc.table(
        [
            "run",
            "strain_reference",
            "final C/C0 (median)",
            "|S_T(on) - S_T(off)| (median)",
            "source share median [min, max]",
            "coupling verdicts (trials)",
            "outcome",
        ],
        rows,
    )
    _sweep_figure(doc, result, solvers[0], names, noise_index)


def trial_outcomes(final: NDArray, verdicts: list[str], *, ran: NDArray | None = None) -> dict:
    """Per-trial joint rule of a run's task outcome, (trials,) final C/C0 and coupling
    verdicts: ``learned`` (C/C0 <= MET_AT and not decoupled), ``trivial`` (met while
    decoupled), ``unmeasured`` (no coupling verdict or no final C/C0), the run's ``outcome``
    text, ``short`` (trials that did not run the steps), ``long_median`` (median C/C0 over
    those that did, nan for none) and the finding's ``verdict``: reproduced when a majority
    of the trials learned, not comparable when most are unmeasured, contradicted when at least
    :func:`~continuum_vs_network.report.verdicts.claims.enough_trials` trials ran
    :data:`~continuum_vs_network.report.verdicts.claims.MIN_STEPS` steps (``ran``, (trials,) bool;
    None: all of them did) and the median C/C0 over those trials is >= 1, not reproduced
    otherwise."""
    from ....learning.coupling import MET_AT
    from ...verdicts.claims import enough_trials

    final = np.asarray(final, dtype=np.float64)
    n = len(final)
    measured = [
        i
        for i in range(n)
        if np.isfinite(final[i]) and i < len(verdicts) and verdicts[i] != "not measured"
    ]
    met = [i for i in measured if final[i] <= MET_AT]
    learned = sum(1 for i in met if verdicts[i] != "decoupled")
    trivial = len(met) - learned
    ran = np.ones(n, dtype=bool) if ran is None else np.asarray(ran, dtype=bool)
    long = final[ran & np.isfinite(final)]
    long_median = float(np.median(long)) if long.size else float("nan")
    if 2 * learned > n:
        outcome, verdict = "learned", "reproduced"
    elif 2 * (n - len(measured)) > n:
        outcome, verdict = "not measured", "not comparable"
    else:
        outcome = "not learned"
        rises = long.size >= enough_trials(n) and long_median >= 1.0
        verdict = "contradicted" if rises else "not reproduced"
    return {
        "learned": learned,
        "trivial": trivial,
        "unmeasured": n - len(measured),
        "short": int(n - ran.sum()),
        "long_median": long_median,
        "outcome": outcome,
        "verdict": verdict,
    }


def _sweep_figure(doc: Document, result, solver: str, names, noise_index: int) -> None:
    panels = []
    for name in names:
        c = _coupling(result, f"{solver}/{name}/noise{noise_index}")
        if c is None:
            continue
        scales, sweep = c.scales, c.sweep
        series = []
        for i in range(sweep.shape[0]):
            for t in range(sweep.shape[2]):
                series.append(
                    Series(
                        scales,
                        sweep[i, :, t] - c.desired[i, t],
                        "trained" if i == t == 0 else "",
                        marker="o",
                        width=1.0,
                        color=COLORS[0],
                    )
                )
        panels.append(
            Panel(
                series,
                name,
                "source strain / task source strain",
                "S_T - desired S_T",
                hlines=(0.0,),
                legend=False,
            )
        )
    if panels:
        doc.figure(
            "coupling",
            panels,
            "Source sweeps of every trained network: each target's strain minus its "
            "desired strain against the source strains scaled by 0 ... 2 (one line per "
            "trial and target; the task is at 1, where a met task crosses 0). A flat "
            "line is a target the sources do not drive; a sloped line can still be "
            "decoupled when its slope is the untrained network's (the drive was left as it "
            "was and prestress met the task), which the table's source share measures and "
            "this figure does not show.",
            ncols=min(4, len(panels)),
            panel_size=(3.2, 2.6),
        )
