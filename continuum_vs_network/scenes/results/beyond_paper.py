"""Results of the ``beyond_paper`` units (:mod:`..units_beyond`,
:mod:`..units_beyond_examples`): one default rule's run on a task, or the optimum of a task.

Every run records what :class:`LearningRun` holds (the error curve, its wall-clock seconds,
the stop, the final C/C0 and the coupling of the trained network); each unit adds its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import KEEP_NONE

__all__ = [
    "CLASSES",
    "CapacityResult",
    "CompareResult",
    "ExamplesRun",
    "LearningRun",
    "NodeResult",
    "OptimumResult",
    "RegressionResult",
    "SymmetricResult",
    "ThermalResult",
]


@dataclass(frozen=True)
class OptimumResult:
    """The optimum of a task set for one dof (a ``beyond/optimum/<task>/<dof>`` unit, and
    the ``exact`` record of a run on several examples).

    ``ratio``: its C/C0; ``worst_example``: the largest C_e/C_e0 of one example;
    ``feasible``: whether that is <= ``FEASIBLE``; ``source_share`` (smallest over the
    examples with sources on) and ``coupling``: the coupling of the optimal network;
    ``outcome``: ``"feasible"``, ``"infeasible"`` or ``"stopped"`` (no state found:
    ``stop_reason`` says why, and the effort fields below are absent); ``seconds``:
    wall-clock; ``max_iter``: the L-BFGS-B budget. Of a found optimum: ``converged``,
    the optimizer's ``message``, ``iterations``, ``evaluations`` and the ``dof`` learned.
    """

    outcome: str
    ratio: float
    worst_example: float
    feasible: bool
    source_share: float
    coupling: str
    seconds: float
    max_iter: int
    stop_reason: str | None = None
    converged: bool | None = None
    message: str | None = None
    iterations: int | None = None
    evaluations: int | None = None
    dof: str | None = None


@dataclass(frozen=True)
class LearningRun:
    """What every learning unit of the scene records (not a unit's class by itself).

    ``error`` (steps + 1,): C after every step (step 0: the initial network);
    ``seconds_trace`` (steps + 1,): cumulative wall-clock seconds (stored as ``seconds``);
    ``completed`` of ``steps`` steps, ``stop_reason`` ("" when none); ``ratio``: final
    C/C0 (NaN for a run stopped early); ``source_share`` and ``coupling``: the trained
    network's coupling (NaN and ``"not measured"`` when not measured); ``outcome``: the
    coupling vocabulary's verdict (``"stopped"`` for a run stopped early); ``seconds``:
    the largest of the trace; ``rule``: the rule's settings (``History.settings``).
    """

    error: np.ndarray
    seconds_trace: np.ndarray = field(metadata={"stored": "seconds"})
    completed: int
    steps: int
    stop_reason: str
    ratio: float
    source_share: float
    coupling: str
    outcome: str
    seconds: float
    rule: dict[str, Any]


@dataclass(frozen=True)
class CompareResult(LearningRun):
    """One default rule on the paper's or the lattice's anchored task (a
    ``beyond/compare/<task>/<rule>`` unit). ``shares``: the source share of every example
    with sources on (``source_share`` is the smallest); ``dof`` learned; whether the
    initial stiffness is uniform and its mean; the network's size; the task's
    ``source_strain`` and desired ``target_strain`` (one per source and target spring)."""

    shares: list[float]
    dof: str
    uniform_stiffness: bool
    stiffness_mean: float
    n_nodes: int
    n_springs: int
    source_strain: list[float]
    target_strain: list[float]


@dataclass(frozen=True)
class NodeResult(LearningRun):
    """One default rule on an anchored node task (a ``beyond/node/<outputs>/<rule>`` unit):
    ``n_targets`` output coordinates, ``outputs`` ``"absolute"`` or ``"relative"``, the dof
    the rule ``learns``; ``source_share``: of the output displacements."""

    n_targets: int
    outputs: str
    learns: str


@dataclass(frozen=True)
class ThermalResult(LearningRun):
    """GCL at one nudge or the exact gradient, stiffnesses, at one temperature (a
    ``beyond/thermal/T<i>/<run>`` unit): ``shares`` as :class:`CompareResult`'s; ``floor``:
    median C/C0 over the last quarter of the steps (NaN for a run stopped early);
    ``temperature`` (k_B T, energy units); GCL's nudge ``eta`` (None, stored as null: the
    exact gradient)."""

    shares: list[float]
    floor: float
    temperature: float
    eta: float | None = field(default=None, metadata=KEEP_NONE)


@dataclass(frozen=True)
class ExamplesRun(LearningRun):
    """GCL of the stiffnesses on several examples at once, beside their optimum (what the
    capacity, regression and symmetric units share): ``shares`` as
    :class:`CompareResult`'s; ``worst_example``: the largest final C_e/C_e0 of one example
    (NaN for a run stopped early); ``exact``: the optimum's record (:attr:`optimum`)."""

    shares: list[float]
    worst_example: float
    exact: dict[str, Any]

    @property
    def optimum(self) -> OptimumResult:
        """``exact`` as an :class:`OptimumResult`."""
        return OptimumResult(**self.exact)


@dataclass(frozen=True)
class CapacityResult(ExamplesRun):
    """``examples`` response-change examples on one lattice, one ``seed`` (a
    ``beyond/capacity/size<n>/examples<m>/seed<s>`` unit): the network's size and the
    relative ``change`` of each example's response."""

    n_nodes: int
    n_springs: int
    examples: int
    seed: int
    change: float


@dataclass(frozen=True)
class RegressionResult(ExamplesRun):
    """A linear regression task (the ``beyond/regression`` unit): the summed error of the
    ``n_train`` training and ``n_test`` held-out examples before (``*_initial``) and after
    (``*_final``, NaN for a run stopped early; the held-out one NaN when a state is not
    found); ``gain`` of the random map."""

    train_initial: float
    train_final: float
    test_initial: float
    test_final: float
    n_train: int
    n_test: int
    gain: float


@dataclass(frozen=True)
class SymmetricResult(ExamplesRun):
    """A task and its exchange trained at once (the ``beyond/symmetric`` unit): each
    direction's error, forward then backward, before (``error_initial``) and after
    (``error_final``)."""

    error_initial: list[float]
    error_final: list[float]


#: the result class of a unit, by the start of its key (:func:`~.read_result`)
CLASSES = {
    "beyond/compare/": CompareResult,
    "beyond/optimum/": OptimumResult,
    "beyond/node/": NodeResult,
    "beyond/thermal/": ThermalResult,
    "beyond/capacity/": CapacityResult,
    "beyond/regression": RegressionResult,
    "beyond/symmetric": SymmetricResult,
}
