"""Capacity of the ``beyond_paper`` section (:mod:`.beyond_paper`): final error of networks
trained on several examples at once against the number of examples, two sizes, several
draws, and the capacity rule (:func:`capacity`).
"""

from __future__ import annotations

import numpy as np

from ...learning.coupling import MET_AT
from ..figures import COLORS, Panel, Series
from ..findings import CONTRADICTED, NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding
from .beyond_paper_format import _g


def capacity(outcomes: dict[int, list[str]]) -> int:
    """Largest number of examples ``m`` at which at least half the runs (draws) *learned*
    (outcome ``"learned ..."``: ``C/C0 <= MET_AT`` and not decoupled); 0 when no ``m`` did."""
    best = 0
    for m, runs in outcomes.items():
        learned = sum(o.startswith("learned") for o in runs)
        if runs and 2 * learned >= len(runs):
            best = max(best, m)
    return best


def _draw_outcome(meta: dict) -> str:
    """A capacity draw's outcome: its coupling outcome, unless an example missed its own
    response (``worst_example > MET_AT``)."""
    worst = meta.get("worst_example", float("nan"))
    if meta["outcome"].startswith("learned") and not worst <= MET_AT:
        return "not met (an example missed)"
    return meta["outcome"]


def _capacity(doc, scene, units) -> None:
    from ...scenes.units_beyond import CAPACITY, EXACT, GCL_K

    L = scene.learning
    sizes = scene.network.sizes
    seeds = range(L.capacity_seeds)
    doc.heading("Several examples at once: capacity", 3)
    doc.add(
        "Networks trained on m independent input/output pairs at once (each example its own "
        "source and target spring, source strain ~ N(0, "
        f"{scene.task.source_std:g}); the desired target strain is the untrained network's "
        f"response changed by {CAPACITY['change']:g} of itself, up or down at random: Rocks et "
        "al. 2019's kind of task), the error C the sum of the examples' errors, stiffnesses "
        f"learned with floor {GCL_K['floor']:g} mean k, {L.capacity_seeds} draws of the "
        "examples per size and m (one network per size). Two ways on the same draws: "
        "*exact*, the optimum of C (L-BFGS-B on the exact adjoint gradient, at most "
        f"{EXACT['max_iter']} iterations, stopped once every example's C_e/C_e0 <= 1e-4): "
        "what the network can hold, as far as a local search finds it (a converged search "
        "can stop at a local optimum, so the exact capacity is a lower bound); *GCL*, the "
        "local rule (one step is the sum of the "
        f"per-example updates; rate {GCL_K['alpha']:g} / mean k, nudge {L.eta:g}, "
        f"{L.steps} steps): what the rule reaches in that budget. A draw is *learned* when "
        f"every example met its own response, C_e/C_e0 <= {MET_AT:g} (the summed C/C0 is "
        "dominated by the examples with the strongest responses), and the network is not "
        "decoupled. The *capacity* of a size is the largest m at which at least half the "
        "draws learned.",
        "",
    )
    rows, series, caps, gcl_caps, unconverged = [], [], {}, {}, 0
    for i, n in enumerate(sizes):
        by_m, by_m_gcl, med = {}, {}, {}
        for m in L.examples:
            us = [units[f"beyond/capacity/size{n}/examples{m}/seed{s}"] for s in seeds]
            ex = [u.meta["exact"] for u in us]
            by_m[m] = [_draw_outcome(e) for e in ex]
            by_m_gcl[m] = [_draw_outcome(u.meta) for u in us]
            unconverged += sum(not e.get("converged", False) for e in ex)
            worst = np.array([e["worst_example"] for e in ex], dtype=float)
            med[m] = float(np.median(worst)) if np.all(np.isfinite(worst)) else float("nan")
            rows.append(
                [
                    f"{n} x {n} ({us[0].meta['n_springs']} springs)",
                    m,
                    ", ".join(_g(w) for w in worst),
                    f"{sum(o.startswith('learned') for o in by_m[m])} / {len(us)}",
                    ", ".join("yes" if e.get("converged") else "no" for e in ex),
                    ", ".join(_g(u.meta.get("worst_example")) for u in us),
                    f"{sum(o.startswith('learned') for o in by_m_gcl[m])} / {len(us)}",
                    _g(min(min(e["source_share"], u.meta["source_share"])
                           for e, u in zip(ex, us)), 2),
                    _g(sum(e["seconds"] for e in ex)) + " / "
                    + _g(sum(u.meta["seconds"] for u in us)),
                ]
            )  # fmt: skip
        caps[n], gcl_caps[n] = capacity(by_m), capacity(by_m_gcl)
        series.append(
            Series(np.array(list(med), dtype=float), np.array(list(med.values())),
                   f"{n} x {n}", marker="o", color=COLORS[i % len(COLORS)])
        )  # fmt: skip
    doc.table(
        ["lattice", "examples", "exact: worst C_e/C_e0 (each draw)", "exact: draws learned",
         "exact: converged", "GCL: worst C_e/C_e0 (each draw)", "GCL: draws learned",
         "smallest source share", "seconds exact / GCL (all draws)"],
        rows,
    )  # fmt: skip
    doc.figure(
        "beyond_capacity",
        [Panel(series, "capacity (exact gradient)", "examples m",
               "median worst example's C_e / C_e0", xscale="log", yscale="log",
               hlines=(MET_AT,))],
        f"Median over {L.capacity_seeds} draws of the worst example's error at the "
        f"exact-gradient optimum, m examples at once, every lattice size (dotted: {MET_AT:g}).",
    )  # fmt: skip
    small, large = sizes[0], sizes[-1]
    top = max(L.examples)
    if caps[large] == top and caps[small] == top:
        verdict = NOT_COMPARABLE
    elif caps[large] > caps[small]:
        verdict = REPRODUCED
    elif max(caps[small], caps[large]) < 2:
        verdict = NOT_COMPARABLE
    elif caps[large] == caps[small]:
        verdict = NOT_REPRODUCED
    else:
        verdict = CONTRADICTED
    censored = [f"{n} x {n}" for n, c in caps.items() if c == top]
    doc.finding(
        Finding(
            claim="a larger network holds more independent examples (Rocks et al. 2019)",
            metric=f"capacity by the exact gradient (largest m at which at least half of "
            f"{L.capacity_seeds} draws learned at the optimum: every example's C_e/C_e0 <= "
            f"{MET_AT:g}, not decoupled); GCL's capacity beside it",
            measured={
                **{f"exact capacity {n} x {n}": float(c) for n, c in caps.items()},
                **{f"GCL capacity {n} x {n}": float(c) for n, c in gcl_caps.items()},
            },
            verdict=verdict,
            rule="from the exact-gradient capacities: reproduced when the largest lattice's "
            "capacity exceeds the smallest's, not reproduced when equal, contradicted when "
            "smaller; not comparable when both reach the largest m run (the limit is not "
            "reached) or neither holds two examples",
        )
    )
    reach = [
        f"{n} x {n}: GCL {gcl_caps[n]} of {caps[n]} "
        + ("(reaches it)" if gcl_caps[n] >= caps[n] else "(falls short)")
        for n in sizes
    ]
    doc.add(
        "Capacity by the exact gradient: "
        + ", ".join(f"{n} x {n}: {c}" for n, c in caps.items())
        + " examples"
        + (f" (at least: {', '.join(censored)} learned the largest m run)" if censored else "")
        + f"; {verdict} by the rule in the findings. "
        + f"By GCL in {L.steps} steps: " + "; ".join(reach) + ". "
        + (f"{unconverged} exact-gradient searches hit the iteration limit (their draws count "
           "as learned only if they met the criterion anyway, so an exact capacity is a lower "
           "bound)." if unconverged else "Every exact-gradient search converged."),
        "",
    )  # fmt: skip
