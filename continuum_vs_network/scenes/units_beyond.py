"""Units of a ``beyond_paper`` scene: what the field uses beyond the paper, on tasks that are
learned (coupled verdict) or shown infeasible by the optimum.

Every rule is the package's default rule object (:func:`rule`: scale-free rates, no alpha;
GCL at ``[learning] eta``): GCL and the exact gradient by their adaptive rate, GPC and
directed aging by their scaled one. Rest lengths stay in
:data:`~continuum_vs_network.learning.ranges.REST_LENGTH_RANGE` and stiffnesses in
:data:`~continuum_vs_network.learning.ranges.STIFFNESS_RANGE` of their initial values, the
bounds of the optimum (:func:`~continuum_vs_network.learning.optimum.exact_optimum`), which
runs at most ``[learning] steps`` L-BFGS-B iterations: the same budget as a rule's steps.
Bulk learning (sources and targets frozen), strains against the initial rest lengths.

* ``beyond/compare/<task>/<rule>``: every rule of :func:`compare_rules` (``[learning]
  rules`` and ``gcl_k``; :data:`DOFS` says what each learns) on each task of ``[learning]
  compare_tasks``, trained with its rest example
  (:func:`~continuum_vs_network.learning.examples.anchored`, so prestress alone cannot meet
  it): ``paper`` (the paper's network and task, strains about 5) and ``lattice`` (Rocks et
  al.'s allosteric task, :func:`lattice_task`, on the ``n x n`` lattice, ``n = [network]
  sizes[-1]``, the largest).
* ``beyond/optimum/<task>/<dof>``: the optimum of the same anchored task for every dof a
  compared rule learns (feasible when every example's ``C_e/C_e0 <= FEASIBLE``).
* ``beyond/node/<outputs>/<rule>``: ``[learning] rules`` and ``gcl_k`` on an anchored node
  task (:func:`~continuum_vs_network.learning.node_tasks.node_task`: ``[task] n_sources``
  sources, ``n_targets`` outputs asked to move by ``N(0, target_std)`` mean rest lengths)
  on the largest lattice, for every kind of ``[task] node_outputs``. The optimum does not
  take node tasks.
* ``beyond/thermal/T<i>/<run>``: learning at temperature ``T = [learning]
  temperatures[i]`` (:mod:`~continuum_vs_network.learning.thermal`) of the stiffnesses on
  the anchored lattice task: GCL at every nudge of ``[learning] etas``
  (``gcl_eta<eta>``) and the exact gradient (``exact``). The floor is the median C/C0 of
  the last quarter of the steps.
* capacity, regression and symmetric training: :mod:`.units_beyond_examples`.

Every unit records the error after every step, the wall-clock seconds and the coupling of
the trained network (:mod:`~continuum_vs_network.learning.coupling`; per example for a task
set: the smallest source share).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .results.beyond_paper import (
    CompareResult,
    NodeResult,
    OptimumResult,
    ThermalResult,
)
from .schema import Scene
from .units import Unit, UnitContext

__all__ = [
    "DOFS",
    "FEASIBLE",
    "LATTICE_TASK",
    "compare_rules",
    "lattice_task",
    "node_rules",
    "plan_beyond_paper",
    "rule",
]

#: what each rule learns
DOFS = {
    "aging": "rest_length",
    "aging_k": "stiffness",
    "gpc": "rest_length",
    "gcl": "rest_length",
    "gcl_both": "both",
    "exact": "rest_length",
    "gcl_k": "stiffness",
}
#: a draw is feasible when its optimum brings every example to C_e/C_e0 <= FEASIBLE
FEASIBLE = 1e-3
#: Rocks et al.'s 1 -> 1 allosteric task on the lattice (as the allostery scene's):
#: source strain, response ratio asked for, distance of the target (fraction of the box)
LATTICE_TASK = {"source_strain": 0.05, "ratio": 0.3, "distance": 0.25}


def rule(name: str, scene: Scene, *, eta: float | None = None):
    """The default rule object ``name`` (see :data:`DOFS`): no rate given, so GCL and the
    exact gradient use their adaptive rate and GPC and aging their scaled one; rest
    lengths bounded by ``REST_LENGTH_RANGE`` as at the optimum; GCL at ``eta`` (default
    ``[learning] eta``)."""
    from ..learning import CoupledLearning, DirectedAging, ExactGradient, ProspectiveConfiguration
    from ..learning.ranges import REST_LENGTH_RANGE

    dof = DOFS[name]
    kw: dict[str, Any] = {"dof": dof}
    if dof != "stiffness":
        kw["rest_length_range"] = REST_LENGTH_RANGE
    if name.startswith("gcl"):
        return CoupledLearning(eta=scene.learning.eta if eta is None else eta, **kw)
    if name == "exact":
        return ExactGradient(**kw)
    if name == "gpc":
        return ProspectiveConfiguration(**kw)
    return DirectedAging(**kw)


def compare_rules(scene: Scene) -> tuple[str, ...]:
    """The rules of the comparison: ``[learning] rules`` and ``gcl_k``."""
    return (*scene.learning.rules, "gcl_k")


def node_rules(scene: Scene) -> tuple[str, ...]:
    """The rules of the node task: ``[learning] rules`` and ``gcl_k``."""
    return compare_rules(scene)


def plan_beyond_paper(scene: Scene) -> list[Unit]:
    from .units_beyond_examples import plan_examples

    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "learning") if k in d}
    L = scene.learning
    steps = L.steps
    units = []
    for task in L.compare_tasks:
        for dof in sorted({DOFS[r] for r in compare_rules(scene)}):
            units.append(
                Unit(f"beyond/optimum/{task}/{dof}", optimum_unit, {"task": task, "dof": dof},
                     depends, weight=2 * steps)
            )  # fmt: skip
        units += [
            Unit(f"beyond/compare/{task}/{r}", compare_unit, {"task": task, "rule": r},
                 depends, weight=steps)
            for r in compare_rules(scene)
        ]  # fmt: skip
    units += [
        Unit(f"beyond/node/{outputs}/{r}", node_unit, {"rule": r, "outputs": outputs},
             depends, weight=steps)
        for outputs in scene.task.node_outputs
        for r in node_rules(scene)
    ]  # fmt: skip
    for i, T in enumerate(L.temperatures):
        for run in thermal_runs(scene):
            units.append(
                Unit(f"beyond/thermal/T{i}/{run}", thermal_unit, {"temperature": T, "run": run},
                     depends, weight=steps)
            )  # fmt: skip
    return units + plan_examples(scene, depends)


def thermal_runs(scene: Scene) -> list[str]:
    """The runs at each temperature: ``gcl_eta<eta>`` per nudge, then ``exact``."""
    etas = scene.learning.etas or (scene.learning.eta,)
    return [*(f"gcl_eta{eta:g}" for eta in etas), "exact"]


def lattice(scene: Scene, n: int, salt: int = 0):
    """The ``n x n`` triangular lattice of stream ``salt`` and its generator."""
    from ..network.builders import triangular_lattice

    noise = 0.1 if scene.network.noise is None else scene.network.noise
    rng = np.random.default_rng([scene.seed, n, salt])
    return triangular_lattice(n, n, noise=noise, rng=rng if noise > 0 else None), rng


def lattice_task(scene: Scene, n: int, salt: int = 0):
    """Rocks et al.'s allosteric task (:data:`LATTICE_TASK`, ``[task] n_sources`` and
    ``n_targets``) on the lattice of :func:`lattice`: ``(net, task)``."""
    from ..learning.allostery import allostery_task

    net, rng = lattice(scene, n, salt)
    t = scene.task
    task = allostery_task(net, rng, n_sources=t.n_sources, n_targets=t.n_targets, **LATTICE_TASK)
    return net, task


def compare_task(scene: Scene, which: str):
    """``(net, task, anchored task set)`` of the comparison's task ``which``."""
    from ..learning.examples import anchored
    from ..learning.tasks import paper_task
    from ..network.builders import paper_network

    if which == "paper":
        rng = np.random.default_rng([scene.seed, 1])
        net = paper_network(rng)
        task = paper_task(net, rng)
    else:
        net, task = lattice_task(scene, scene.network.sizes[-1])
    return net, task, anchored(task, net)


