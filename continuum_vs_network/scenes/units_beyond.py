"""Units of a ``beyond_paper`` scene: what the field uses beyond the paper.

* ``beyond/compare/<task>/<rule>``: every rule of ``[learning] rules`` (directed aging of
  rest lengths ``aging`` and of stiffnesses ``aging_k``, ``gpc``, ``gcl``, ``exact``, and
  ``gcl_both``: GCL of rest lengths and stiffnesses together, ``dof="both"``) on
  the paper's task (the paper's network, one source and one target at strains about 5)
  and on Stern's task (an ``n x n`` lattice, ``n = [network] sizes[0]``, with ``[task]``'s
  sources and targets). The same rule objects on both tasks: bulk learning (sources and
  targets frozen), strains against the initial rest lengths, rest-length floor 1e-3, rates
  ``[learning] alpha_*`` (the exact gradient descends the length cost at ``alpha_gcl``,
  as :func:`~continuum_vs_network.learning.stern.stern_rules` matches step sizes) for unit
  stiffness: the k-weighted rules run at ``alpha / mean(k)`` (:func:`per_stiffness`; the
  paper's network has ``mean(k)`` about 25, the lattices 1).
* ``beyond/capacity/size<n>/examples<m>/seed<s>``: GCL of the stiffnesses on ``m``
  independent examples trained together on every lattice of ``[network] sizes``, for every
  ``m`` of ``[learning] examples`` and ``[learning] capacity_seeds`` seeds: each example
  its own source and target spring (source strain ``N(0, [task] source_std)``,
  :func:`~continuum_vs_network.learning.examples.examples_task`), its desired target strain
  the untrained response changed by ``CAPACITY["change"]`` up or down
  (:func:`~continuum_vs_network.learning.examples.gain_examples`, Rocks et al. 2019),
  :func:`gcl_k`. A network at rest that learns only stiffnesses cannot meet
  a task by prestress, so a met task is a changed response (the coupling is measured all
  the same). The same unit finds the examples' exact-gradient optimum (meta ``exact``:
  L-BFGS-B on the exact gradient, same floor, at most ``EXACT["max_iter"]`` iterations,
  :mod:`~continuum_vs_network.learning.optimum`): what the network can hold.
* ``beyond/node/<outputs>/<rule>``: every rule, and ``gcl_k`` (:func:`gcl_k`: GCL of the
  stiffnesses at rate ``GCL_K["alpha"] / mean(k)``, floor ``GCL_K["floor"] mean(k)``), on a
  node task
  (:func:`~continuum_vs_network.learning.node_tasks.node_task`: ``[task] n_sources``
  sources, ``n_targets`` outputs asked to move by ``N(0, target_std)`` mean rest lengths)
  on the first lattice, for every kind of ``[task] node_outputs``: ``absolute`` (node
  coordinates) or ``relative`` (a node's coordinate relative to another node's); its
  coupling is the source share of the output displacements (sources on and off, as
  :mod:`~continuum_vs_network.learning.coupling`).
* ``beyond/thermal/T<i>/<run>``: learning at temperature ``T = [learning]
  temperatures[i]`` (every state the rule reads is one harmonic Boltzmann draw,
  :mod:`~continuum_vs_network.learning.thermal`) on Stern's task of the first lattice: GCL
  at every nudge of ``[learning] etas`` (``gcl_eta<eta>``; default ``eta``) and the exact
  gradient (``exact``, no nudge). The error floor is the median C/C0 of the last quarter
  of the steps.
* ``beyond/regression``: a regression task on the first lattice
  (:func:`~continuum_vs_network.learning.examples.regression_task`: two source springs,
  one target spring, desired target strain ``M S_S`` with a random ``M``, gain 0.5, source
  strains ``N(0, [task] source_std)``): GCL of the stiffnesses (the slope of a linear
  response is set by k; rest lengths change it only through prestress) at ``alpha = 100 /
  mean(k)``, ``[learning] eta``, stiffness floor ``0.3 mean(k)``, on 4 training examples;
  the summed error of 3 held-out examples is measured before and after (generalisation).
* ``beyond/symmetric``: GCL on one source and one target trained in both directions at
  once (:func:`~continuum_vs_network.learning.examples.symmetric`) on the first lattice.

Every unit records the error after every step, the wall-clock seconds and the coupling of
the trained network (:mod:`~continuum_vs_network.learning.coupling`; per example for a
task set: the smallest source share).
"""

