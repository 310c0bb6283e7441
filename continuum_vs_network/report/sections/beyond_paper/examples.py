"""One network, more than one input/output pair, in the ``beyond_paper`` section (:mod:`.`):

* capacity: networks trained on several examples at once against the number of examples
  and the network size, several draws: what the optimum holds (feasible draws) and what GCL
  learns of it, and the capacity rule (:func:`capacity`);
* symmetric training (a task and its exchange at once) and a regression task (training and
  held-out error: generalisation), each beside the optimum of its training examples.
"""

from __future__ import annotations

import numpy as np

from ....learning.coupling import MET_AT
from ....scenes.results.beyond_paper import (
    CapacityResult,
    ExamplesRun,
    OptimumResult,
    RegressionResult,
    SymmetricResult,
)
from ...document import coupling_text, fmt
from ...figures import COLORS, Panel, Series
from ...findings import (
    CONTRADICTED,
    NOT_COMPARABLE,
    NOT_REPRODUCED,
    REPRODUCED,
    Finding,
    reasoned,
    runs_basis,
)
from .aging import _or_dash


def capacity(outcomes: dict[int, list[str]]) -> int:
    """Largest number of examples ``m`` at which at least half the runs (draws) *learned*
    (outcome ``"learned ..."``: ``C/C0 <= MET_AT`` and not decoupled); 0 when no ``m`` did."""
    best = 0
    for m, runs in outcomes.items():
        learned = sum(o.startswith("learned") for o in runs)
        if runs and 2 * learned >= len(runs):
            best = max(best, m)
    return best


def _draw_outcome(run: ExamplesRun) -> str:
    """A run's outcome, unless an example missed its own response
    (``worst_example > MET_AT``)."""
    if run.outcome.startswith("learned") and not run.worst_example <= MET_AT:
        return "not met (an example missed)"
    return run.outcome


def _held(opt: OptimumResult) -> str:
    """An optimum as a capacity outcome: held ("learned ...") when feasible and not
    decoupled."""
    if opt.feasible and opt.coupling != "decoupled":
        return f"learned ({opt.coupling})"
    return "not met"


