"""The paper's claims about its learning runs, checked against histories by stated rules.

Every claim of :func:`~.replication.paper_experiments` is split into the statements it
makes (C falls by orders of magnitude; E^C descends; ...). :func:`check_claims` measures
each on the histories of a run and gives a verdict by the rule printed next to it:

``reproduced``
    the measured value satisfies the statement;
``contradicted``
    it shows the opposite (a quantity said to fall rises; none of the trials converges);
``not reproduced``
    neither (the right direction but not the stated size), or a task success that the
    coupling measurement shows to be trivial (:mod:`.coupling`: the targets keep their
    strain with the sources off), which is not the success the paper claims;
``not comparable``
    the run differs from the paper's in what the claim depends on (coupled learning in the
    other strain convention is another algorithm; a size reached after the paper's 300
    steps judged on a run of fewer than :data:`MIN_STEPS`), or nothing was measured.

Claims of a *direction* (rises, descends, lowers) are judged at any run length; claims of
a *size* reached (orders of magnitude, C = 0, ~50 %, 33 %, converges to 0) need at least
:data:`MIN_STEPS` steps, a third of the paper's 300.

The metric: the paper's task error (Figs. 4, 6, 10) is Eq. 26 with strains against the
learning rest length (Eq. 24 as printed), i.e. ``error_current``; claims about ``C`` are
judged on it in every scene. The paper's coupled learning clamps in that convention too;
its prospective configuration keeps its rods at fixed lengths (Sec. 7.2), which is the
``"initial"`` clamp convention, while its error uses the learning ``L``: prospective
configuration claims are comparable in both conventions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .history import History
from .metrics import final_values, length_error, normalised, rest_length_error

__all__ = ["MIN_STEPS", "VERDICTS", "ClaimCheck", "check_claims", "majority"]

VERDICTS = ("reproduced", "not reproduced", "contradicted", "not comparable")
#: fewest learning steps on which a claim about a size reached is judged (the paper: 300)
MIN_STEPS = 100

#: the strain conventions in which the paper's run of each rule family is reproduced
_PAPER_CONVENTIONS = {"gcl": ("current",), "gpc": ("current", "initial")}
_C_METRIC = "C/C0 with strains against the learning L (Eq. 26 as printed; error_current)"


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
    """

    experiment: str
    figures: str
    claim: str
    metric: str
    measured: float
    rule: str
    verdict: str
    reason: str = ""


def majority(verdicts: Sequence[str]) -> str | None:
    """The most common coupling verdict of the trials (ties go to the less coupled one);
    None when no trial was measured."""
    order = ("decoupled", "partially coupled", "coupled")
    counts = {v: list(verdicts).count(v) for v in order}
    if not any(counts.values()):
        return None
    return max(order, key=lambda v: (counts[v], -order.index(v)))


def _ratio_final(values: NDArray, h: History, *, updates: bool = False) -> NDArray:
    completed = np.minimum(h.completed, h.steps - 1) if updates else h.completed
    return final_values(normalised(values), completed)


def _median(x: NDArray) -> float:
    ok = x[np.isfinite(x)]
    return float(np.median(ok)) if ok.size else float("nan")


def _mean(x: NDArray) -> float:
    ok = x[np.isfinite(x)]
    return float(np.mean(ok)) if ok.size else float("nan")


@dataclass(frozen=True)
class _Statement:
    claim: str
    metric: str
    measure: Callable[[History], float]
    rule: str
    judge: Callable[[float], str]
    needs_coupling: bool = False  # a claim that the task is learned
    size: bool = True  # a size reached (False: a direction)


def _c_ratio(h: History) -> NDArray:
    return _ratio_final(h.error_current, h)


def _converged_fraction(h: History) -> float:
    r = _c_ratio(h)
    return float(np.sum(r <= 1e-6)) if np.isfinite(r).any() else float("nan")


def _moved(h: History) -> NDArray:
    d = np.stack(
        [np.abs(h.target_strain[i, :, 0] - h.tasks[i].target_strain[0]) for i in range(h.trials)]
    )
    return 1.0 - _ratio_final(d, h)


def _gcl_statements(trials: int) -> list[_Statement]:
    return [
        _Statement(
            "GCL lowers C by orders of magnitude",
            f"median over trials of the final {_C_METRIC}",
            lambda h: _median(_c_ratio(h)),
            "reproduced if <= 1e-2 and the trained networks are not decoupled; "
            "contradicted if >= 1",
            lambda m: "reproduced" if m <= 1e-2 else "contradicted" if m >= 1 else "not reproduced",
            needs_coupling=True,
        ),
        _Statement(
            "all trials but one converge to C = 0",
            "trials whose final C/C0 (learning L) is <= 1e-6",
            _converged_fraction,
            f"reproduced if >= {trials - 1} of {trials} and not decoupled; contradicted if 0",
            lambda m: (
                "reproduced" if m >= trials - 1 else "contradicted" if m == 0 else "not reproduced"
            ),
            needs_coupling=True,
        ),
    ]