def callback(ctx: UnitContext):
    return None if ctx.on_step is None else (lambda trial, step, net: ctx.on_step())


def record(h, initial, tasks) -> dict[str, Any]:
    """Error curve, seconds, and the coupling of the trained network (every example whose
    sources are on: a rest example has none to measure): the fields of
    :class:`~.results.beyond_paper.LearningRun` and ``shares``."""
    from ..learning.coupling import coupling_verdict, measure_coupling, outcome
    from ..network.equilibrium import EquilibriumError

    e = np.asarray(h.error_initial[0], dtype=float)
    done = int(h.completed[0]) == h.steps
    ratio = float(e[-1] / e[0]) if done and e[0] > 0 else float("nan")
    shares = []
    if done:
        for task in tasks:
            if not np.any(task.source_strain):
                continue
            try:
                shares.append(measure_coupling(initial, h.final[0], task).share)
            except EquilibriumError:
                shares = []
                break
    share = min(shares) if shares else float("nan")
    verdict = coupling_verdict(share) if shares else "not measured"
    return {
        "error": e,
        "seconds_trace": np.asarray(h.seconds[0], dtype=float),
        "completed": int(h.completed[0]),
        "steps": int(h.steps),
        "stop_reason": h.stop_reason[0],
        "ratio": ratio,
        "source_share": share,
        "shares": shares,
        "coupling": verdict,
        "outcome": outcome(ratio, verdict if shares else None) if done else "stopped",
        "seconds": float(np.nanmax(h.seconds[0])),
        "rule": h.settings,
    }