from __future__ import annotations

import dataclasses
import itertools
from typing import Any

import numpy as np

from .schema import Scene
from .units import Unit, UnitContext

__all__ = ["beyond_rules", "gcl_k", "node_rules", "plan_beyond_paper"]

TASKS = ("paper", "stern")


def _table(scene: Scene) -> dict[str, Any]:
    from ..learning.stern import stern_rules
    from .units_learning import aging_rules

    L = scene.learning
    base = stern_rules(alpha=L.alpha_gcl, eta=L.eta, alpha_gpc=L.alpha_gpc)
    table = {"gcl": base["GCL"], "gpc": base["GPC"], "exact": base["exact"]}
    table["gcl_both"] = dataclasses.replace(base["GCL"], dof="both", min_stiffness=1e-3)
    table.update(aging_rules(L.alpha_aging, base["GPC"]))
    return table


def beyond_rules(scene: Scene) -> dict[str, Any]:
    """The rule objects of the comparison, by scene name (same objects on both tasks;
    ``gcl`` also trains the capacity and symmetric runs)."""
    table = _table(scene)
    return {name: table[name] for name in scene.learning.rules}


def node_rules(scene: Scene) -> tuple[str, ...]:
    """The rules of the node task: ``[learning] rules`` and ``gcl_k``."""
    return (*scene.learning.rules, "gcl_k")


def plan_beyond_paper(scene: Scene) -> list[Unit]:
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "learning") if k in d}
    steps = scene.learning.steps
    units = [
        Unit(
            key=f"beyond/compare/{task}/{rule}",
            func=compare_unit,
            params={"task": task, "rule": rule},
            depends=depends,
            weight=steps,
        )
        for task in TASKS
        for rule in scene.learning.rules
    ]
    units += [
        Unit(
            key=f"beyond/node/{outputs}/{rule}",
            func=node_unit,
            params={"rule": rule, "outputs": outputs},
            depends=depends,
            weight=steps,
        )
        for outputs in scene.task.node_outputs
        for rule in node_rules(scene)
    ]
    L = scene.learning
    for i, T in enumerate(L.temperatures):
        for run in [*(f"gcl_eta{eta:g}" for eta in _etas(scene)), "exact"]:
            units.append(
                Unit(
                    key=f"beyond/thermal/T{i}/{run}",
                    func=thermal_unit,
                    params={"temperature": T, "run": run},
                    depends=depends,
                    weight=steps,
                )
            )
    for n in scene.network.sizes:
        for m in scene.learning.examples:
            for seed in range(L.capacity_seeds):
                units.append(
                    Unit(
                        key=f"beyond/capacity/size{n}/examples{m}/seed{seed}",
                        func=capacity_unit,
                        params={"size": n, "examples": m, "seed": seed},
                        depends=depends,
                        weight=(steps + 2 * EXACT["max_iter"]) * m,
                    )
                )
    units.append(
        Unit(key="beyond/regression", func=regression_unit, params={}, depends=depends,
             weight=steps)
    )  # fmt: skip
    units.append(
        Unit(key="beyond/symmetric", func=symmetric_unit, params={}, depends=depends, weight=steps)
    )
    return units


def _lattice(scene: Scene, n: int, salt: int = 0):
    from ..network.builders import triangular_lattice

    noise = 0.1 if scene.network.noise is None else scene.network.noise
    rng = np.random.default_rng([scene.seed, n, salt])
    return triangular_lattice(n, n, noise=noise, rng=rng if noise > 0 else None), rng


def _callback(ctx: UnitContext):
    return None if ctx.on_step is None else (lambda trial, step, net: ctx.on_step())