def _capacity(doc, scene, units) -> None:
    from ....scenes.units_beyond import FEASIBLE
    from ....scenes.units_beyond_examples import CAPACITY

    L = scene.learning
    sizes = scene.network.sizes
    seeds = range(L.capacity_seeds)
    doc.heading("Several examples at once: capacity", 3)
    doc.add(
        "Networks trained on m independent input/output pairs at once (each example its own "
        "source and target spring, source strain ~ N(0, "
        f"{scene.task.source_std:g}); the desired target strain is the untrained network's "
        f"response changed by {CAPACITY['change']:g} of itself, up or down at random: Rocks et "
        "al. 2019's kind of task), C the sum of the examples' errors, stiffnesses learned "
        "(a network at rest learning stiffnesses cannot prestress: a met example is a changed "
        f"response), {L.capacity_seeds} draws of the examples per size and m (one network "
        "per size). Two ways on the same draws: the *optimum* of C (L-BFGS-B on the exact "
        f"gradient within the stiffness range, at most {L.steps} iterations): a draw is "
        f"*feasible* when it brings every example to C_e/C_e0 <= {FEASIBLE:g}; and *GCL*, "
        f"the default local rule, {L.steps} steps (one step is the sum of the per-example "
        "updates): a draw is *learned* when every example met its own response, C_e/C_e0 <= "
        f"{MET_AT:g}, and the network is not decoupled. The *capacity* of a size is the "
        "largest m at which at least half the draws are feasible (optimum) or learned (GCL, "
        "among the feasible draws; infeasible draws are counted apart). A converged search "
        "can stop at a local optimum, so a capacity by the optimum is a lower bound.",
        "",
    )
    rows, series, caps, gcl_caps = [], [], {}, {}
    feasible_runs, learned_runs, infeasible = [], [], 0
    for i, n in enumerate(sizes):
        by_m, by_m_gcl, med = {}, {}, {}
        for m in L.examples:
            us: list[CapacityResult] = [
                units[f"beyond/capacity/size{n}/examples{m}/seed{s}"] for s in seeds
            ]
            ex = [u.optimum for u in us]
            by_m[m] = [_held(e) for e in ex]
            feas = [u for u, e in zip(us, ex) if e.feasible]
            infeasible += len(us) - len(feas)
            feasible_runs += feas
            by_m_gcl[m] = [_draw_outcome(f) for f in feas]
            learned_runs += [f for f in feas if _draw_outcome(f).startswith("learned")]
            worst = np.array([e.worst_example for e in ex], dtype=float)
            med[m] = float(np.median(worst)) if np.all(np.isfinite(worst)) else float("nan")
            rows.append(
                [
                    f"{n} x {n} ({us[0].n_springs} springs)",
                    m,
                    ", ".join(fmt(w) for w in worst),
                    f"{len(feas)} / {len(us)}",
                    ", ".join(str(_or_dash(e.iterations)) for e in ex),
                    ", ".join(fmt(u.worst_example) for u in us),
                    f"{sum(o.startswith('learned') for o in by_m_gcl[m])} / {len(feas)}",
                    fmt(min(min(e.source_share, u.source_share)
                           for e, u in zip(ex, us)), 2),
                    fmt(sum(e.seconds for e in ex)) + " / "
                    + fmt(sum(u.seconds for u in us)),
                ]
            )  # fmt: skip
        caps[n], gcl_caps[n] = capacity(by_m), capacity(by_m_gcl)
        series.append(
            Series(np.array(list(med), dtype=float), np.array(list(med.values())),
                   f"{n} x {n}", marker="o", color=COLORS[i % len(COLORS)])
        )  # fmt: skip
    doc.table(
        ["lattice", "examples", "optimum: worst C_e/C_e0 (each draw)", "feasible draws",
         "optimum: iterations", "GCL: worst C_e/C_e0 (each draw)", "GCL: learned / feasible",
         "smallest source share", "seconds optimum / GCL (all draws)"],
        rows,
    )  # fmt: skip
    doc.figure(
        "beyond_capacity",
        [Panel(series, "capacity (optimum)", "examples m",
               "median worst example's C_e / C_e0", xscale="log", yscale="log",
               hlines=(FEASIBLE,))],
        f"Median over {L.capacity_seeds} draws of the worst example's error at the optimum, "
        f"m examples at once, every lattice size (dotted: {FEASIBLE:g}, feasible below).",
    )  # fmt: skip
    small, large = sizes[0], sizes[-1]
    top = max(L.examples)
    reason = ""
    if caps[large] == top and caps[small] == top:
        verdict = NOT_COMPARABLE
        reason = f"every size holds the largest m run ({top}): the limit is not reached"
    elif caps[large] > caps[small]:
        verdict = REPRODUCED
    elif max(caps[small], caps[large]) < 2:
        verdict = NOT_COMPARABLE
        reason = "no size holds two examples"
    elif caps[large] == caps[small]:
        verdict = NOT_REPRODUCED
    else:
        verdict = CONTRADICTED
    opt_metas = [
        units[f"beyond/capacity/size{n}/examples{m}/seed{s}"].optimum
        for n in sizes for m in L.examples for s in seeds
    ]  # fmt: skip
    doc.finding(
        Finding(
            claim="a larger network holds more independent examples (Rocks et al. 2019)",
            metric=f"capacity by the optimum (largest m at which at least half of "
            f"{L.capacity_seeds} draws are feasible: every example's C_e/C_e0 <= {FEASIBLE:g}, "
            "not decoupled)",
            measured={f"capacity {n} x {n}": float(c) for n, c in caps.items()},
            verdict=verdict,
            rule=reasoned(
                "reproduced when the largest lattice's capacity exceeds the smallest's, not "
                "reproduced when equal, contradicted when smaller",
                verdict,
                reason,
            ),
            source="field",
            basis=runs_basis([e for e in opt_metas if e.feasible]),
        )
    )
    if not feasible_runs:
        gverdict, greason = NOT_COMPARABLE, "no draw is feasible"
    elif all(gcl_caps[n] >= caps[n] for n in sizes):
        gverdict, greason = REPRODUCED, ""
    else:
        gverdict, greason = NOT_REPRODUCED, ""
    doc.finding(
        Finding(
            claim="GCL learns as many examples at once as the network can hold (its capacity "
            "reaches the optimum's)",
            metric=f"GCL's capacity among the feasible draws ({L.steps} steps) against the "
            f"optimum's (at most {L.steps} iterations), every size",
            measured={
                **{f"GCL capacity {n} x {n}": float(c) for n, c in gcl_caps.items()},
                **{f"optimum capacity {n} x {n}": float(c) for n, c in caps.items()},
                "feasible draws": float(len(feasible_runs)),
                "learned by GCL": float(len(learned_runs)),
                "infeasible draws (apart)": float(infeasible),
            },
            verdict=gverdict,
            rule=reasoned(
                "reproduced when GCL's capacity equals the optimum's at every size, not "
                "reproduced when it falls short at some size",
                gverdict,
                greason,
            ),
            source="field",
            basis=runs_basis(feasible_runs),
        )
    )
    reach = [
        f"{n} x {n}: GCL {gcl_caps[n]} of {caps[n]} "
        + ("(reaches it)" if gcl_caps[n] >= caps[n] else "(falls short)")
        for n in sizes
    ]
    doc.add(
        "Capacity by the optimum: "
        + ", ".join(f"{n} x {n}: {c}" for n, c in caps.items())
        + f" examples; {verdict} by the rule in the findings. "
        + f"By GCL in {L.steps} steps: " + "; ".join(reach)
        + f". GCL learned {len(learned_runs)} of the {len(feasible_runs)} feasible draws "
        + f"({infeasible} infeasible draws counted apart).",
        "",
    )  # fmt: skip


