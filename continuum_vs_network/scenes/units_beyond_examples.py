"""Units of a ``beyond_paper`` scene on several examples at once (:mod:`.units_beyond`):
capacity, regression, symmetric training.

All three learn the stiffnesses of a network at rest with the default GCL
(:func:`~.units_beyond.rule` ``"gcl_k"``: adaptive rate, ``[learning] eta``) for
``[learning] steps`` steps, beside the optimum of the same examples (at most as many
L-BFGS-B iterations, :func:`~.units_beyond.optimum`). A network at rest that learns only
stiffnesses keeps no prestress with the sources off, so a met task is a changed response;
the coupling is measured all the same.

* ``beyond/capacity/size<n>/examples<m>/seed<s>``: ``m`` independent examples trained
  together on every lattice of ``[network] sizes``, for every ``m`` of ``[learning]
  examples`` and ``[learning] capacity_seeds`` seeds: each example its own source and
  target spring (source strain ``N(0, [task] source_std)``,
  :func:`~continuum_vs_network.learning.examples.examples_task`), its desired target strain
  the untrained response changed by ``CAPACITY["change"]`` up or down
  (:func:`~continuum_vs_network.learning.examples.gain_examples`, Rocks et al. 2019).
  Meta ``exact``: the optimum (what the network can hold).
* ``beyond/regression``: a regression task on the largest lattice
  (:func:`~continuum_vs_network.learning.examples.regression_task`: two source springs,
  one target spring, desired target strain ``M S_S`` with a random ``M`` of gain
  ``REGRESSION["gain"]``, source strains ``N(0, [task] source_std)``) on
  ``REGRESSION["n_train"]`` training examples; the summed error of ``REGRESSION["n_test"]``
  held-out examples before and after (generalisation); meta ``exact``: the optimum of the
  training set.
* ``beyond/symmetric``: Rocks et al.'s 1 -> 1 task on the largest lattice
  (:func:`~.units_beyond.lattice_task`, stream 3) and its exchange trained at once
  (:func:`~continuum_vs_network.learning.examples.symmetric`); meta ``exact``: the optimum
  of the pair.
"""

from __future__ import annotations

import itertools

import numpy as np

from .results import to_stored
from .results.beyond_paper import CapacityResult, RegressionResult, SymmetricResult
from .schema import Scene
from .units import Unit, UnitContext
from .units_beyond import callback, lattice, lattice_task, optimum, record, rule

__all__ = ["CAPACITY", "REGRESSION", "plan_examples"]

#: the capacity study: relative change of each example's response
CAPACITY = {"change": 0.5}
#: the regression task: training and held-out examples, gain of the map
REGRESSION = {"n_train": 4, "n_test": 3, "gain": 0.5}


def plan_examples(scene: Scene, depends: dict) -> list[Unit]:
    L = scene.learning
    units = [
        Unit(
            f"beyond/capacity/size{n}/examples{m}/seed{seed}",
            capacity_unit,
            {"size": n, "examples": m, "seed": seed},
            depends,
            weight=3 * L.steps * m,
        )
        for n in scene.network.sizes
        for m in L.examples
        for seed in range(L.capacity_seeds)
    ]
    units.append(Unit("beyond/regression", regression_unit, {}, depends, weight=3 * L.steps))
    units.append(Unit("beyond/symmetric", symmetric_unit, {}, depends, weight=3 * L.steps))
    return units


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


def _train_k(scene: Scene, net, tasks, ctx: UnitContext):
    from ..learning.train import train

    h = train(net, tasks, rule("gcl_k", scene), scene.learning.steps, progress=False,
              callback=callback(ctx))  # fmt: skip
    common = record(h, net, tasks.tasks)
    common["worst_example"] = _worst_example(h, tasks)
    # the optimum's record, nested in the run's
    common["exact"] = to_stored(optimum(net, tasks, "stiffness", scene.learning.steps))[1]
    return h, common


def capacity_unit(scene: Scene, params: dict, ctx: UnitContext) -> CapacityResult:
    """GCL of the stiffnesses on ``examples`` response-change examples at once on an
    ``n x n`` lattice (one seed), and their optimum."""
    from ..learning.examples import examples_task, gain_examples

    t = scene.task
    net, _ = lattice(scene, params["size"], 2)
    rng = np.random.default_rng([scene.seed, params["size"], 2, params["seed"], 1])
    drawn = examples_task(
        net, params["examples"], rng, source_std=t.source_std, target_std=t.target_std
    )
    tasks = gain_examples(drawn, net, rng, change=CAPACITY["change"])
    _, common = _train_k(scene, net, tasks, ctx)
    return CapacityResult(**common, n_nodes=net.n_nodes, n_springs=net.n_springs,
                          examples=params["examples"], seed=params["seed"],
                          **CAPACITY)  # fmt: skip


def regression_unit(scene: Scene, params: dict, ctx: UnitContext) -> RegressionResult:
    """GCL of the stiffnesses on a linear regression task; train and held-out test error."""
    from ..learning.examples import regression_task
    from ..network.equilibrium import EquilibriumError, relax

    R = REGRESSION
    net, rng = lattice(scene, scene.network.sizes[-1], 5)
    train_set, test_set, _ = regression_task(
        net, R["n_train"], R["n_test"], rng, source_std=scene.task.source_std, gain=R["gain"]
    )
    h, common = _train_k(scene, net, train_set, ctx)

    def test_error(which) -> float:
        try:
            frees = [relax(which, pinned=t.pinned, clamped=t.source_clamps(which)) for t in
                     test_set.tasks]  # fmt: skip
        except EquilibriumError:
            return float("nan")
        return test_set.error(which, [f.positions for f in frees])

    e = common["error"]
    done = int(h.completed[0]) == h.steps
    return RegressionResult(
        **common,
        train_initial=float(e[0]),
        train_final=float(e[-1]) if done else float("nan"),
        test_initial=test_error(net),
        test_final=test_error(h.final[0]) if done else float("nan"),
        **R,
    )


def symmetric_unit(scene: Scene, params: dict, ctx: UnitContext) -> SymmetricResult:
    """Rocks et al.'s task and its exchange trained at once (GCL of the stiffnesses)."""
    from ..learning.examples import symmetric
    from ..network.equilibrium import relax

    net, task = lattice_task(scene, scene.network.sizes[-1], 3)
    pair = symmetric(task)
    h, common = _train_k(scene, net, pair, ctx)
    per = []
    for which in (net, h.final[0]):
        per.append(
            [
                t.error(
                    which, relax(which, pinned=t.pinned, clamped=t.source_clamps(which)).positions
                )
                for t in pair.tasks
            ]
        )
    return SymmetricResult(**common, error_initial=per[0], error_final=per[1])
