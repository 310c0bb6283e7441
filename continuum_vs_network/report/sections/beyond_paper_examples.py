"""One network, more than one input/output pair, in the ``beyond_paper`` section
(:mod:`.beyond_paper`): symmetric training (a task and its exchange at once) and a
regression task (training and held-out error: generalisation), each beside the optimum of
its training examples.
"""

from __future__ import annotations

import numpy as np

from ...learning.coupling import MET_AT
from ..document import fmt
from ..findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding
from .beyond_paper_format import basis, reasoned


def _infeasible(opt: dict) -> str:
    """The reason a task is not comparable when its optimum shows it infeasible, else ""."""
    from ...scenes.units_beyond import FEASIBLE

    if opt.get("outcome") == "stopped":
        return "the optimum could not be found"
    if not opt.get("feasible"):
        return (
            f"infeasible, the optimum of the stiffnesses leaves its worst example at "
            f"C_e/C_e0 = {fmt(opt['worst_example'])} > {FEASIBLE:g} in "
            f"{opt.get('iterations', '-')} iterations (counted apart)"
        )
    return ""


def _symmetric(doc, units) -> None:
    u = units.get("beyond/symmetric")
    if u is None:
        return
    m = u.meta
    opt = m["exact"]
    doc.heading("Symmetric training", 3)
    before, after = m["error_initial"], m["error_final"]
    total = float(sum(before))
    both = all(np.isfinite(a) and a <= MET_AT * total for a in after)
    doc.add(
        "Rocks et al.'s task (one source, one target) and its exchange trained at once by "
        "GCL of the stiffnesses (the target clamped at the strain it should reach and the "
        "source asked for its own strain, as a second example), "
        f"{m['completed']} steps: errors forward / backward "
        f"{fmt(before[0])} / {fmt(before[1])} before, {fmt(after[0])} / {fmt(after[1])} after; "
        f"coupling {fmt(m['source_share'], 2)} ({m['coupling']}). The optimum of the pair "
        f"leaves its worst direction at C_e/C_e0 = {fmt(opt.get('worst_example'))} "
        f"({opt.get('outcome')}).",
        "",
    )
    reason = _infeasible(opt)
    if reason:
        verdict = NOT_COMPARABLE
    elif both and m["outcome"].startswith("learned"):
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
                "source share": m["source_share"],
                "optimum worst C_e/C_e0": opt.get("worst_example", np.nan),
            },
            verdict=verdict,
            rule=reasoned(
                f"reproduced when both are <= {MET_AT:g} and the network is not decoupled, "
                "not reproduced when a feasible pair is not learned",
                verdict,
                reason,
            ),
            source="field",
            basis=basis([m]),
        )
    )


#: a regression *generalises* when the held-out C/C0 is below 1 and within this factor of
#: the training C/C0
GENERALISES_WITHIN = 2.0


def _regression(doc, units) -> None:
    u = units.get("beyond/regression")
    if u is None:
        return
    m = u.meta
    opt = m["exact"]
    doc.heading("A regression task: generalisation", 3)
    train_ratio = m["train_final"] / m["train_initial"] if m["train_initial"] > 0 else np.nan
    test_ratio = m["test_final"] / m["test_initial"] if m["test_initial"] > 0 else np.nan
    doc.add(
        "The seed paper's proposed next step: desired target strain a fixed linear map of two "
        f"source strains, S_T = M S_S (random M, gain {fmt(m['gain'])}); GCL of the "
        f"stiffnesses on {m['n_train']} training examples, {m['completed']} steps; the summed "
        f"error of {m['n_test']} held-out examples is measured before and after. Training "
        f"C/C0 {fmt(train_ratio)}, held-out C/C0 {fmt(test_ratio)}; coupling of the trained "
        f"network (smallest source share over the training examples) "
        f"{fmt(m['source_share'], 2)} ({m['coupling']}); {fmt(m['seconds'], 2)} s. The optimum "
        f"of the training set leaves its worst example at C_e/C_e0 = "
        f"{fmt(opt.get('worst_example'))} ({opt.get('outcome')}).",
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
                "optimum worst C_e/C_e0": opt.get("worst_example", np.nan),
            },
            verdict=verdict,
            rule=reasoned(
                f"reproduced when held-out C/C0 < 1 and <= {GENERALISES_WITHIN:g} x the "
                "training C/C0",
                verdict,
                reason,
            ),
            source="paper",
            basis=basis([m]),
        )
    )
