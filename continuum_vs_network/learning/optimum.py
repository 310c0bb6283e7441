"""The quasi-static optimum of a task's error: what a network *can* hold, rule speed aside.

:func:`exact_optimum` minimises the task error ``C`` (Eq. 26, summed over the examples of a
:class:`~.examples.TaskSet`) over the learning stiffnesses with L-BFGS-B (scipy) on the exact
(adjoint) gradient of :class:`~.rules.ExactGradient` (the same gradient, masks and
equilibria; only the step is chosen by a quasi-Newton line search instead of a fixed rate).
Bounds keep every stiffness at or above ``floor``. A local rule trained for a fixed budget
reaches this optimum or not; the optimum says how many responses the network can hold.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..network.model import SpringNetwork
from .examples import TaskSet

__all__ = ["Optimum", "exact_optimum"]


@dataclass(frozen=True, eq=False)
class Optimum:
    """Result of :func:`exact_optimum`.

    Attributes
    ----------
    net : SpringNetwork
        The network at the optimum (new stiffnesses).
    error, error_initial : float
        Summed error ``C`` at the optimum and of the untrained network.
    example_ratio : (n_examples,) float array
        Each example's ``C_e / C_e0`` (NaN for an example with ``C_e0 = 0``).
    iterations, evaluations : int
        L-BFGS-B iterations and equilibrium evaluations (one free state per example each).
    converged : bool
        Whether L-BFGS-B met its tolerance (False: it hit ``max_iter``); ``message`` says why.
    message : str
    """

    net: SpringNetwork
    error: float
    error_initial: float
    example_ratio: NDArray
    iterations: int
    evaluations: int
    converged: bool
    message: str


def exact_optimum(
    net: SpringNetwork,
    tasks: TaskSet,
    *,
    floor: float,
    max_iter: int = 300,
    rtol: float = 1e-4,
) -> Optimum:
    """Minimise ``C = sum_e C_e`` over the bulk stiffnesses of ``net`` (L-BFGS-B).

    Parameters
    ----------
    net : SpringNetwork
    tasks : TaskSet
        Spring-task examples; their sources and targets keep their stiffnesses (bulk learning).
    floor : float
        Least stiffness (> 0, force / length).
    max_iter : int
        Most L-BFGS-B iterations (>= 1).
    rtol : float
        Stop as soon as every example's ``C_e / C_e0 <= rtol`` (met with margin), else when
        L-BFGS-B's own tolerances are met or at ``max_iter``.

    Returns
    -------
    Optimum

    Raises
    ------
    EquilibriumError, LearningError
        A free state cannot be found during the search.
    """
    from scipy.optimize import minimize

    from .rules import ExactGradient
    from .states import Tracker

    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    if not isinstance(tasks, TaskSet) or tasks.node_outputs:
        raise check.ArgumentError("tasks", tasks, "a TaskSet of AllosteryTask examples")
    floor = check.real("floor", floor, low=0, low_open=True)
    max_iter = check.integer("max_iter", max_iter, low=1)
    rtol = check.real("rtol", rtol, low=0, low_open=True)
    tasks.check(net)

    rule = ExactGradient(1.0, dof="stiffness", cost="strain")
    tracker = Tracker(rule.solver)  # one per search: its factorisations are reused
    mask = rule.learning_mask(net, tasks)
    k0 = net.stiffness.copy()
    scale = float(np.mean(k0))
    state: dict = {"warm": None, "evals": 0}

    def evaluate(z: NDArray) -> tuple[float, NDArray, list]:
        k = k0.copy()
        k[mask] = z * scale
        trial = net.with_stiffness(k)
        step = rule.update(trial, tasks, warm=state["warm"], tracker=tracker)
        state["warm"], state["evals"] = step.warm, state["evals"] + 1
        errors = [t.error(trial, s.free.positions) for t, s in zip(tasks.tasks, step.examples)]
        grad = -np.asarray(step.raw)[mask] * scale  # raw = -dC/dk at alpha = 1
        return float(sum(errors)), grad, errors

    z0 = k0[mask] / scale
    c0, _, e0 = evaluate(z0)
    if c0 == 0.0:
        raise ValueError("tasks: the untrained network already meets every example (C0 = 0)")

    def fun(z):
        c, g, e = evaluate(z)
        if all(a <= rtol * b for a, b in zip(e, e0)):
            raise _Done(z)
        return c / c0, g / c0

    try:
        res = minimize(
            fun, z0, jac=True, method="L-BFGS-B",
            bounds=[(floor / scale, None)] * z0.size,
            options={"maxiter": max_iter, "ftol": 1e-14, "gtol": 1e-12},
        )  # fmt: skip
        z, iterations, converged, message = res.x, int(res.nit), bool(res.success), res.message
    except _Done as done:
        z, iterations, converged, message = done.z, -1, True, f"every C_e <= {rtol:g} C_e0"
    c, _, e = evaluate(z)
    k = k0.copy()
    k[mask] = z * scale
    ratio = np.array([a / b if b > 0 else np.nan for a, b in zip(e, e0)])
    return Optimum(
        net=net.with_stiffness(k), error=c, error_initial=c0, example_ratio=ratio,
        iterations=iterations, evaluations=state["evals"], converged=converged,
        message=str(message),
    )  # fmt: skip


class _Done(Exception):
    """Every example met ``rtol`` (stops the search early)."""

    def __init__(self, z: NDArray) -> None:
        super().__init__()
        self.z = np.array(z, copy=True)
