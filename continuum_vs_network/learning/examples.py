"""Several examples at once: a dataset of input/output pairs trained together.

A :class:`TaskSet` is a tuple of :class:`~.tasks.AllosteryTask` examples on one network
(the same pins), or of :class:`~.node_tasks.NodeTask` examples (outputs are node
displacements; one kind per set): different source strains, each with its own desired target strains
(a multifunctional network), or different source and target springs (symmetric training,
:func:`symmetric`). Every rule takes a task set where it takes a task: one learning step
is the **sum of the per-example updates** (each example's own free / nudged / clamped
states), masked and floored once; so the exact gradient descends the summed error
``C = sum_e C_e`` and a local rule descends the sum of its per-example objectives.
:func:`~.train.train` records the summed error and the examples' target values side by
side (``n_targets`` is the total over the examples).

Bulk learning freezes the union of every example's sources and targets.

:func:`anchored` adds the **rest example** to a task (spring or node task): the sources
clamped at zero strain, the targets (outputs) asked to stay where the untrained network puts
them with the sources off. A
network that meets both examples must *transmit* the source strains; prestressing the
targets into place (a decoupled, trivial solution, :mod:`.coupling`) fails the rest
example, so the task cannot be met trivially: prestress alone that splits the difference
between the two examples leaves summed C/C0 = 0.5 (an offset ``d`` minimises
``|a - d|^2 + |d|^2`` at ``d = a / 2``), the signature of a network that learned nothing.

:func:`examples_task` draws a dataset for a capacity study (Rocks et al. 2019: how many
independent responses a network of a given size can hold).

:func:`gain_examples` turns a spring-task set into Rocks et al.'s kind of task: each
example's desired target strains are its untrained response changed by a given fraction,
up or down at random (a network that meets it changes how the sources drive the targets; a
stiffness-learning network at rest cannot meet it by prestress).

:func:`regression_task` draws a regression dataset on fixed source and target springs: the
desired target strains are a fixed linear map of the source strains, ``S_T = M S_S``; train
on the training examples, measure the summed error of held-out test examples
(generalisation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..network.constraints import default_pins
from ..network.model import SpringNetwork
from .node_tasks import NodeTask
from .states import Solver, Tracker
from .tasks import (
    AllosteryTask,
    StrainReference,
    _candidates,
    _positive_normal,
    check_strain_reference,
)

__all__ = [
    "TaskSet",
    "anchored",
    "examples_task",
    "gain_examples",
    "regression_task",
    "symmetric",
]


@dataclass(frozen=True, eq=False)
class TaskSet:
    """Examples trained together (see the module).

    Attributes
    ----------
    tasks : tuple of AllosteryTask, or tuple of NodeTask
        The examples, at least one, all of one kind; all with the same ``pinned`` mask.
    """

    tasks: tuple[AllosteryTask, ...] | tuple[NodeTask, ...]

    def __post_init__(self) -> None:
        tasks = tuple(self.tasks) if isinstance(self.tasks, list | tuple) else None
        kinds = {type(t) for t in tasks or ()}
        if not tasks or not (kinds == {AllosteryTask} or kinds == {NodeTask}):
            raise check.ArgumentError(
                "tasks", self.tasks, "a non-empty sequence of AllosteryTask or of NodeTask examples"
            )
        pins = tasks[0].pinned
        for e, t in enumerate(tasks[1:], 1):
            if t.pinned.shape != pins.shape or not np.array_equal(t.pinned, pins):
                raise ValueError(f"example {e} has other pins than example 0: share one mask")
        object.__setattr__(self, "tasks", tasks)

    # -- what rules and train read --------------------------------------------------------
    @property
    def n_examples(self) -> int:
        return len(self.tasks)

    @property
    def pinned(self) -> NDArray[np.bool_]:
        return self.tasks[0].pinned

    @property
    def node_outputs(self) -> bool:
        """True when the examples are node tasks (outputs are node displacements)."""
        return isinstance(self.tasks[0], NodeTask)

    @property
    def sources(self) -> NDArray[np.int64]:
        """Every example's sources, concatenated (the springs bulk learning freezes)."""
        return np.concatenate([t.sources for t in self.tasks])

    @property
    def targets(self) -> NDArray[np.int64]:
        """Every example's targets, concatenated (the order of recorded target values)."""
        return np.concatenate([t.targets for t in self.tasks])

    @property
    def target_strain(self) -> NDArray[np.float64]:
        return np.concatenate([t.target_strain for t in self.tasks])

    @property
    def n_targets(self) -> int:
        return int(sum(t.n_targets for t in self.tasks))

    @property
    def n_sources(self) -> int:
        return int(sum(t.n_sources for t in self.tasks))

    def check(self, net: SpringNetwork) -> None:
        """Raise ``ValueError`` if an example does not fit ``net``."""
        for t in self.tasks:
            t.check(net)

    def desired_lengths(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> NDArray:
        """Every example's desired target lengths (node examples: desired outputs),
        concatenated."""
        if self.node_outputs:
            return np.concatenate([t.desired for t in self.tasks])
        return np.concatenate([t.desired_lengths(net, strain_reference) for t in self.tasks])

    def error(
        self,
        net: SpringNetwork,
        positions: list[ArrayLike],
        strain_reference: StrainReference = "initial",
    ) -> float:
        """Summed error ``sum_e C_e`` at the examples' free-state ``positions`` (a list)."""
        if len(positions) != self.n_examples:
            raise ValueError(f"need one free state per example ({self.n_examples})")
        return float(sum(t.error(net, x, strain_reference) for t, x in zip(self.tasks, positions)))

    # -- files ------------------------------------------------------------------------------
    def to_arrays(self) -> dict[str, NDArray]:
        from .history import _task_arrays

        out: dict[str, NDArray] = {"n_examples": np.array(self.n_examples)}
        for e, t in enumerate(self.tasks):
            out.update({f"e{e}/{k.split('/', 1)[1]}": v for k, v in _task_arrays("x", t).items()})
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> TaskSet:
        from .history import _task_from

        n = int(arrays["n_examples"])
        tasks = []
        for e in range(n):
            head = f"e{e}/"
            part = {"x/" + k[len(head) :]: v for k, v in arrays.items() if k.startswith(head)}
            tasks.append(_task_from(part, "x"))
        return cls(tuple(tasks))


def symmetric(task: AllosteryTask) -> TaskSet:
    """Symmetric training: ``task`` and its exchange (sources become targets, at the
    strains the targets should reach, and targets become sources), trained together."""
    if not isinstance(task, AllosteryTask):
        raise check.ArgumentError("task", task, "an AllosteryTask")
    swapped = AllosteryTask(
        sources=task.targets,
        source_strain=task.target_strain,
        targets=task.sources,
        target_strain=task.source_strain,
        source_rest_length=task.target_rest_length,
        target_rest_length=task.source_rest_length,
        pinned=task.pinned,
    )
    return TaskSet((task, swapped))


def anchored(
    task: AllosteryTask | NodeTask,
    net: SpringNetwork,
    *,
    strain_reference: StrainReference = "initial",
    solver: Solver | None = None,
) -> TaskSet:
    """``task`` and its rest example, trained together (see the module).

    The rest example has ``task``'s sources clamped at zero strain and its targets desired
    at the strains they show in ``net`` (the untrained network) in that state: zero change
    when the sources are off. Strains in ``strain_reference`` (the two conventions agree
    when ``net`` is the network ``task`` was made on). For a :class:`~.node_tasks.NodeTask`
    the rest example's outputs are desired at their values in that state.

    Raises
    ------
    EquilibriumError
        The state of ``net`` with the sources off cannot be found.
    """
    if not isinstance(task, AllosteryTask | NodeTask):
        raise check.ArgumentError("task", task, "an AllosteryTask or a NodeTask")
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    check_strain_reference(strain_reference)
    task.check(net)
    off = task.with_source_strain(np.zeros(task.n_sources))
    eq = Tracker(solver or Solver()).solve(
        net, task.pinned, off.source_clamps(net, strain_reference), None, key="free"
    )
    if isinstance(task, NodeTask):
        import dataclasses

        rest_node = dataclasses.replace(off, displacement=off.outputs(eq.positions) - off.reference)
        return TaskSet((task, rest_node))
    rest = off.with_target_strain(
        off.target_strains(net, net.lengths(eq.positions, task.targets), strain_reference)
    )
    return TaskSet((task, rest))


def examples_task(
    net: SpringNetwork,
    n_examples: int,
    rng: np.random.Generator,
    *,
    n_sources: int = 1,
    n_targets: int = 1,
    source_std: float = 0.1,
    target_std: float = 0.1,
    shared_springs: bool = False,
    candidates: ArrayLike | None = None,
) -> TaskSet:
    """``n_examples`` independent input/output pairs on one network.

    Each example clamps ``n_sources`` source springs at strains drawn from
    ``N(0, source_std)`` and asks for ``n_targets`` target strains drawn from
    ``N(0, target_std)``, independently of every other example. With ``shared_springs``
    every example uses the same source and target springs (only the strains differ: in
    linear response a network then holds at most ``n_sources + 1`` examples exactly,
    whatever its size); otherwise (the default) each example has its own springs, distinct
    from every other example's (independent responses: the capacity grows with the
    network, Rocks et al. 2019). Springs are drawn as in :func:`~.tasks.stern_task`.
    """
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_examples = check.integer("n_examples", n_examples, low=1)
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    target_std = check.real("target_std", target_std, low=0, low_open=True)
    shared_springs = check.boolean("shared_springs", shared_springs)
    pool = _candidates(net, candidates)
    per = n_sources + n_targets
    need = per if shared_springs else per * n_examples
    if pool.size < need:
        raise ValueError(
            f"need {need} candidate springs for {n_examples} examples, the network offers "
            f"{pool.size}"
        )
    chosen = rng.choice(pool, size=need, replace=False)
    pins = default_pins(net, avoid=chosen)
    tasks = []
    for e in range(n_examples):
        springs = chosen[:per] if shared_springs else chosen[e * per : (e + 1) * per]
        tasks.append(
            AllosteryTask.create(
                net,
                springs[:n_sources],
                _positive_normal(rng, 0.0, source_std, n_sources),
                springs[n_sources:],
                _positive_normal(rng, 0.0, target_std, n_targets),
                pinned=pins,
            )
        )
    return TaskSet(tuple(tasks))


def regression_task(
    net: SpringNetwork,
    n_train: int,
    n_test: int,
    rng: np.random.Generator,
    *,
    n_sources: int = 2,
    n_targets: int = 1,
    source_std: float = 0.1,
    gain: float = 1.0,
    candidates: ArrayLike | None = None,
) -> tuple[TaskSet, TaskSet, NDArray]:
    """A linear regression task on one network: ``(train, test, M)``.

    One set of ``n_sources`` source and ``n_targets`` target springs (drawn as in
    :func:`~.tasks.stern_task`); a random map ``M`` of shape ``(n_targets, n_sources)``
    with entries ``N(0, gain^2 / n_sources)``; ``n_train + n_test`` examples with source
    strains ``N(0, source_std)`` (each > -1) and desired target strains ``M S_S``. The
    first ``n_train`` are the training set, the rest the held-out test set (same pins).
    """
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_train = check.integer("n_train", n_train, low=1)
    n_test = check.integer("n_test", n_test, low=1)
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    gain = check.real("gain", gain, low=0, low_open=True)
    pool = _candidates(net, candidates)
    per = n_sources + n_targets
    if pool.size < per:
        raise ValueError(f"need {per} candidate springs, the network offers {pool.size}")
    springs = rng.choice(pool, size=per, replace=False)
    pins = default_pins(net, avoid=springs)
    gain_map = rng.normal(0.0, gain / np.sqrt(n_sources), (n_targets, n_sources))
    tasks = []
    for _ in range(n_train + n_test):
        s = _positive_normal(rng, 0.0, source_std, n_sources)
        t = gain_map @ s
        if np.any(t <= -1.0):
            raise ValueError("a desired target strain is <= -1: lower gain or source_std")
        tasks.append(
            AllosteryTask.create(net, springs[:n_sources], s, springs[n_sources:], t, pinned=pins)
        )
    return TaskSet(tuple(tasks[:n_train])), TaskSet(tuple(tasks[n_train:])), gain_map


def gain_examples(
    tasks: TaskSet,
    net: SpringNetwork,
    rng: np.random.Generator,
    *,
    change: float = 0.5,
    solver: Solver | None = None,
) -> TaskSet:
    """``tasks`` with every example's desired target strains set to ``S^0 (1 +- change)``.

    ``S^0`` are the target strains of ``net`` (the untrained network) with the example's
    sources clamped, in the ``"initial"`` convention; the sign is drawn per target
    (Rocks et al. 2019: each response's ratio of target to source strain to be changed by
    a relative amount).

    Raises
    ------
    EquilibriumError
        A free state of ``net`` cannot be found.
    """
    if not isinstance(tasks, TaskSet) or tasks.node_outputs:
        raise check.ArgumentError("tasks", tasks, "a TaskSet of AllosteryTask examples")
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    change = check.real("change", change, low=0, low_open=True)
    tracker = Tracker(solver or Solver())
    out = []
    for task in tasks.tasks:
        task.check(net)
        eq = tracker.solve(net, task.pinned, task.source_clamps(net), None, key="free")
        s0 = task.target_strains(net, net.lengths(eq.positions, task.targets))
        sign = rng.choice([-1.0, 1.0], size=s0.size)
        out.append(task.with_target_strain(s0 * (1.0 + sign * change)))
    return TaskSet(tuple(out))