def _record(h, initial, tasks) -> tuple[dict, dict]:
    """Error curve, seconds, and the coupling of the trained network (every example)."""
    from ..learning.coupling import coupling_verdict, measure_coupling, outcome
    from ..network.equilibrium import EquilibriumError

    e = np.asarray(h.error_initial[0], dtype=float)
    arrays = {"error": e, "seconds": np.asarray(h.seconds[0], dtype=float)}
    done = int(h.completed[0]) == h.steps
    ratio = float(e[-1] / e[0]) if done and e[0] > 0 else float("nan")
    shares = []
    if done:
        for task in tasks:
            try:
                shares.append(measure_coupling(initial, h.final[0], task).share)
            except EquilibriumError:
                shares = []
                break
    share = min(shares) if shares else float("nan")
    verdict = coupling_verdict(share) if shares else "not measured"
    meta = {
        "completed": int(h.completed[0]),
        "stop_reason": h.stop_reason[0],
        "ratio": ratio,
        "source_share": share,
        "shares": shares,
        "coupling": verdict,
        "outcome": outcome(ratio, verdict if shares else None) if done else "stopped",
        "seconds": float(np.nanmax(h.seconds[0])),
        "rule": h.settings,
    }
    return arrays, meta


def compare_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One rule on the paper's or Stern's task."""
    from ..learning.tasks import paper_task, stern_task
    from ..learning.train import train
    from ..network.builders import paper_network

    if params["task"] == "paper":
        rng = np.random.default_rng([scene.seed, 1])
        net = paper_network(rng)
        task = paper_task(net, rng)
    else:
        t = scene.task
        net, rng = _lattice(scene, scene.network.sizes[0])
        task = stern_task(
            net, t.n_sources, t.n_targets, rng, source_std=t.source_std, target_std=t.target_std
        )
    rule = per_stiffness(beyond_rules(scene)[params["rule"]], net)
    h = train(net, task, rule, scene.learning.steps, progress=False, callback=_callback(ctx))
    arrays, meta = _record(h, net, [task])
    k = net.stiffness
    meta.update(
        uniform_stiffness=bool(np.ptp(k) <= 1e-12 * np.max(k)),
        stiffness_mean=float(np.mean(k)),
        n_nodes=net.n_nodes,
        n_springs=net.n_springs,
    )
    return arrays, meta


def per_stiffness(rule, net):
    """Rates are given for unit stiffness: a k-weighted rule (GCL, GPC, the exact gradient
    of the length cost, whose steps scale with k) runs at ``alpha / mean(k)``; directed
    aging, whose rate carries no k, at ``alpha``."""
    from ..learning.aging import DirectedAging

    if isinstance(rule, DirectedAging):
        return rule
    return dataclasses.replace(rule, alpha=rule.alpha / float(np.mean(net.stiffness)))


#: GCL of the stiffnesses (``gcl_k`` of the node tasks, the capacity study): rate for unit
#: stiffness (its updates scale with squared strains, ~ 1e-3 here) and floor (of mean k)
GCL_K = {"alpha": 1e5, "floor": 0.1}

#: the capacity study: relative change of each example's response
CAPACITY = {"change": 0.5}


def gcl_k(scene: Scene, net):
    """GCL of the stiffnesses at ``GCL_K`` (the scene's nudge)."""
    k = float(np.mean(net.stiffness))
    return dataclasses.replace(
        _table(scene)["gcl"], alpha=GCL_K["alpha"] / k, dof="stiffness",
        min_stiffness=GCL_K["floor"] * k,
    )  # fmt: skip


def capacity_unit(scene: Scene, params: dict, ctx: UnitContext):
    """GCL of the stiffnesses on ``examples`` response-change examples at once on an
    ``n x n`` lattice (one seed)."""
    from ..learning.examples import examples_task, gain_examples
    from ..learning.train import train

    t = scene.task
    net, _ = _lattice(scene, params["size"], 2)
    rng = np.random.default_rng([scene.seed, params["size"], 2, params["seed"], 1])
    drawn = examples_task(
        net, params["examples"], rng, source_std=t.source_std, target_std=t.target_std
    )
    tasks = gain_examples(drawn, net, rng, change=CAPACITY["change"])
    rule = gcl_k(scene, net)
    h = train(net, tasks, rule, scene.learning.steps, progress=False, callback=_callback(ctx))
    arrays, meta = _record(h, net, tasks.tasks)
    meta.update(
        n_nodes=net.n_nodes, n_springs=net.n_springs, examples=params["examples"],
        seed=params["seed"], worst_example=_worst_example(h, tasks), **CAPACITY, **GCL_K,
        exact=_exact_capacity(net, tasks),
    )  # fmt: skip
    return arrays, meta


def _exact_capacity(net, tasks) -> dict:
    """The same examples at the quasi-static optimum of their summed error (L-BFGS-B on the
    exact gradient, :mod:`~continuum_vs_network.learning.optimum`), same stiffness floor:
    what the network can hold, whatever a rule reaches in its budget."""
    import time

    from ..learning.coupling import coupling_verdict, measure_coupling, outcome
    from ..learning.optimum import exact_optimum
    from ..learning.rules import LearningError
    from ..network.equilibrium import EquilibriumError

    start = time.perf_counter()
    k = float(np.mean(net.stiffness))
    try:
        o = exact_optimum(net, tasks, floor=GCL_K["floor"] * k, max_iter=EXACT["max_iter"])
        shares = [measure_coupling(net, o.net, task).share for task in tasks.tasks]
    except (EquilibriumError, LearningError) as err:
        return {"outcome": "stopped", "stop_reason": str(err), "ratio": float("nan"),
                "worst_example": float("nan"), "source_share": float("nan"),
                "seconds": time.perf_counter() - start}  # fmt: skip
    ratio = o.error / o.error_initial
    verdict = coupling_verdict(min(shares))
    return {
        "ratio": float(ratio),
        "worst_example": float(np.nanmax(o.example_ratio)),
        "source_share": float(min(shares)),
        "coupling": verdict,
        "outcome": outcome(ratio, verdict),
        "converged": o.converged,
        "message": o.message,
        "evaluations": o.evaluations,
        "seconds": time.perf_counter() - start,
        **EXACT,
    }


#: the exact-gradient reference of the capacity study: most L-BFGS-B iterations
EXACT = {"max_iter": 150}


def _worst_example(h, tasks) -> float:
    """Largest final-over-initial error of one example of a task set (NaN if stopped)."""
    if int(h.completed[0]) != h.steps:
        return float("nan")
    miss = (np.asarray(h.target_strain[0], dtype=float) - tasks.target_strain) ** 2
    edges = np.cumsum([0, *(t.n_targets for t in tasks.tasks)])
    ratios = [
        miss[-1, a:b].sum() / miss[0, a:b].sum()
        for a, b in itertools.pairwise(edges)
        if miss[0, a:b].sum() > 0
    ]
    return float(max(ratios)) if ratios else float("nan")


#: the regression task of ``beyond/regression``: training and held-out examples, GCL rate
#: of the stiffnesses (for unit stiffness) and the stiffness floor (in units of mean k)
REGRESSION = {"n_train": 4, "n_test": 3, "gain": 0.5, "alpha": 100.0, "floor": 0.3}


def regression_unit(scene: Scene, params: dict, ctx: UnitContext):
    """GCL of the stiffnesses on a linear regression task; train and held-out test error."""
    from ..learning.examples import regression_task
    from ..learning.train import train
    from ..network.equilibrium import EquilibriumError, relax

    R = REGRESSION
    net, rng = _lattice(scene, scene.network.sizes[0], 5)
    train_set, test_set, _ = regression_task(
        net, R["n_train"], R["n_test"], rng, source_std=scene.task.source_std, gain=R["gain"]
    )
    k = float(np.mean(net.stiffness))
    rule = dataclasses.replace(
        _table(scene)["gcl"], alpha=R["alpha"] / k, dof="stiffness", min_stiffness=R["floor"] * k
    )
    h = train(net, train_set, rule, scene.learning.steps, progress=False, callback=_callback(ctx))

    def test_error(which) -> float:
        try:
            frees = [relax(which, pinned=t.pinned, clamped=t.source_clamps(which)) for t in
                     test_set.tasks]  # fmt: skip
        except EquilibriumError:
            return float("nan")
        return test_set.error(which, [f.positions for f in frees])

    arrays, meta = _record(h, net, train_set.tasks)
    e = arrays["error"]
    done = int(h.completed[0]) == h.steps
    meta.update(
        train_initial=float(e[0]),
        train_final=float(e[-1]) if done else float("nan"),
        test_initial=test_error(net),
        test_final=test_error(h.final[0]) if done else float("nan"),
        **R,
    )
    return arrays, meta


def symmetric_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One source and one target, trained in both directions at once (GCL)."""
    from ..learning.examples import symmetric
    from ..learning.tasks import stern_task
    from ..learning.train import train

    t = scene.task
    net, rng = _lattice(scene, scene.network.sizes[0], 3)
    pair = symmetric(stern_task(net, 1, 1, rng, source_std=t.source_std, target_std=t.target_std))
    h = train(
        net, pair, _table(scene)["gcl"], scene.learning.steps, progress=False,
        callback=_callback(ctx),
    )  # fmt: skip
    arrays, meta = _record(h, net, pair.tasks)
    from ..network.equilibrium import relax

    per = []
    for which in (net, h.final[0]):
        per.append(
            [
                task.error(
                    which,
                    relax(which, pinned=task.pinned, clamped=task.source_clamps(which)).positions,
                )
                for task in pair.tasks
            ]
        )
    meta.update(error_initial=per[0], error_final=per[1])
    return arrays, meta


def node_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One rule on a node task (target node displacements)."""
    from ..learning.coupling import coupling_verdict, outcome, source_share
    from ..learning.node_tasks import node_task
    from ..learning.train import train
    from ..network.equilibrium import EquilibriumError, relax

    t = scene.task
    relative = params["outputs"] == "relative"
    net, rng = _lattice(scene, scene.network.sizes[0], 6 if relative else 4)
    task = node_task(
        net, rng, n_sources=t.n_sources, n_targets=t.n_targets, source_std=t.source_std,
        displacement_std=t.target_std, relative=relative,
    )  # fmt: skip
    if params["rule"] == "gcl_k":
        rule = gcl_k(scene, net)
    else:
        rule = per_stiffness(beyond_rules(scene)[params["rule"]], net)
    h = train(net, task, rule, scene.learning.steps, progress=False, callback=_callback(ctx))
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
    meta = {
        "completed": int(h.completed[0]),
        "stop_reason": h.stop_reason[0],
        "ratio": ratio,
        "source_share": share,
        "coupling": verdict,
        "outcome": outcome(ratio, None if verdict == "not measured" else verdict)
        if done
        else "stopped",
        "seconds": float(np.nanmax(h.seconds[0])),
        "rule": h.settings,
        "n_targets": task.n_targets,
        "outputs": params["outputs"],
        "learns": rule.dof,
    }
    return {"error": e, "seconds": np.asarray(h.seconds[0], dtype=float)}, meta


def _etas(scene: Scene) -> tuple[float, ...]:
    return scene.learning.etas or (scene.learning.eta,)


def thermal_unit(scene: Scene, params: dict, ctx: UnitContext):
    """GCL at one nudge, or the exact gradient, at temperature ``T`` on Stern's task."""
    from ..learning.tasks import stern_task
    from ..learning.train import train

    t = scene.task
    net, rng = _lattice(scene, scene.network.sizes[0])
    task = stern_task(
        net, t.n_sources, t.n_targets, rng, source_std=t.source_std, target_std=t.target_std
    )
    run = params["run"]
    rule = _table(scene)["exact" if run == "exact" else "gcl"]
    if run != "exact":
        rule = dataclasses.replace(rule, eta=float(run.removeprefix("gcl_eta")))
    rule = per_stiffness(rule, net)
    h = train(
        net, task, rule, scene.learning.steps, temperature=params["temperature"],
        progress=False, callback=_callback(ctx),
    )  # fmt: skip
    arrays, meta = _record(h, net, [task])
    e = arrays["error"]
    tail = e[-max(1, e.size // 4) :] / e[0]
    meta.update(
        floor=float(np.median(tail)) if int(h.completed[0]) == h.steps else float("nan"),
        temperature=params["temperature"],
        eta=None if run == "exact" else rule.eta,
    )
    return arrays, meta
