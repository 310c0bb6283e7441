"""The paper's claims about its learning runs, checked against histories by stated rules.

Every claim of :func:`...scenes.replication.paper_experiments` is split into the statements it
makes (C falls by orders of magnitude; E^C descends; ...). :func:`check_claims` measures
each on the histories of a run and gives a verdict by the rule printed next to it:

``reproduced``
    the measured value satisfies the statement;
``contradicted``
    it shows the opposite (a quantity said to fall rises; none of the trials converges);
``not reproduced``
    neither (the right direction but not the stated size), or a task success that the
    coupling measurement shows to be trivial (:mod:`...learning.coupling`: the targets keep their
    strain with the sources off), which is not the success the paper claims;
``not comparable``
    the run differs from the paper's in what the claim depends on (a rule run in the other
    strain convention is another algorithm; a size reached after the paper's 300 steps
    judged on too few trials that ran :data:`MIN_STEPS`), or nothing was measured.

Claims of a *direction* (rises, descends, lowers) are judged on every trial at any run
length; claims of a *size* reached (orders of magnitude, C = 0, ~50 %, 33 %, converges to
0) only on the trials that completed at least :data:`MIN_STEPS` steps (the GCL notebook's
100 epochs; :func:`last_measured`) or whose learning ran away (:func:`diverged`: judged with
their last value, a failure), and are "not comparable" when fewer than
:func:`enough_trials` of them did.

A claim that a quantity *converges to 0* (C falls by orders of magnitude, all trials but
one reach C = 0, the rest-length error converges to 0) is "not reproduced" or
"contradicted" only when the median curve over the judged trials has stopped falling by
the plateau test (:func:`...learning.metrics.tail_change`,
:func:`...learning.metrics.bound`), and "not comparable" while it still falls (the run
settles lower than the value read; the reason gives the change).

A claim that the task is learned, or that C is lowered, is judged per trial: a trial meets
it when its own final value does *and* its own coupling verdict is not decoupled (a trial
that meets it while decoupled met it trivially, :mod:`...learning.coupling`); the verdict is
"reproduced" only when the statement's count of such trials is reached (a majority for
"lowers C" and "orders of magnitude"). Medians taken separately over the error and over
the coupling are not combined.

A claim that C *rises* under GPC is a property of GPC only if it is specific to it: C is
measured against a rest length that moves, so it can rise under any rule. Such a statement
is "reproduced" only when its value also exceeds the same metric of the reference rule
(:data:`REFERENCE_RULE`, the exact gradient) in the same run, and "not comparable"
otherwise; the reference's and the other rules' values are kept in
:attr:`ClaimCheck.references`.

The metric: the paper's task error (Figs. 4, 6, 10) is Eq. 26 with strains against the
learning rest length (Eq. 24 as printed), i.e. ``error_current``; claims about ``C`` are
judged on it in every scene. The paper's coupled learning clamps in that convention
(``"current"``). Its prospective configuration inserts rods of fixed length: "during GPC
this fixed rod length remains unchanged throughout the learning process, if the target
spring updates its equilibrium length then the induced strain changes too" (Sec. 7.2),
which is the ``"initial"`` clamp convention; GPC claims are judged on runs in that
convention only (a GPC run in ``"current"`` moves its rods with ``L``: another procedure).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...learning.history import History
from ...learning.metrics import PLATEAU, bound, tail_change
from .claim_statements import statements

__all__ = [
    "MIN_STEPS",
    "REFERENCE_RULE",
    "VERDICTS",
    "ClaimCheck",
    "check_claims",
    "diverged",
    "enough_trials",
    "last_measured",
    "majority",
]

VERDICTS = ("reproduced", "not reproduced", "contradicted", "not comparable")
#: fewest learning steps on which a claim about a size reached is judged (the GCL notebook's
#: 100 epochs; the GPC notebook's 150)
MIN_STEPS = 100

#: the strain conventions in which the paper's run of each rule family is reproduced
_PAPER_CONVENTIONS = {"gcl": ("current",), "gpc": ("initial",)}
_CONVENTION_REASON = {
    "gcl": "the paper's GCL clamps against the learning L (`current`)",
    "gpc": "the paper's GPC keeps its rods at a fixed length while L learns (Sec. 7.2), "
    "the `initial` convention",
}
#: the rule a statement that must be specific to the claimed rule is compared with (the
#: exact gradient of the same task, in the same run)
REFERENCE_RULE = "exact"


@dataclass(frozen=True)
class ClaimCheck:
    """One statement of the paper, measured and judged.

    Attributes
    ----------
    experiment, figures : str
        The run (``"gcl"``, ...) and the paper's figures.
    claim : str
        The statement, as the paper makes it.
    metric : str
        What is measured (which error, which statistic over trials).
    measured : float
        The measured value (NaN: nothing measured).
    rule : str
        How the verdict follows from ``measured``.
    verdict : str
        One of :data:`VERDICTS`.
    reason : str
        Why, in a few words (the coupling, the convention, ...).
    references : tuple of (str, float)
        The same metric measured on the reference rules of the same run (the exact
        gradient first), for a statement that must be specific to the claimed rule.
    """

    experiment: str
    figures: str
    claim: str
    metric: str
    measured: float
    rule: str
    verdict: str
    reason: str = ""
    references: tuple[tuple[str, float], ...] = ()


def majority(verdicts: Sequence[str]) -> str | None:
    """The most common coupling verdict of the trials (ties go to the less coupled one);
    None when no trial was measured."""
    order = ("decoupled", "partially coupled", "coupled")
    counts = {v: list(verdicts).count(v) for v in order}
    if not any(counts.values()):
        return None
    return max(order, key=lambda v: (counts[v], -order.index(v)))


def last_measured(h: History) -> NDArray[np.int64]:
    """Index of each trial's last measurement, (trials,): ``completed``, or one less for a
    trial that stopped because its equilibrium was lost (no measurement at ``completed``)."""
    idx = np.minimum(np.asarray(h.completed, dtype=np.int64), h.steps)
    at = h.error_current[np.arange(h.trials), idx]
    return idx - ((~np.isfinite(at)) & (idx > 0)).astype(np.int64)


#: stop reasons of a trial whose learning ran away (a rest length to 0, a target nudged to
#: over 1e6 x its rest length): a failure of the rule, judged with its last value
_RUNAWAY = ("rest length", "nudged target length")


def diverged(h: History) -> NDArray[np.bool_]:
    """Per trial: it stopped early because its learning ran away (:data:`_RUNAWAY`); such a
    trial is judged on a size claim with its last measured value (it failed), not left out
    as too short."""
    return np.array(
        [
            int(c) < h.steps and any(t in r for t in _RUNAWAY)
            for c, r in zip(h.completed, h.stop_reason, strict=True)
        ],
        dtype=bool,
    )


def enough_trials(trials: int) -> int:
    """Fewest trials a size claim is judged on: half of them and at least 3 (all of them
    when fewer than 3 ran)."""
    return min(trials, max(3, -(-trials // 2)))


def _subset(h: History, keep: NDArray[np.bool_]) -> History:
    idx = np.flatnonzero(keep)
    return dataclasses.replace(
        h,
        seeds=h.seeds[idx],
        completed=h.completed[idx],
        stop_reason=tuple(h.stop_reason[i] for i in idx),
        data={k: v[idx].copy() for k, v in h.data.items()},
        initial=tuple(h.initial[i] for i in idx),
        final=tuple(h.final[i] for i in idx),
        tasks=tuple(h.tasks[i] for i in idx),
    )


def check_claims(
    histories: dict[str, History],
    experiments: Sequence,
    *,
    coupling: dict[str, Sequence[str]] | None = None,
) -> list[ClaimCheck]:
    """Every statement of the paper's claims about the runs in ``histories``.

    Parameters
    ----------
    histories : {experiment name: History}
    experiments : sequence of :class:`...scenes.replication.Experiment`
    coupling : {experiment name: per-trial coupling verdicts}, optional
        From :mod:`...learning.coupling`; a claim that the task is learned needs them (without them
        such a claim is "not comparable": it cannot be told from a trivial solution).

    Returns
    -------
    list of ClaimCheck
        Experiments without a claim in the paper (``gcl_frozen``, ``exact``, ...) give none.
    """
    out = []
    coupling = coupling or {}
    for exp in experiments:
        h = histories.get(exp.name)
        if h is None:
            continue
        family = "gcl" if exp.name.startswith("gcl") else "gpc"
        verdicts = list(coupling.get(exp.name, ()))
        if len(verdicts) != h.trials:
            verdicts = []  # not measured (or not one verdict per trial)
        ran = (last_measured(h) >= MIN_STEPS) | diverged(h)
        for st in statements(exp.name):
            keep = ran if st.size else np.ones(h.trials, dtype=bool)
            judged = _subset(h, keep) if keep.sum() < h.trials else h
            m = float(st.measure(judged)) if keep.any() else float("nan")
            verdict, reason = _judge(st, h, judged, keep, m, family, verdicts)
            refs = _references(st, histories, exp.name)
            if refs:
                verdict, reason = _specific(verdict, reason, m, refs)
            out.append(
                ClaimCheck(
                    experiment=exp.name,
                    figures=exp.figures,
                    claim=st.claim,
                    metric=st.metric,
                    measured=m,
                    rule=st.rule
                    + (
                        f"; judged on the trials that completed >= {MIN_STEPS} steps or whose "
                        "learning ran away (last value), not comparable with fewer than "
                        f"{enough_trials(h.trials)} of {h.trials}"
                        if st.size
                        else ""
                    )
                    + (_specific_rule(refs) if st.specific else "")
                    + (_SETTLED_RULE if st.curve is not None else ""),
                    verdict=verdict,
                    reason=reason,
                    references=refs,
                )
            )
    return out


def _references(st, histories, name) -> tuple[tuple[str, float], ...]:
    """The statement's metric on the reference rule (then every other rule) of the same
    run; empty when the statement needs none or the reference rule did not run."""
    if not st.specific or REFERENCE_RULE not in histories:
        return ()
    order = [REFERENCE_RULE, *sorted(r for r in histories if r not in (REFERENCE_RULE, name))]
    return tuple((r, float(st.measure(histories[r]))) for r in order)


def _specific_rule(refs) -> str:
    if not refs:
        return f"; no `{REFERENCE_RULE}` run in this scene to tell a rise specific to the rule"
    return (
        f"; reproduced only if it also exceeds the `{REFERENCE_RULE}` run's value of the same "
        "metric in the same run (the rise is specific to the rule), not comparable if it "
        "does not (the exact gradient rises as much)"
    )


def _specific(verdict, reason, m, refs) -> tuple[str, str]:
    """Reproduced only when ``m`` exceeds the reference rule's value (``refs[0]``)."""
    if verdict != "reproduced":
        return verdict, reason
    ref_name, ref = refs[0]
    values = ", ".join(f"{r}: {v:.3g}" for r, v in refs)
    if not np.isfinite(ref):
        verdict, why = "not comparable", f"the {ref_name} run's value is not measured"
    elif m > ref:
        why = f"above {ref_name} ({values})"
    elif all(v > 1 for _, v in refs):
        verdict = "not comparable"
        why = f"every rule rises on this metric, the exact gradient included ({values})"
    else:
        verdict, why = (
            "not comparable",
            f"the {ref_name} run rises as much on this metric ({values})",
        )
    return verdict, "; ".join(x for x in (reason, why) if x)


