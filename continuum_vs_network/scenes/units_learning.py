"""Units of a learning scene: training trials, then sweeps, gradient comparison and fields.

* ``train/<solver>/<rule>/noise<i>/trial<k>``: one trial (seed ``scene.seed + k``) of one
  rule with one equilibrium solver at one read-out noise level; a one-trial
  :class:`~continuum_vs_network.learning.History`, checkpointed inside the trial.
* ``sweeps/<solver>/<rule>`` (``[learning] sweeps``): source sweeps of the trained networks
  (Fig. 5 and the appendix), noise level 0 (the first listed).
* ``gradient/<rule>`` (``[learning] compare_gradient``): cosine between each rule's step and
  the exact gradient's, at every trial's initial and final network;
* ``coupling/<solver>/<rule>/noise<i>`` (every run, unless ``measure = false`` asks for the
  rules' own work only): target strains of every trained network
  with the sources on, off and over a source sweep, and of the initial network with the
  sources off (:mod:`~continuum_vs_network.learning.coupling`), so that every learning
  result states whether the sources cause the target strains;
* ``feasibility`` (paper task, ``[learning] paper_setting``): what each draw of the task
  allows (linear response, the exact optimum, self-stress, collapse;
  :func:`~continuum_vs_network.scenes.paper_setting.draw_feasibility`);
* ``fields/<solver>/<rule>`` (only with ``[export]`` or ``[report] images``): free states of
  the exported trials' initial and final networks and, with ``[export] series``, of the
  trajectory frames.

Nothing else is solved: a prospective-configuration run with ``measure = false`` (which
also skips the coupling measurement) and neither sweeps, gradient comparison, export nor
images solves no free state at all.

This module plans the units; they are built in :mod:`.units_learning_build` (networks,
tasks, rules), :mod:`.units_learning_train` (trials) and :mod:`.units_learning_measure`
(coupling, sweeps, gradient, fields).
"""

from __future__ import annotations

from typing import Any

from .schema import Scene
from .units import Unit
from .units_learning_build import aging_rules as aging_rules
from .units_learning_build import build_rules, experiments, rule_steps
from .units_learning_build import builders as builders
from .units_learning_build import task_example as task_example
from .units_learning_measure import (
    coupling_unit,
    feasibility_unit,
    fields_unit,
    gradient_unit,
    sweeps_unit,
)
from .units_learning_train import frames_file, train_unit

__all__ = [
    "build_rules",
    "experiments",
    "frames_file",
    "group_key",
    "plan_learning",
    "run_names",
]


def group_key(solver: str, rule: str, noise_index: int) -> str:
    """Key of a learning run: ``"<solver>/<rule>/noise<i>"``."""
    return f"{solver}/{rule}/noise{noise_index}"


def run_names(scene: Scene) -> tuple[str, ...]:
    """The scene's learning runs: its rules, a GCL rule once per nudge when ``etas`` lists
    nudges (``<rule>_eta<value>``)."""
    L = scene.learning
    out = []
    for rule in L.rules:
        if rule.startswith("gcl") and L.etas:
            out += [f"{rule}_eta{eta:g}" for eta in L.etas]
        else:
            out.append(rule)
    return tuple(out)


def _solvers(scene: Scene) -> tuple[str, ...]:
    return scene.solver.methods if scene.solver is not None else ("newton",)


def _training_depends(scene: Scene) -> dict[str, Any]:
    d = scene.to_dict()
    learning = {
        k: v
        for k, v in d["learning"].items()
        if k
        not in (
            "rules",
            "trials",
            "noise",
            "sweeps",
            "sweep_span",
            "sweep_points",
            "compare_gradient",
        )
    }
    solver = d.get("solver", {})
    return {
        "seed": scene.seed,
        "network": d["network"],
        "task": d["task"],
        "learning": learning,
        "paper_iterations": solver.get("paper_iterations", 300),
    }


def plan_learning(scene: Scene) -> list[Unit]:
    """Training trials (phase 0) and the units that read their histories (phase 1)."""
    L = scene.learning
    assert L is not None
    dep = _training_depends(scene)
    export = scene.export
    series_trials = set(export.trials) if export is not None and export.series else set()
    units: list[Unit] = []
    for solver in _solvers(scene):
        for rule in run_names(scene):
            for i, noise in enumerate(L.noise):
                for k in range(L.trials):
                    series = export.every if (k in series_trials and i == 0) else 0
                    units.append(
                        Unit(
                            key=f"train/{group_key(solver, rule, i)}/trial{k}",
                            func=train_unit,
                            params={
                                "solver": solver,
                                "rule": rule,
                                "noise": noise,
                                "seed": scene.seed + k,
                                "series_every": series,
                            },
                            depends=dep,
                            weight=rule_steps(scene, rule),
                        )
                    )
    first = {"sweep_span": L.sweep_span, "sweep_points": L.sweep_points}
    for solver in _solvers(scene):
        for rule in run_names(scene):
            for i, noise in enumerate(L.noise if L.measure else ()):
                units.append(
                    Unit(
                        key=f"coupling/{group_key(solver, rule, i)}",
                        func=coupling_unit,
                        params={"group": group_key(solver, rule, i)},
                        depends={**dep, "trials": L.trials, "noise": noise},
                        phase=1,
                    )
                )
            deps = {**dep, "trials": L.trials, "noise": L.noise[0]}
            if L.sweeps:
                units.append(
                    Unit(
                        key=f"sweeps/{solver}/{rule}",
                        func=sweeps_unit,
                        params={"group": group_key(solver, rule, 0), **first},
                        depends=deps,
                        phase=1,
                    )
                )
            if scene.export is not None or scene.report.images:
                trials = list(export.trials) if export is not None else [0]
                units.append(
                    Unit(
                        key=f"fields/{solver}/{rule}",
                        func=fields_unit,
                        params={
                            "group": group_key(solver, rule, 0),
                            "trials": trials,
                            "series": bool(series_trials),
                        },
                        depends=deps,
                        phase=1,
                    )
                )
    if scene.task.kind == "paper" and L.paper_setting:
        units.append(
            Unit(
                key="feasibility",
                func=feasibility_unit,
                params={"group": group_key(_solvers(scene)[0], L.rules[0], 0)},
                depends={**dep, "trials": L.trials},
                phase=1,
            )
        )
    if L.compare_gradient:
        solver = "newton" if "newton" in _solvers(scene) else _solvers(scene)[0]
        for rule in run_names(scene):
            if rule == "exact":
                continue
            units.append(
                Unit(
                    key=f"gradient/{rule}",
                    func=gradient_unit,
                    params={"group": group_key(solver, rule, 0), "rule": rule},
                    depends={**dep, "trials": L.trials, "noise": L.noise[0]},
                    phase=1,
                )
            )
    return units