def _infeasible(opt: OptimumResult) -> str:
    """The reason a task is not comparable when its optimum shows it infeasible, else ""."""
    from ....scenes.units_beyond import FEASIBLE

    if opt.outcome == "stopped":
        return "the optimum could not be found"
    if not opt.feasible:
        return (
            f"infeasible, the optimum of the stiffnesses leaves its worst example at "
            f"C_e/C_e0 = {fmt(opt.worst_example)} > {FEASIBLE:g} in "
            f"{_or_dash(opt.iterations)} iterations (counted apart)"
        )
    return ""


def _symmetric(doc, units) -> None:
    m: SymmetricResult | None = units.get("beyond/symmetric")
    if m is None:
        return
    opt = m.optimum
    doc.heading("Symmetric training", 3)
    before, after = m.error_initial, m.error_final
    total = float(sum(before))
    both = all(np.isfinite(a) and a <= MET_AT * total for a in after)
    doc.add(
        "Rocks et al.'s task (one source, one target) and its exchange trained at once by "
        "GCL of the stiffnesses (the target clamped at the strain it should reach and the "
        "source asked for its own strain, as a second example), "
        f"{m.completed} steps: errors forward / backward "
        f"{fmt(before[0])} / {fmt(before[1])} before, {fmt(after[0])} / {fmt(after[1])} after; "
        f"coupling {coupling_text(m)}. The optimum of the pair "
        f"leaves its worst direction at C_e/C_e0 = {fmt(opt.worst_example)} "
        f"({opt.outcome}).",
        "",
    )
    reason = _infeasible(opt)
    if reason:
        verdict = NOT_COMPARABLE
    elif both and m.outcome.startswith("learned"):
        verdict = REPRODUCED
    else:
        verdict = NOT_REPRODUCED
    doc.finding(
        Finding(
            claim="one network learns a task and its exchange (source and target swapped) at once",
            metric="each direction's final error over the summed initial error; the optimum's "
            "worst direction",
            measured={
                "forward": after[0] / total,
                "backward": after[1] / total,
                "source share": m.source_share,
                "optimum worst C_e/C_e0": opt.worst_example,
            },
            verdict=verdict,
            rule=reasoned(
                f"reproduced when both are <= {MET_AT:g} and the network is not decoupled, "
                "not reproduced when a feasible pair is not learned",
                verdict,
                reason,
            ),
            source="field",
            basis=runs_basis([m]),
        )
    )


#: a regression *generalises* when the held-out C/C0 is below 1 and within this factor of
#: the training C/C0
GENERALISES_WITHIN = 2.0


def _regression(doc, units) -> None:
    m: RegressionResult | None = units.get("beyond/regression")
    if m is None:
        return
    opt = m.optimum
    doc.heading("A regression task: generalisation", 3)
    train_ratio = m.train_final / m.train_initial if m.train_initial > 0 else np.nan
    test_ratio = m.test_final / m.test_initial if m.test_initial > 0 else np.nan
    doc.add(
        "The seed paper's proposed next step: desired target strain a fixed linear map of two "
        f"source strains, S_T = M S_S (random M, gain {fmt(m.gain)}); GCL of the "
        f"stiffnesses on {m.n_train} training examples, {m.completed} steps; the summed "
        f"error of {m.n_test} held-out examples is measured before and after. Training "
        f"C/C0 {fmt(train_ratio)}, held-out C/C0 {fmt(test_ratio)}; coupling of the trained "
        f"network (smallest source share over the training examples) "
        f"{coupling_text(m)}; {fmt(m.seconds, 2)} s. The optimum "
        f"of the training set leaves its worst example at C_e/C_e0 = "
        f"{fmt(opt.worst_example)} ({opt.outcome}).",
        "",
    )
    finite = bool(np.isfinite(train_ratio) and np.isfinite(test_ratio))
    reason = _infeasible(opt)
    if reason:
        verdict = NOT_COMPARABLE
    elif not finite or train_ratio > MET_AT:
        verdict = NOT_COMPARABLE  # nothing learned, nothing to generalise
        reason = f"training did not reach C/C0 <= {MET_AT:g}, so there is nothing to generalise"
    elif test_ratio < 1.0 and test_ratio <= GENERALISES_WITHIN * train_ratio:
        verdict = REPRODUCED
    else:
        verdict = NOT_REPRODUCED
    doc.finding(
        Finding(
            claim="a network trained on a few examples of a linear map predicts held-out "
            "examples better than before training (generalises)",
            metric="summed error of the training and of the held-out examples, final over initial",
            measured={
                "train C/C0": float(train_ratio),
                "held-out C/C0": float(test_ratio),
                "optimum worst C_e/C_e0": opt.worst_example,
            },
            verdict=verdict,
            rule=reasoned(
                f"reproduced when held-out C/C0 < 1 and <= {GENERALISES_WITHIN:g} x the "
                "training C/C0",
                verdict,
                reason,
            ),
            source="paper",
            basis=runs_basis([m]),
        )
    )