_SETTLED_RULE = (
    "; a verdict other than reproduced stands only once the median curve over the trials "
    "judged has stopped falling (its fitted relative change over the last quarter of the "
    f"steps, learning.metrics.tail_change, is >= -{PLATEAU:.0%}): not comparable while it "
    "still falls (the run settles lower than the value read)"
)


def _settled(curves: NDArray, h: History, verdict: str) -> tuple[str, str]:
    """``verdict`` (not reproduced or contradicted) of a convergence claim and its reason,
    from the median over the trials of ``curves`` (trials, steps + 1) up to the last step
    all of ``h``'s trials measured: it stands when that median has stopped falling (a
    plateau, or still rising: :func:`...learning.metrics.bound`), else "not comparable"."""
    end = int(np.min(last_measured(h)))
    change = tail_change(np.median(np.asarray(curves, dtype=np.float64)[:, : end + 1], axis=0))
    kind = bound(change)
    if kind == "unknown":
        return "not comparable", "no finite change of the median curve over the last quarter"
    pct = f"{100 * change:+.2g} % over the last quarter of the steps (fitted, median curve)"
    if kind == "upper bound":
        return "not comparable", f"still falling: {pct}"
    return verdict, ("plateaued: " if kind == "plateau" else "still rising: ") + pct


