"""Results of the allostery units: a rule trained on one draw, the draw's bounded optimum,
and a feasibility map."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["AllosteryOptimumResult", "AllosteryTrainResult", "FeasibilityMapResult"]


@dataclass(frozen=True)
class AllosteryTrainResult:
    """One rule trained on one draw (an ``allostery/train`` unit).

    Traces over the learning steps (steps + 1,): ``error`` (C, against the initial
    network's clamped state), ``seconds_trace`` and ``rule_seconds_trace`` (wall-clock, in
    all and without the coupling measurements; stored as ``seconds`` and
    ``rule_seconds``). ``sweep`` (scales, n_targets): the trained network's target
    response to scaled source strains (NaN where not measured). The draw and its result:
    ``positions`` (n_nodes, 2), ``springs`` (n_springs, 2), stiffness ``k0`` -> ``k`` and
    rest lengths ``L0`` -> ``L`` (n_springs,), ``sources`` and ``targets`` (spring
    indices). ``ratio``: final C/C0 (NaN for a run stopped early); ``floor``: median C/C0
    over the last quarter of the steps; ``steps_to``: first step with C/C0 <= each level
    (keyed by the level, None: never); ``share``, ``coupling``, ``outcome``: the coupling
    measurement and the verdict; ``contrast``: max / min k / k0 over the learning
    springs; ``seconds`` and ``rule_seconds``: the largest of the traces;
    ``task_ratio``: target over source strain.
    """

    error: np.ndarray
    seconds_trace: np.ndarray = field(metadata={"stored": "seconds"})
    rule_seconds_trace: np.ndarray = field(metadata={"stored": "rule_seconds"})
    sweep: np.ndarray
    positions: np.ndarray
    springs: np.ndarray
    k0: np.ndarray
    k: np.ndarray
    L0: np.ndarray
    L: np.ndarray
    sources: np.ndarray
    targets: np.ndarray
    ratio: float
    floor: float
    noise: float
    eta: float
    steps: int
    completed: int
    stop_reason: str
    steps_to: dict[str, Any]
    share: float
    coupling: str
    outcome: str
    contrast: float
    seconds: float
    rule_seconds: float
    n_nodes: int
    n_springs: int
    task_ratio: float


@dataclass(frozen=True)
class AllosteryOptimumResult:
    """The bounded optimum of one draw and the untrained network's response (an
    ``allostery/opt`` unit): ``sweep0`` (scales, n_targets) the untrained target response
    to scaled source strains, ``desired`` and ``rest`` (n_targets,) the targets' desired
    and unforced strains, ``example_ratio`` the optimum's C/C0 per training example;
    ``ratio`` its C/C0, ``feasible`` whether that reaches FEASIBLE, its evaluations,
    iterations, convergence, seconds, stiffness contrast and source share."""

    sweep0: np.ndarray
    desired: np.ndarray
    rest: np.ndarray
    example_ratio: np.ndarray
    ratio: float
    feasible: bool
    evaluations: int
    iterations: int
    converged: bool
    seconds: float
    contrast: float
    share: float
    n_nodes: int
    n_springs: int


@dataclass(frozen=True)
class FeasibilityMapResult:
    """The optimum at every source-target distance and target/source ratio of one map draw
    (an ``allostery/map`` unit), each (n_distances, n_ratios): its C/C0 ``ratio``,
    stiffness ``contrast``, the measured ``distance`` and whether it is ``feasible``;
    ``dof``: what the optimum changes."""

    ratio: np.ndarray
    contrast: np.ndarray
    distance: np.ndarray
    feasible: np.ndarray
    dof: str
    n_nodes: int