def optimum(net, tasks, dof: str, max_iter: int) -> OptimumResult:
    """The optimum of ``tasks`` learning ``dof`` (at most ``max_iter`` iterations): C/C0,
    worst example, feasibility, coupling, effort; ``outcome="stopped"`` when no state."""
    from ..learning.coupling import coupling_verdict, measure_coupling
    from ..learning.optimum import exact_optimum
    from ..learning.step import LearningError
    from ..network.equilibrium import EquilibriumError

    start = time.perf_counter()
    try:
        o = exact_optimum(net, tasks, dof=dof, max_iter=max_iter)
        shares = [
            measure_coupling(net, o.net, t).share for t in tasks.tasks if np.any(t.source_strain)
        ]
    except (EquilibriumError, LearningError) as err:
        return OptimumResult(outcome="stopped", stop_reason=str(err), ratio=float("nan"),
                             worst_example=float("nan"), feasible=False,
                             source_share=float("nan"), coupling="not measured",
                             seconds=time.perf_counter() - start, max_iter=max_iter)  # fmt: skip
    worst = float(np.nanmax(o.example_ratio))
    return OptimumResult(
        ratio=float(o.ratio),
        worst_example=worst,
        feasible=bool(worst <= FEASIBLE),
        source_share=float(min(shares)),
        coupling=coupling_verdict(min(shares)),
        outcome="feasible" if worst <= FEASIBLE else "infeasible",
        converged=bool(o.converged),
        message=o.message,
        iterations=int(o.iterations),
        evaluations=int(o.evaluations),
        seconds=time.perf_counter() - start,
        max_iter=max_iter,
        dof=dof,
    )


def optimum_unit(scene: Scene, params: dict, ctx: UnitContext) -> OptimumResult:
    """The optimum of a comparison task for one dof."""
    net, _, tasks = compare_task(scene, params["task"])
    return optimum(net, tasks, params["dof"], scene.learning.steps)