def _fall(claim: str, metric: str, measure) -> _Statement:
    return _Statement(
        claim,
        metric,
        measure,
        "reproduced if < 1 (it fell); contradicted if > 1",
        lambda m: "reproduced" if m < 1 else "contradicted" if m > 1 else "not reproduced",
        size=False,
    )


def _gpc_statements() -> list[_Statement]:
    return [
        _Statement(
            "C rises on average (large spread)",
            f"mean over trials of the final {_C_METRIC}",
            lambda h: _mean(_c_ratio(h)),
            "reproduced if > 1; contradicted if < 1",
            lambda m: "reproduced" if m > 1 else "contradicted" if m < 1 else "not reproduced",
            size=False,
        ),
        _fall(
            "the clamped energy E^C descends",
            "median over trials of the final E^C / E^C_0",
            lambda h: _median(_ratio_final(h.energy_clamped, h, updates=True)),
        ),
        _fall(
            "|dE^C/dL| descends",
            "median over trials of the final |dE^C/dL| / |dE^C/dL|_0",
            lambda h: _median(_ratio_final(h.energy_gradient_clamped, h, updates=True)),
        ),
        _Statement(
            "the target length error falls by ~50 %",
            "median over trials of the final sum |r_T - l_T| / initial (Fig. 8)",
            lambda h: _median(_ratio_final(length_error(h), h)),
            "reproduced if in [0.25, 0.75]; contradicted if >= 1",
            lambda m: (
                "reproduced"
                if 0.25 <= m <= 0.75
                else "contradicted"
                if m >= 1
                else "not reproduced"
            ),
        ),
        _Statement(
            "the target rest-length error converges to 0",
            "median over trials of the final sum |L_T - l_T| / initial (Fig. 9)",
            lambda h: _median(_ratio_final(rest_length_error(h), h)),
            "reproduced if <= 1e-2; contradicted if >= 1",
            lambda m: "reproduced" if m <= 1e-2 else "contradicted" if m >= 1 else "not reproduced",
        ),
    ]


def _gpc_frozen_statements() -> list[_Statement]:
    return [
        _fall(
            "GPC with the target frozen lowers C",
            f"median over trials of the final {_C_METRIC}",
            lambda h: _median(_c_ratio(h)),
        ),
        _Statement(
            "the target strain moves 33 % of the way to the desired strain",
            "median over trials of 1 - |S - S_T| / |S_0 - S_T| (target strain in the run's "
            "convention)",
            lambda h: _median(_moved(h)),
            "reproduced if in [0.2, 0.5] (33 % within a factor 1.5); contradicted if <= 0",
            lambda m: (
                "reproduced" if 0.2 <= m <= 0.5 else "contradicted" if m <= 0 else "not reproduced"
            ),
        ),
    ]


def _statements(name: str, trials: int) -> list[_Statement]:
    if name in ("gcl", "gcl_floor"):
        return _gcl_statements(trials)
    if name == "gpc":
        return _gpc_statements()
    if name == "gpc_frozen":
        return _gpc_frozen_statements()
    return []


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
    experiments : sequence of :class:`~.replication.Experiment`
    coupling : {experiment name: per-trial coupling verdicts}, optional
        From :mod:`.coupling`; a claim that the task is learned needs them (without them
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
        comparable = h.strain_reference in _PAPER_CONVENTIONS[family]
        verdicts = coupling.get(exp.name, ())
        major = majority(verdicts)
        for st in _statements(exp.name, h.trials):
            m = float(st.measure(h))
            reason = ""
            if not comparable:
                verdict = "not comparable"
                reason = (
                    f"the paper's {family.upper()} clamps in the other strain convention "
                    f"(this run: {h.strain_reference})"
                )
            elif not np.isfinite(m):
                verdict, reason = "not comparable", "no trial measured"
            elif st.size and h.steps < MIN_STEPS:
                verdict = "not comparable"
                reason = f"a size after 300 steps; this run has {h.steps} < {MIN_STEPS}"
            else:
                verdict = st.judge(m)
                if st.needs_coupling:
                    if major is None:
                        verdict, reason = "not comparable", "coupling not measured"
                    elif verdict == "reproduced" and major == "decoupled":
                        verdict = "not reproduced"
                        reason = (
                            "met trivially: with the sources off the targets keep their "
                            f"strain (coupling: {major} in "
                            f"{list(verdicts).count(major)}/{len(verdicts)} trials)"
                        )
                    else:
                        reason = f"coupling: {major} (most common verdict over trials)"
            out.append(
                ClaimCheck(
                    experiment=exp.name,
                    figures=exp.figures,
                    claim=st.claim,
                    metric=st.metric,
                    measured=m,
                    rule=st.rule,
                    verdict=verdict,
                    reason=reason,
                )
            )
    return out
