"""The optimum of a task's error: what the task allows within the physical range.

:func:`exact_optimum` minimises the task error ``C`` (Eq. 26, summed over the examples of a
:class:`~.examples.TaskSet`) over the bulk springs' stiffnesses, rest lengths or both
(``dof``), with L-BFGS-B (scipy) on the exact (adjoint) gradient of
:class:`~.rules.ExactGradient` (the same gradient, masks and equilibria as the rule; only
the step is chosen by a quasi-Newton line search instead of a rate). Every learned value
stays within its range relative to its initial value (:mod:`.ranges`, the bounds every rule
honours), so the optimum is the reference beside every rule: a rule trained for a fixed
budget reaches it or not, and a task whose optimum misses the level
(:meth:`Optimum.feasible`) asks for a response the material cannot give. :func:`optima`
gives the three, with ``"both"`` started from the better single one.

The search is local and follows the free states continuously from the untrained network:
where learning the rest lengths drives the network to a snap-through (a fold of its
equilibria), the error jumps there and the search stops at the fold (L-BFGS-B's line search
then ends "ABNORMAL", ``converged=False``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..network.equilibrium import EquilibriumError
from ..network.model import SpringNetwork
from .examples import TaskSet
from .ranges import REST_LENGTH_RANGE, STIFFNESS_RANGE, check_range
from .step import JOINT, LearningError, Warm

__all__ = ["Optimum", "exact_optimum", "optima"]

DOFS = ("stiffness", "rest_length", "both")
#: relative force tolerance of the free states. The rules' 1e-10 leaves the differences of
#: ``C`` between nearby warm-started states wrong by 1e-3 (the error lies along the step),
#: which the line search sees; where 1e-12 is out of float64's reach, 1e-10 is used.
_TOL = 1e-12
#: the largest change of a scaled value ``v / mean(v0)`` in the search's first trial
_FIRST_STEP = 1e-2
#: Newton iterations a trial's free state may take from the accepted point's
_BUDGET = 100


@dataclass(frozen=True, eq=False)
class Optimum:
    """Result of :func:`exact_optimum`.

    Attributes
    ----------
    net : SpringNetwork
        The network at the optimum (new stiffnesses, rest lengths, or both).
    error, error_initial : float
        Summed error ``C`` at the optimum and of the untrained network.
    example_ratio : (n_examples,) float array
        Each example's ``C_e / C_e0``; an example the untrained network already meets
        (``C_e0 = 0``, such as the rest example of :func:`~.examples.anchored`) is measured
        against the summed initial error instead, ``C_e / C0``.
    iterations, evaluations : int
        L-BFGS-B iterations and gradient evaluations (one free state and one adjoint solve
        per example each).
    converged : bool
        Whether the search met ``rtol`` or L-BFGS-B its own tolerance (False: it hit
        ``max_iter``, or its line search failed, typically at a snap-through); ``message``
        says why.
    message : str
    dof : {"stiffness", "rest_length", "both"}
        What was optimised.
    contrast : float
        ``max(k / k0) / min(k / k0)`` over the learning springs: the stiffness contrast
        the optimum needs (1 for rest-length learning).
    free : tuple of (n_nodes, 2) float arrays
        Each example's free state at the optimum (the branch the search followed).
    """

    net: SpringNetwork
    error: float
    error_initial: float
    example_ratio: NDArray
    iterations: int
    evaluations: int
    converged: bool
    message: str
    dof: str
    contrast: float
    free: tuple[NDArray, ...] = dataclasses.field(repr=False)

    @property
    def ratio(self) -> float:
        """``C / C0``: the summed error at the optimum over the untrained one."""
        return self.error / self.error_initial

    def feasible(self, level: float = 1e-3) -> bool:
        """Whether every example reaches ``C_e / C_e0 <= level`` at the optimum.

        The optimum is the least error learning ``dof`` reaches within the physical range.
        A draw whose optimum cannot reach ``level`` is one whose target cannot be made to
        respond to its source as asked: the study flags or redraws it rather than charging
        a rule for missing it.
        """
        level = check.real("level", level, low=0, low_open=True)
        return bool(np.all(self.example_ratio <= level))


def exact_optimum(
    net: SpringNetwork,
    tasks: TaskSet,
    *,
    dof: str = "stiffness",
    stiffness_range: tuple[float, float] | None = STIFFNESS_RANGE,
    rest_length_range: tuple[float, float] | None = REST_LENGTH_RANGE,
    floor: float | None = None,
    start: Optimum | None = None,
    max_iter: int = 300,
    rtol: float = 1e-4,
) -> Optimum:
    """Minimise ``C = sum_e C_e`` over the bulk springs' ``dof`` (L-BFGS-B, exact gradient).

    Parameters
    ----------
    net : SpringNetwork
        The untrained network: the ranges and ``error_initial`` refer to it.
    tasks : TaskSet
        Spring-task examples; their sources and targets keep their values (bulk learning).
    dof : {"stiffness", "rest_length", "both"}
        The learning degrees of freedom: stiffnesses ``k``, rest lengths ``L``, or both.
    stiffness_range : (low, high) or None
        Each learned stiffness stays within ``[low, high] * k0`` (its initial value;
        :data:`~.ranges.STIFFNESS_RANGE` by default). None: only ``k >= 0``.
    rest_length_range : (low, high) or None
        The same for the rest lengths (:data:`~.ranges.REST_LENGTH_RANGE`). None: only
        ``L >= 0``.
    floor : float, optional
        Least stiffness (> 0, force / length, absolute): the lower bound of each learned
        stiffness is ``max(floor, low * k0)`` (and its upper bound at least that). Ignored
        for ``dof="rest_length"``.
    start : Optimum, optional
        Start from this earlier optimum of ``net`` and ``tasks`` (its values and free
        states, clipped into the bounds) instead of ``net``: for ``dof="both"``, the better
        single-dof optimum (:func:`optima`), so that the joint optimum is no worse.
    max_iter : int
        Most L-BFGS-B iterations (>= 1).
    rtol : float
        Stop as soon as every example's ratio (:attr:`Optimum.example_ratio`) is
        ``<= rtol``, else when L-BFGS-B's own tolerances are met or at ``max_iter``.

    Returns
    -------
    Optimum

    Raises
    ------
    EquilibriumError, LearningError
        A free state of the starting network cannot be found (a trial point of the search
        whose state cannot be found is rejected instead).
    ValueError
        The untrained network already meets every example (``C0 = 0``).
    """
    from scipy.optimize import minimize

    problem = _Problem(net, tasks, dof, stiffness_range, rest_length_range, floor, start)
    max_iter = check.integer("max_iter", max_iter, low=1)
    rtol = check.real("rtol", rtol, low=0, low_open=True)

    def fun(u: NDArray) -> tuple[float, NDArray]:
        f, g, ratios = problem.objective(u)
        if ratios is not None and np.all(ratios <= rtol):
            raise _Done(u)
        return f, g

    nit = [0]

    def accept(u: NDArray) -> None:
        nit[0] += 1
        problem.accept(u)

    if np.all(problem.ratios(problem.e_start) <= rtol):
        u, converged, message = problem.u0, True, f"every C_e <= {rtol:g} C_e0"
    else:
        try:
            res = minimize(
                fun, problem.u0, jac=True, method="L-BFGS-B", bounds=problem.bounds,
                callback=accept, options={"maxiter": max_iter, "ftol": 1e-14, "gtol": 1e-12},
            )  # fmt: skip
            u, converged, message = res.x, bool(res.success), str(res.message)
        except _Done as done:
            u, converged, message = done.u, True, f"every C_e <= {rtol:g} C_e0"
    return problem.result(u, nit[0], converged, message)


def optima(net: SpringNetwork, tasks: TaskSet, **options) -> dict[str, Optimum]:
    """The optimum of each ``dof`` of :data:`DOFS`, ``"both"`` from the better single one.

    ``options`` go to :func:`exact_optimum` (not ``dof`` or ``start``). Started from the
    better single-dof optimum, the joint search keeps or lowers its error: more freedom
    does no worse, which a joint search from ``net`` does not promise (it can stop at a
    snap-through the single ones avoid).
    """
    out = {d: exact_optimum(net, tasks, dof=d, **options) for d in DOFS[:2]}
    best = min(out.values(), key=lambda o: o.error)
    out["both"] = exact_optimum(net, tasks, dof="both", start=best, **options)
    return out


class _Problem:
    """The search variables, their bounds and ``C`` with its gradient (what L-BFGS-B sees).

    The learning springs' values over their network means (``z = L / mean(L0)``,
    ``k / mean(k0)``: numbers of order one; concatenated in the order :data:`~.step.JOINT`
    for ``dof="both"``), each dof's divided by a factor ``a`` (``u = z / a`` up to a shift
    that keeps the untrained values exact) that makes L-BFGS-B's first trial move no ``z``
    by more than :data:`_FIRST_STEP`.
    """

    def __init__(self, net, tasks, dof, stiffness_range, rest_length_range, floor, start) -> None:
        from .rules import ExactGradient
        from .states import Solver, Tracker

        if not isinstance(net, SpringNetwork):
            raise check.ArgumentError("net", net, "a SpringNetwork")
        if not isinstance(tasks, TaskSet) or tasks.node_outputs:
            raise check.ArgumentError("tasks", tasks, "a TaskSet of AllosteryTask examples")
        self.dof = check.choice("dof", dof, DOFS)
        ranges = {
            "stiffness": check_range("stiffness_range", stiffness_range),
            "rest_length": check_range("rest_length_range", rest_length_range),
        }
        if floor is not None:
            floor = check.real("floor", floor, low=0, low_open=True)
        if start is not None and not (
            isinstance(start, Optimum) and start.net.n_springs == net.n_springs
        ):
            raise check.ArgumentError("start", start, f"None or an Optimum of {net!r}")
        tasks.check(net)
        self.net, self.tasks = net, tasks
        # the raw rate (step.raw = -dC/dtheta) and no range: the bounds are L-BFGS-B's
        names = {f.name for f in dataclasses.fields(ExactGradient)}
        off = {n: None for n in ("stiffness_range", "rest_length_range") if n in names}
        lean = {"max_iter": _BUDGET, "retry_ramps": (), "trust_region": False}
        self.rules = [
            ExactGradient(1.0, dof=self.dof, cost="strain", solver=solver, **off)
            for solver in (Solver(tol=_TOL, **lean), Solver(**lean), Solver())
        ]
        self.trackers = [Tracker(r.solver) for r in self.rules]  # factorisations reused
        self.mask = self.rules[0].learning_mask(net, tasks)
        self.parts = JOINT if self.dof == "both" else (self.dof,)
        self.initial = {"stiffness": net.stiffness.copy(), "rest_length": net.rest_length.copy()}
        self.scale = {d: float(np.mean(v)) for d, v in self.initial.items()}
        low, high = [], []
        for d in self.parts:
            v0 = self.initial[d][self.mask]
            lo, hi = np.zeros_like(v0), np.full_like(v0, np.inf)
            if ranges[d] is not None:
                lo, hi = ranges[d][0] * v0, ranges[d][1] * v0
            if d == "stiffness" and floor is not None:
                lo = np.maximum(lo, floor)
                hi = np.maximum(hi, lo)
            low.append(lo / self.scale[d])
            high.append(hi / self.scale[d])
        low, high = np.concatenate(low), np.concatenate(high)
        self.evaluations = 0
        self._cache: dict[bytes, tuple] = {}
        self.warm = Warm()
        z0 = self.zbar = self._zs(net)  # the untrained network
        self.c0, g0, self.e0 = self.evaluate(z0, robust=True)
        if self.c0 == 0.0:
            raise ValueError("tasks: the untrained network already meets every example (C0 = 0)")
        # L-BFGS-B's first trial is the Cauchy step -g (its first Hessian is the identity),
        # up to the bounds when every variable is boxed. Rest lengths a few per cent off
        # prestress the network more than the source does (and can snap it), and C is far
        # more sensitive to L than to k: each dof's factor a moves it by _FIRST_STEP at most
        n = int(self.mask.sum())
        self.a = np.ones_like(z0)
        for i in range(len(self.parts)):
            top = float(np.max(np.abs(g0[i * n : (i + 1) * n]), initial=0.0))
            if top > 0:
                self.a[i * n : (i + 1) * n] = np.sqrt(_FIRST_STEP * self.c0 / top)
        self.ubar = z0 / self.a
        self.u0 = self.ubar
        if start is not None:
            self.u0 = self.ubar + (np.clip(self._zs(start.net), low, high) - z0) / self.a
            self.warm = Warm(examples=tuple(Warm(free=np.asarray(x)) for x in start.free))
        _, _, self.e_start = self.evaluate(self.z(self.u0), robust=True)
        lows = (self.ubar + (low - z0) / self.a).tolist()
        highs = (self.ubar + (high - z0) / self.a).tolist()
        self.bounds = [(lo, None if np.isinf(hi) else hi) for lo, hi in zip(lows, highs)]
        self.accept(self.u0)

    def _zs(self, net: SpringNetwork) -> NDArray:
        """The scaled values ``z`` of ``net``."""
        return np.concatenate([getattr(net, d)[self.mask] / self.scale[d] for d in self.parts])

    def z(self, u: NDArray) -> NDArray:
        """The scaled values ``z = v / mean(v0)`` of the search variables ``u``."""
        return self.zbar + (np.asarray(u, dtype=float) - self.ubar) * self.a

    def values(self, z: NDArray) -> dict[str, NDArray]:
        """The full arrays of the learned ``dof`` at ``z`` (their initial values, exactly,
        where ``z`` has the untrained network's)."""
        out, n = {}, int(self.mask.sum())
        dz = np.asarray(z, dtype=float) - self.zbar
        for i, d in enumerate(self.parts):
            v = self.initial[d].copy()
            v[self.mask] += dz[i * n : (i + 1) * n] * self.scale[d]
            out[d] = v
        return out

    def network(self, z: NDArray) -> SpringNetwork:
        """``net`` with the learned values at ``z``."""
        v = self.values(z)
        net = self.net
        if "rest_length" in v:
            net = net.with_rest_length(v["rest_length"])
        if "stiffness" in v:
            net = net.with_stiffness(v["stiffness"])
        return net

    def evaluate(self, z: NDArray, *, robust: bool = False) -> tuple[float, NDArray, list[float]]:
        """``(C, dC/dz, [C_e])`` at ``z``, from the free states of the last accepted point.

        Every trial starts from the equilibria of :meth:`accept`'s point (not the last
        trial's): a prestressed network can hold several equilibria, and a line search
        that overshoots must not carry the free state onto another branch. A state not
        found to :data:`_TOL` (float64's reach) is found to the rules' tolerance, both
        within :data:`_BUDGET` Newton iterations from the warm start: a trial that needs
        more is typically past a snap-through, and the search rejects it
        (:meth:`objective`) rather than spend minutes there. ``robust`` (the starting
        points): every tier, the last with the rules' full recovery.
        """
        z = np.asarray(z, dtype=float)
        key = z.tobytes()
        if key in self._cache:
            return self._cache[key][0]
        trial = self.network(z)
        tiers = len(self.rules) if robust else len(self.rules) - 1
        for i, (rule, tracker) in enumerate(zip(self.rules[:tiers], self.trackers)):
            try:
                step = rule.update(trial, self.tasks, warm=self.warm, tracker=tracker)
                break
            except (EquilibriumError, LearningError) as err:
                state = getattr(err, "state", None)
                near = state is not None and state.relative_residual <= 10 * _TOL
                if i == tiers - 1 or not (robust or near):  # a trial far from a state
                    raise
        self.evaluations += 1
        errors = [t.error(trial, s.free.positions) for t, s in zip(self.tasks.tasks, step.examples)]
        raw = np.asarray(step.raw).reshape(len(self.parts), -1)  # raw = -dC/dtheta
        grad = np.concatenate(
            [-raw[i][self.mask] * self.scale[d] for i, d in enumerate(self.parts)]
        )
        result = (float(sum(errors)), grad, errors)
        free = tuple(s.free.positions for s in step.examples)
        if len(self._cache) >= 64:  # the line search's trials since the last accepted point
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = (result, free)
        return result

    def objective(self, u: NDArray) -> tuple[float, NDArray, NDArray | None]:
        """What L-BFGS-B minimises, ``C / C0``, its gradient with respect to ``u``, and the
        examples' ratios. A trial whose free state cannot be found is rejected: an error
        above the accepted one (and the accepted gradient; ratios None)."""
        try:
            c, g, e = self.evaluate(self.z(u))
        except (EquilibriumError, LearningError):
            c, g, _ = self.evaluate(self.z(self._accepted))
            return c / self.c0 + 1.0, g * self.a / self.c0, None
        return c / self.c0, g * self.a / self.c0, self.ratios(e)

    def accept(self, u: NDArray) -> None:
        """Start the following trials from the equilibria at ``u`` (an accepted iterate)."""
        self._accepted = np.array(u, dtype=float)
        hit = self._cache.get(self.z(u).tobytes())
        if hit is not None:
            self.warm = Warm(examples=tuple(Warm(free=x) for x in hit[1]))

    def ratios(self, errors: list[float]) -> NDArray:
        """Each example's ``C_e / C_e0`` (``C_e / C0`` where ``C_e0 = 0``)."""
        return np.array([a / (b if b > 0 else self.c0) for a, b in zip(errors, self.e0)])

    def result(self, u: NDArray, iterations: int, converged: bool, message: str) -> Optimum:
        """The :class:`Optimum` at ``u`` (at the last accepted point if ``u``'s state
        cannot be found)."""
        z = self.z(u)
        try:
            c, _, e = self.evaluate(z)
        except (EquilibriumError, LearningError):
            z = self.z(self._accepted)
            c, _, e = self.evaluate(z)
        free = self._cache[z.tobytes()][1]
        contrast = 1.0
        if "stiffness" in self.parts:
            q = self.values(z)["stiffness"][self.mask] / self.initial["stiffness"][self.mask]
            contrast = float(q.max() / q.min()) if q.size else 1.0
        return Optimum(
            net=self.network(z), error=c, error_initial=self.c0, example_ratio=self.ratios(e),
            iterations=iterations, evaluations=self.evaluations, converged=converged,
            message=message, dof=self.dof, contrast=contrast, free=free,
        )  # fmt: skip


class _Done(Exception):
    """Every example met ``rtol`` (stops the search early)."""

    def __init__(self, u: NDArray) -> None:
        super().__init__()
        self.u = np.array(u, copy=True)
