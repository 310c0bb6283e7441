"""Learning in spring networks: allosteric tasks, local learning rules, training, metrics.

Light to import (numpy and scipy only). The main names:

* tasks: :class:`AllosteryTask`, :func:`paper_task`, :func:`stern_task`; several examples
  at once: :class:`TaskSet`, :func:`examples_task`, :func:`gain_examples`,
  :func:`regression_task`, :func:`symmetric`, :func:`anchored`; node displacements
  (absolute or relative to another node) as outputs: :class:`NodeTask`, :func:`node_task`;
* rules: :class:`CoupledLearning`, :class:`ProspectiveConfiguration`,
  :class:`ExactGradient`, :class:`DirectedAging` (frozen dataclasses with
  ``update(net, task, ...) -> Step``);
* equilibria for learning: :class:`Solver`, :class:`Tracker`;
* exact gradients: :func:`cost_gradient`, :class:`Sensitivity`, :func:`gcl_limit`;
* training: :func:`train` -> :class:`History` (``.save`` / ``History.load``);
* coupling of a trained network's targets to its sources: :func:`measure_coupling`.
"""

from __future__ import annotations

from .aging import DirectedAging
from .coupling import Coupling, measure_coupling
from .examples import (
    TaskSet,
    anchored,
    examples_task,
    gain_examples,
    regression_task,
    symmetric,
)
from .history import History
from .node_tasks import NodeTask, node_cost_gradient, node_task
from .physical_time import TimeHistory, learn_in_time, network_relaxation_time
from .rules import (
    CoupledLearning,
    ExactGradient,
    LearningError,
    ProspectiveConfiguration,
    Rule,
    Step,
    Warm,
)
from .sensitivity import Sensitivity, cost_gradient, gcl_limit
from .states import Solver, Tracker
from .tasks import AllosteryTask, paper_task, stern_task
from .train import train

__all__ = [
    "AllosteryTask",
    "CoupledLearning",
    "Coupling",
    "DirectedAging",
    "ExactGradient",
    "History",
    "LearningError",
    "NodeTask",
    "ProspectiveConfiguration",
    "Rule",
    "Sensitivity",
    "Solver",
    "Step",
    "TaskSet",
    "TimeHistory",
    "Tracker",
    "Warm",
    "anchored",
    "cost_gradient",
    "examples_task",
    "gain_examples",
    "gcl_limit",
    "learn_in_time",
    "measure_coupling",
    "network_relaxation_time",
    "node_cost_gradient",
    "node_task",
    "paper_task",
    "regression_task",
    "stern_task",
    "symmetric",
    "train",
]