def compare_unit(scene: Scene, params: dict, ctx: UnitContext) -> CompareResult:
    """One rule on the paper's or the lattice's anchored task."""
    from ..learning.train import train

    net, task, tasks = compare_task(scene, params["task"])
    r = rule(params["rule"], scene)
    h = train(net, tasks, r, scene.learning.steps, progress=False, callback=callback(ctx))
    k = net.stiffness
    return CompareResult(
        **record(h, net, tasks.tasks),
        dof=r.dof,
        uniform_stiffness=bool(np.ptp(k) <= 1e-12 * np.max(k)),
        stiffness_mean=float(np.mean(k)),
        n_nodes=net.n_nodes,
        n_springs=net.n_springs,
        source_strain=[float(s) for s in task.source_strain],
        target_strain=[float(s) for s in task.target_strain],
    )


def node_unit(scene: Scene, params: dict, ctx: UnitContext) -> NodeResult:
    """One rule on an anchored node task (target node displacements)."""
    from ..learning.coupling import coupling_verdict, outcome, source_share
    from ..learning.examples import anchored
    from ..learning.node_tasks import node_task
    from ..learning.train import train
    from ..network.equilibrium import EquilibriumError, relax

    t = scene.task
    relative = params["outputs"] == "relative"
    net, rng = lattice(scene, scene.network.sizes[-1], 6 if relative else 4)
    task = node_task(
        net, rng, n_sources=t.n_sources, n_targets=t.n_targets, source_std=t.source_std,
        displacement_std=t.target_std, relative=relative,
    )  # fmt: skip
    r = rule(params["rule"], scene)
    h = train(net, anchored(task, net), r, scene.learning.steps, progress=False,
              callback=callback(ctx))  # fmt: skip
    e = np.asarray(h.error_initial[0], dtype=float)
    done = int(h.completed[0]) == h.steps
    ratio = float(e[-1] / e[0]) if done and e[0] > 0 else float("nan")
    share, verdict = float("nan"), "not measured"
    if done:
        off = task.with_source_strain(np.zeros(task.n_sources))

        def out(n, k):
            return k.outputs(relax(n, pinned=k.pinned, clamped=k.source_clamps(n)).positions)

        try:
            share = source_share(
                out(h.final[0], task) - task.reference,
                out(h.final[0], off) - task.reference,
                out(net, off) - task.reference,
                out(net, task) - task.reference,
            )
            verdict = coupling_verdict(share)
        except EquilibriumError:
            pass
    return NodeResult(
        error=e,
        seconds_trace=np.asarray(h.seconds[0], dtype=float),
        completed=int(h.completed[0]),
        steps=int(h.steps),
        stop_reason=h.stop_reason[0],
        ratio=ratio,
        source_share=share,
        coupling=verdict,
        outcome=outcome(ratio, None if verdict == "not measured" else verdict)
        if done
        else "stopped",
        seconds=float(np.nanmax(h.seconds[0])),
        rule=h.settings,
        n_targets=task.n_targets,
        outputs=params["outputs"],
        learns=r.dof,
    )


def thermal_unit(scene: Scene, params: dict, ctx: UnitContext) -> ThermalResult:
    """GCL of the stiffnesses at one nudge, or the exact gradient, at temperature ``T`` on
    the anchored lattice task."""
    from ..learning import CoupledLearning, ExactGradient
    from ..learning.train import train

    net, _, tasks = compare_task(scene, "lattice")
    run = params["run"]
    if run == "exact":
        r = ExactGradient(dof="stiffness")
    else:
        r = CoupledLearning(eta=float(run.removeprefix("gcl_eta")), dof="stiffness")
    h = train(
        net, tasks, r, scene.learning.steps, temperature=params["temperature"],
        progress=False, callback=callback(ctx),
    )  # fmt: skip
    common = record(h, net, tasks.tasks)
    e = common["error"]
    tail = e[-max(1, e.size // 4) :] / e[0]
    return ThermalResult(
        **common,
        floor=float(np.median(tail)) if int(h.completed[0]) == h.steps else float("nan"),
        temperature=params["temperature"],
        eta=None if run == "exact" else r.eta,
    )
