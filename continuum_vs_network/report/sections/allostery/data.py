"""The numbers of the ``allostery`` section, read from the scene's stored units (it runs
nothing): the verdict of every draw and rule, and the tallies and medians of the summary.

A draw whose bounded optimum does not reach C/C0 <= FEASIBLE is *infeasible*: its verdict
is ``"infeasible (optimum C/C0 = x)"`` whatever the rule did, and it is counted apart, never
in a success rate. Medians are over the feasible draws.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ....scenes.results import from_stored
from ....scenes.results.allostery import (
    AllosteryOptimumResult,
    AllosteryTrainResult,
    FeasibilityMapResult,
)
from ....scenes.units_allostery import LEVELS, Run, runs
from ...document import quiet

__all__ = [
    "LEARNED",
    "RULE_NAMES",
    "Group",
    "Tally",
    "feasibility_map",
    "groups",
    "nan_median",
    "optimum_summary",
    "tally",
    "verdict",
]

#: The outcome (:func:`~continuum_vs_network.learning.coupling.outcome`) that counts.
LEARNED = "learned (coupled)"

#: How the report names each rule.
RULE_NAMES = {"gcl": "GCL", "exact": "exact gradient", "gpc": "GPC", "aging": "directed aging"}


def verdict(run: AllosteryTrainResult, opt: AllosteryOptimumResult | None) -> str:
    """The verdict of one rule on one draw: ``"infeasible (optimum C/C0 = x)"`` when the
    optimum (None: not computed) shows the draw infeasible, else the rule's outcome
    (coupling vocabulary)."""
    if opt is not None and not opt.feasible:
        return f"infeasible (optimum C/C0 = {opt.ratio:.2g})"
    return str(run.outcome)


@dataclass(frozen=True)
class Group:
    """The results of one (size, task, dof): ``opt[i]`` the optimum of draw ``i``,
    ``train[rule][i]`` the rule's run on draw ``i``."""

    n: int
    task: str
    dof: str
    opt: list[AllosteryOptimumResult]
    train: dict[str, list[AllosteryTrainResult]]
    runs: dict[str, Run] = field(default_factory=dict)

    @property
    def key(self) -> str:
        return f"n{self.n}/{self.task}/{self.dof}"

    @property
    def feasible(self) -> list[bool]:
        """Per draw: the optimum reaches C/C0 <= FEASIBLE (every draw when the scene computes
        no optimum: then nothing is known to be infeasible)."""
        if not self.opt:
            return [True] * len(next(iter(self.train.values())))
        return [bool(o.feasible) for o in self.opt]


def groups(scene, units) -> list[Group]:
    """Every (size, task, dof) of the scene, in plan order; ``train`` keyed by run name."""
    a = scene.allostery
    out = []
    for n in a.n_nodes:
        for task in a.tasks:
            for dof in a.dofs:
                base = f"allostery/%s/n{n}/{task}/{dof}/draw"
                opt = (
                    [
                        from_stored(units[f"{base % 'opt'}{i}"], AllosteryOptimumResult)
                        for i in range(a.draws)
                    ]
                    if a.optimum
                    else []
                )
                rs = {r.name: r for r in runs(scene)}
                train = {
                    r: [
                        from_stored(units[f"{base % 'train'}{i}/{r}"], AllosteryTrainResult)
                        for i in range(a.draws)
                    ]
                    for r in rs
                }
                out.append(Group(n, task, dof, opt, train, rs))
    return out


@dataclass(frozen=True)
class Tally:
    """One rule of one group: counts over the draws and medians over the feasible ones.

    ``steps_to[level]``: median first step with C/C0 <= level over the feasible draws that
    reached it (``reached[level]`` of them); NaN when none did.
    """

    rule: str
    draws: int
    feasible: int
    learned: int
    verdicts: list[str]
    ratio: float
    steps_to: dict[str, float]
    reached: dict[str, int]
    seconds: float
    contrast: float

    @property
    def share(self) -> float:
        """Learned (coupled) over feasible draws; NaN without feasible draws."""
        return self.learned / self.feasible if self.feasible else float("nan")


def nan_median(values) -> float:
    """Median of ``values`` with None and NaN left out; NaN when none is left."""
    v = np.asarray([np.nan if x is None else x for x in values], dtype=float)
    return float(quiet(np.nanmedian, v)) if v.size else float("nan")


def tally(group: Group, rule: str) -> Tally:
    """The :class:`Tally` of ``rule`` in ``group``."""
    units = group.train[rule]
    ok = group.feasible
    opts = group.opt or [None] * len(units)
    verdicts = [verdict(u, o) for u, o in zip(units, opts, strict=True)]
    good = [u for u, f in zip(units, ok, strict=True) if f]
    steps_to, reached = {}, {}
    for level in LEVELS:
        hits = [u.steps_to[f"{level:g}"] for u in good]
        hits = [h for h in hits if h is not None]
        steps_to[f"{level:g}"] = nan_median(hits)
        reached[f"{level:g}"] = len(hits)
    return Tally(
        rule=rule,
        draws=len(units),
        feasible=sum(ok),
        learned=sum(v == LEARNED for v in verdicts),
        verdicts=verdicts,
        ratio=nan_median([u.ratio for u in good]),
        steps_to=steps_to,
        reached=reached,
        seconds=nan_median([u.rule_seconds for u in good]),
        contrast=nan_median([u.contrast for u in good]),
    )


def optimum_summary(group: Group) -> dict[str, float]:
    """Medians of the optimum over the draws: C/C0, evaluations, seconds, contrast; counts."""
    o = group.opt
    return {
        "feasible": sum(group.feasible),
        "draws": len(o),
        "ratio": nan_median([m.ratio for m in o]),
        "evaluations": nan_median([m.evaluations for m in o]),
        "seconds": nan_median([m.seconds for m in o]),
        "contrast": nan_median([m.contrast for m in o]),
    }


def feasibility_map(scene, units, n: int, task: str) -> dict[str, np.ndarray] | None:
    """Share of map draws the optimum solves, ``(n_distances, n_ratios)``, with the
    measured distances (median over draws) and the number of draws; None without a map."""
    a = scene.allostery
    keys = [f"allostery/map/n{n}/{task}/draw{j}" for j in range(a.map_draws)]
    if not keys or not a.map_distances or not a.map_ratios:
        return None
    maps = [from_stored(units[k], FeasibilityMapResult) for k in keys]
    feasible = np.stack([np.asarray(m.feasible, dtype=float) for m in maps])
    dist = np.stack([np.asarray(m.distance, dtype=float) for m in maps])
    ratio = np.stack([np.asarray(m.ratio, dtype=float) for m in maps])
    return {
        "share": feasible.mean(axis=0),
        "distance": quiet(np.nanmedian, dist, axis=0),
        "ratio": quiet(np.nanmedian, ratio, axis=0),
        "draws": np.array(len(keys)),
    }