def _judge(st, h, judged, keep, m, family, verdicts) -> tuple[str, str]:
    """The verdict of one statement and its reason (rules: module docstring)."""
    if h.strain_reference not in _PAPER_CONVENTIONS[family]:
        return "not comparable", (f"{_CONVENTION_REASON[family]}; this run: {h.strain_reference}")
    if st.size and keep.sum() < enough_trials(h.trials):
        done = ", ".join(str(int(c)) for c in last_measured(h))
        return "not comparable", (
            f"run too short for a size: {int(keep.sum())} of {h.trials} trials completed "
            f">= {MIN_STEPS} steps or ran away (steps measured per trial: {done})"
        )
    if not np.isfinite(m):
        return "not comparable", "no trial measured"
    n = judged.trials
    verdict = st.judge(m, n)
    note = f"{n} of {h.trials} trials judged; " if n < h.trials else ""
    if st.curve is not None and verdict in ("not reproduced", "contradicted"):
        verdict, why = _settled(st.curve(judged), judged, verdict)
        note += why + "; "
    if st.per_trial is None:
        return verdict, note.rstrip("; ")
    if not verdicts:
        return "not comparable", note + "coupling not measured"
    v = [verdicts[i] for i in np.flatnonzero(keep)]
    met = np.asarray(st.per_trial(judged), dtype=bool)
    trivial = int(sum(1 for ok, c in zip(met, v, strict=True) if ok and c == "decoupled"))
    learned = int(
        sum(
            1 for ok, c in zip(met, v, strict=True) if ok and c not in ("decoupled", "not measured")
        )
    )
    counts = (
        f"{note}{int(met.sum())} of {n} trials meet it, {trivial} of them decoupled; "
        f"{learned} meet it not decoupled (needed: {st.needed(n)})"
    )
    if verdict == "reproduced" and learned < st.needed(n):
        return "not reproduced", "met trivially: " + counts
    return verdict, counts
