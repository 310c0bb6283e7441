"""Building a learning scene's trials: networks, tasks and learning rules.

:func:`builders` gives the ``(network, task)`` callables of a trial generator,
:func:`build_rules` the learning rules a scene names (keys are
:func:`~.units_learning.run_names`), :func:`experiments` the paper's experiments.
Used by the learning units (:mod:`.units_learning_train`, :mod:`.units_learning_measure`),
the beyond-paper units and the sweep's cost estimate.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .schema import Scene

__all__ = ["aging_rules", "build_rules", "builders", "experiments", "task_example"]

_STERN_KIND = {"triangular": "lattice", "diluted": "diluted", "jammed": "jammed"}


def _paper_network(rng: np.random.Generator, *, noise: float):
    from ..network.builders import paper_network

    return paper_network(rng, noise=noise)


def _stern_network(rng: np.random.Generator, *, n_nodes: int, kind: str, noise: float):
    from .stern import stern_network

    return stern_network(n_nodes, rng, kind=kind, noise=noise)


def _stern_task(
    net,
    rng: np.random.Generator,
    *,
    n_sources: int,
    n_targets: int,
    source_std: float,
    target_std: float,
    anchored: bool = False,
    strain_reference: str = "initial",
):
    from ..learning.examples import anchored as with_rest
    from ..learning.tasks import stern_task

    task = stern_task(
        net,
        n_sources,
        n_targets,
        rng,
        candidates=np.ones(net.n_springs, bool),
        source_std=source_std,
        target_std=target_std,
    )
    return with_rest(task, net, strain_reference=strain_reference) if anchored else task


def task_example(task):
    """The task example of a trained task: ``task`` itself, or a task set's first example
    (an anchored task's rest example is not the task; coupling and fields read the task)."""
    from ..learning.examples import TaskSet

    return task.tasks[0] if isinstance(task, TaskSet) else task


def builders(scene: Scene):
    """``(network, task)`` callables of a trial generator, as :func:`~.learning.train` takes."""
    from ..learning.tasks import paper_task

    net, task = scene.network, scene.task
    noise = 0.1 if net.noise is None else net.noise
    if net.builder == "paper":
        return functools.partial(_paper_network, noise=noise), paper_task
    return (
        functools.partial(
            _stern_network, n_nodes=net.n_nodes, kind=_STERN_KIND[net.builder], noise=noise
        ),
        functools.partial(
            _stern_task,
            n_sources=task.n_sources,
            n_targets=task.n_targets,
            source_std=task.source_std,
            target_std=task.target_std,
            anchored=task.anchored,
            strain_reference=scene.learning.strain_reference,
        ),
    )


def _solver(scene: Scene, name: str):
    from .replication import exact_solver, paper_solver

    if name == "newton":
        return exact_solver()
    iterations = scene.solver.paper_iterations if scene.solver is not None else 300
    return paper_solver(iterations)


def build_rules(scene: Scene, solver: str = "newton") -> dict[str, Any]:
    """The learning rules the scene names, with the equilibrium solver ``solver``.

    The paper task uses :func:`~continuum_vs_network.scenes.replication.paper_experiments`
    (every spring learns in ``gcl``, ``gpc`` and ``exact``, as in the paper); Stern-scale
    tasks :func:`~continuum_vs_network.scenes.stern.stern_rules`: ``gcl``, ``gpc`` and
    ``exact`` learn in the bulk (sources and targets frozen; the exact gradient uses
    ``alpha_gcl`` on the length cost, as ``stern_rules`` matches the step sizes),
    ``gcl_all`` and ``gpc_all`` let every spring learn, ``aging`` and ``aging_k`` are
    directed aging of rest lengths and stiffnesses (in the bulk, :func:`aging_rules`),
    ``gcl_both`` GCL of rest lengths and stiffnesses together (``dof="both"``).
    Keys are :func:`run_names`.
    """
    import dataclasses

    L = scene.learning
    eq_solver = _solver(scene, solver)
    if scene.task.kind == "paper":
        table = {e.name: e.rule for e in _paper_experiments(scene, eq_solver)}
    else:
        from .stern import stern_rules

        kw = {"alpha": L.alpha_gcl, "eta": L.eta, "alpha_gpc": L.alpha_gpc, "solver": eq_solver}
        bulk = stern_rules(**kw)
        every = stern_rules(**kw, learn_sources=True, learn_targets=True)
        table = {
            "gcl": bulk["GCL"],
            "gpc": bulk["GPC"],
            "exact": bulk["exact"],
            "gcl_all": every["GCL"],
            "gpc_all": every["GPC"],
        }
        table.update(aging_rules(L.alpha_aging, bulk["GPC"]))
        table["gcl_both"] = dataclasses.replace(bulk["GCL"], dof="both", min_stiffness=1e-3)
    out = {}
    for rule in L.rules:
        if rule.startswith("gcl") and L.etas:
            for eta in L.etas:
                out[f"{rule}_eta{eta:g}"] = dataclasses.replace(table[rule], eta=eta)
        else:
            out[rule] = table[rule]
    return out


def aging_rules(alpha: float, like) -> dict[str, Any]:
    """Directed aging of rest lengths (``aging``) and stiffnesses (``aging_k``) with the
    options of the rule ``like`` (bulk learning, strain reference, solver, floor)."""
    from ..learning.aging import DirectedAging

    common = {
        "learn_sources": like.learn_sources,
        "learn_targets": like.learn_targets,
        "strain_reference": like.strain_reference,
        "solver": like.solver,
    }
    floor = like.min_rest_length
    return {
        "aging": DirectedAging(alpha, min_rest_length=floor, **common),
        "aging_k": DirectedAging(alpha, dof="stiffness", min_stiffness=1e-3, **common),
    }


def experiments(scene: Scene, solver: str = "newton"):
    """The paper's :class:`~.replication.Experiment` objects the scene names."""
    exps = _paper_experiments(scene, _solver(scene, solver))
    return tuple(e for e in exps if e.name in scene.learning.rules)


def _paper_experiments(scene: Scene, eq_solver):
    """The paper's runs: the author's notebooks' setting with ``[learning] paper_setting``
    (:func:`~continuum_vs_network.scenes.paper_setting.paper_setting_experiments`), else
    the package's (:func:`~continuum_vs_network.scenes.replication.paper_experiments`)."""
    L = scene.learning
    common = {
        "solver": eq_solver,
        "alpha_gcl": L.alpha_gcl,
        "eta": L.eta,
        "alpha_gpc": L.alpha_gpc,
        "alpha_exact": L.alpha_exact,
        "floor": L.floor,
    }
    if L.paper_setting:
        from .paper_setting import paper_setting_experiments

        return paper_setting_experiments(**common)
    from .replication import paper_experiments

    return paper_experiments(strain_reference=L.strain_reference, **common)


def rule_steps(scene: Scene, rule: str) -> int:
    """Learning steps of one run: ``[learning] steps_gpc`` for a GPC run of the paper task
    when set, else ``steps``."""
    L = scene.learning
    if scene.task.kind == "paper" and L.steps_gpc and rule.startswith("gpc"):
        return L.steps_gpc
    return L.steps
