"""Topology optimisation of a compliant mechanism: SIMP (penalty 3) with a density filter, OC.

The reference a learned modulus field is compared with (Sigmund 1997; Bendsøe & Sigmund
2003, sec. 2.6 and its 99-line code's mechanism variant), written on scikit-fem's element
operators of :class:`~.learnable.LearnableBody` (the stiffness ``sum_e s_e K_e``):

* design ``x`` (n_elements,) in ``[0, 1]``, filtered ``xt = H x``
  (:func:`~.filtered.density_filter`),
  modulus ``s = e_min + xt^p (e_max - e_min)`` (:func:`simp_modulus`, ``p = 3``; the
  textbook's ``e_max = 1``, the solid; on the allosteric task the task's own material keeps
  ``s = 1``, so ``e_max = 100`` gives SIMP the learned field's range ``1e-2 .. 1e2``: with
  ``e_max = 1`` neither OC nor MMA gets below C/C0 0.65 on the default mechanism scene, and
  the unpenalised exact optimum capped at 1 stalls at 0.77, a limit of the design space);
* volume ``sum_e A_e xt_e <= volfrac * sum_e A_e``;
* optimality-criteria update for mechanisms (:func:`oc_update`): ``x <- x B^0.3`` with
  ``B = max(1e-10, -dc/dx) / (lambda dv/dx)``, move limit 0.1, ``lambda`` by bisection on
  the volume (the objective of a mechanism has sensitivities of both signs; the damping 0.3
  and the floor are the textbook's).

Two objectives: the allosteric task's error ``C`` (:func:`simp_allosteric`, the same ``C`` and
adjoint as :class:`~continuum_vs_network.ExactGradient`; solved by MMA, Svanberg's
globally convergent CCSA from ``nlopt`` (``LD_MMA``, the optional extra ``topopt``), when it
is installed, else by OC: OC's fixed-point heuristic assumes a compliance-like objective
whose sensitivities have one sign, and on a target-tracking ``C`` it stalls, at C/C0 0.65 in
100 iterations of the default mechanism scene), and the force inverter's output
displacement ``u_out`` (:func:`simp_inverter`, minimised: the output should move against the
input; layout :func:`~.mechanism.inverter_layout`), with ``dc/ds_e = -lambda_e . K_e u_e``
from the adjoint ``K lambda = e_out``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "SimpResult",
    "inverter_response",
    "mma_available",
    "oc_update",
    "simp_allosteric",
    "simp_inverter",
    "simp_modulus",
]

#: SIMP penalty
PENALTY = 3.0


def simp_modulus(
    xt: ArrayLike, *, penal: float = PENALTY, e_min: float = 1e-4, e_max: float = 1.0
) -> tuple[NDArray, NDArray]:
    """Modulus ``e_min + xt^p (e_max - e_min)`` and its derivative ``d s / d xt``, (n,)."""
    x = np.asarray(xt, dtype=float)
    return e_min + x**penal * (e_max - e_min), penal * x ** (penal - 1.0) * (e_max - e_min)


def oc_update(
    x: NDArray, dc: NDArray, dv: NDArray, volume: float, weights: sp.csr_matrix,
    area: NDArray, *, move: float = 0.1, damping: float = 0.3, active: NDArray | None = None,
) -> NDArray:  # fmt: skip
    """One optimality-criteria step (see the module): the new design (n,) in [0, 1] whose
    filtered volume ``sum A (H x)`` is ``volume`` (area units). ``dc``, ``dv``: the
    objective's and the volume's sensitivities to ``x``. ``active``: elements that change."""
    act = np.ones_like(x, dtype=bool) if active is None else active
    lo, hi = 0.0, 1e9
    ratio = np.maximum(1e-10, -dc) / np.maximum(dv, 1e-300)
    while (hi - lo) / (hi + lo) > 1e-6:
        mid = 0.5 * (lo + hi)
        new = np.clip(
            x * (ratio / mid) ** damping, np.maximum(0.0, x - move), np.minimum(1.0, x + move)
        )
        new = np.where(act, new, x)
        if float(area @ (weights @ new)) > volume:
            lo = mid
        else:
            hi = mid
    return new


@dataclass(frozen=True, eq=False)
class SimpResult:
    """Result of a SIMP run.

    Attributes
    ----------
    density : (n_elements,) float array
        Filtered (physical) density ``xt`` at the end.
    modulus : (n_elements,) float array
        ``simp_modulus(xt)``.
    objective : (iterations + 1,) float array
        Objective after every iteration (``C / C0`` or ``u_out``).
    volume : float
        Filtered volume fraction at the end.
    iterations, solves : int
        Iterations (MMA: evaluations less one); linear solves (one factorisation each, the
        adjoint reuses it).
    seconds : float
    times : (iterations + 1,) float array
        Cumulative seconds at each objective.
    method : str
        ``"oc"`` or ``"mma"``.
    final : float
        The objective of the returned design (OC: the last evaluation; MMA: the best
        feasible evaluation, which need not be the last).
    """

    density: NDArray[np.float64]
    modulus: NDArray[np.float64]
    objective: NDArray[np.float64]
    volume: float
    iterations: int
    solves: int
    seconds: float
    times: NDArray[np.float64]
    method: str = "oc"
    final: float = np.nan


def _check(volfrac: float, iterations: int) -> None:
    if not (0 < volfrac <= 1):
        raise ValueError(f"volfrac must be in (0, 1], got {volfrac!r}")
    if int(iterations) != iterations or iterations < 1:
        raise ValueError(f"iterations must be an integer >= 1, got {iterations!r}")


def mma_available() -> bool:
    """Whether ``nlopt`` (MMA) imports."""
    try:
        import nlopt  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass(frozen=True, eq=False)
class _AllostericSimp:
    """SIMP on the allosteric task: the filter, the frozen task material and ``C0`` (built
    once by :func:`_allosteric_simp`); :meth:`evaluate` is one solve, shared by OC and MMA."""

    body: Any
    task: Any
    frozen: NDArray[np.bool_]
    H: sp.csr_matrix
    area: NDArray[np.float64]
    c0: float
    e_min: float
    e_max: float

    def evaluate(self, x: NDArray, gradient: bool = True) -> tuple[float, NDArray | None]:
        """``C / C0`` at the design ``x`` (n,) and, with ``gradient``, ``d(C / C0)/dx`` (n,)
        (the adjoint reuses the free state's factorisation)."""
        s, ds = simp_modulus(self.H @ x, e_min=self.e_min, e_max=self.e_max)
        s, ds = np.where(self.frozen, 1.0, s), np.where(self.frozen, 0.0, ds)  # task material
        m = self.body.with_modulus(s)
        free = m.free_state(self.task)
        c = self.task.error(free.target_strain) / self.c0
        if not gradient:
            return c, None
        g = m.task_gradient(self.task, free, "modulus") * self.area * ds / self.c0
        return c, self.H.T @ g

    def result(self, x: NDArray, objective: list, times: list, t0: float, method: str, final=None):
        xt = self.H @ x
        return SimpResult(
            density=xt,
            modulus=np.where(
                self.frozen, 1.0, simp_modulus(xt, e_min=self.e_min, e_max=self.e_max)[0]
            ),
            objective=np.array(objective),
            volume=float(self.area @ xt / self.area.sum()), iterations=len(objective) - 1,
            solves=len(objective), seconds=time.perf_counter() - t0, times=np.array(times),
            method=method, final=float(objective[-1] if final is None else final),
        )  # fmt: skip


def _allosteric_simp(
    body: Any, task: Any, radius: float, e_min: float, e_max: float
) -> _AllostericSimp:
    from .filtered import density_filter

    frozen = ~body.learning_mask(task, learn_sources=False, learn_targets=False)
    H = density_filter(body.body.centroids, body.area, radius, frozen=frozen)
    c0 = task.error(body.free_state(task).target_strain)
    return _AllostericSimp(body, task, frozen, H, body.area, c0, e_min, e_max)


def simp_allosteric(
    body: Any, task: Any, *, volfrac: float = 0.5, radius: float, iterations: int = 100,
    e_min: float = 1e-4, rtol: float = 1e-6, method: str = "auto", e_max: float = 1.0,
) -> SimpResult:  # fmt: skip
    """SIMP on the allosteric task's error ``C`` (see the module), by MMA or OC.

    ``body`` (LearnableBody) gives the mesh and material; ``task`` a MaterialTask. The
    task's own material (its sources' and targets' discs and segments) stays solid
    (``x = 1``, outside the filter). Stops early at ``C <= rtol C0`` (``C0``: the uniform
    body's). ``objective`` holds ``C / C0`` per evaluation (MMA: each evaluation is one
    solve; its inner iterations included). ``method``: ``"mma"`` (needs nlopt), ``"oc"``,
    or ``"auto"`` (MMA when nlopt imports). The result's ``method`` says which ran.
    """
    if method not in ("auto", "mma", "oc"):
        raise ValueError(f"method must be 'auto', 'mma' or 'oc', got {method!r}")
    if method == "auto":
        method = "mma" if mma_available() else "oc"
    _check(volfrac, iterations)
    problem = _allosteric_simp(body, task, radius, e_min, e_max)
    if method == "mma":
        return _simp_allosteric_mma(problem, volfrac=volfrac, iterations=iterations, rtol=rtol)
    frozen, H, area = problem.frozen, problem.H, problem.area
    x = np.where(frozen, 1.0, volfrac)
    volume = volfrac * area.sum()
    t0 = time.perf_counter()
    objective, times = [], []
    for it in range(iterations + 1):
        last = it == iterations
        c, dc = problem.evaluate(x, gradient=not last)
        objective.append(c)
        times.append(time.perf_counter() - t0)
        if last or c <= rtol:
            break
        x = oc_update(x, dc, H.T @ area, volume, H, area, active=~frozen)
    return problem.result(x, objective, times, t0, "oc")


def _simp_allosteric_mma(
    problem: _AllostericSimp, *, volfrac: float, iterations: int, rtol: float
) -> SimpResult:
    """:func:`simp_allosteric` by nlopt's MMA: ``iterations`` evaluations at most, the
    volume as an inequality constraint, bounds ``0 <= x <= 1`` on the active elements.

    It starts from a feasible design: the active elements at the uniform density whose
    filtered volume, with the solid task material, is ``volfrac`` (the volume is linear in
    it). From the infeasible ``x = volfrac`` (the solid discs add volume) MMA spent its
    evaluations regaining feasibility on finer meshes and never improved the objective."""
    import nlopt

    frozen, H, area = problem.frozen, problem.H, problem.area
    active = np.flatnonzero(~frozen)
    total = float(area.sum())
    base = np.where(frozen, 1.0, 0.0)
    dv = (H.T @ area)[active] / total
    t0 = time.perf_counter()
    objective: list[float] = []
    times: list[float] = []

    def full(y: NDArray) -> NDArray:
        x = base.copy()
        x[active] = y
        return x

    solid = float(area @ (H @ base)) / total  # volume at y = 0; each unit of y adds dv.sum()
    start = np.full(active.size, float(np.clip((volfrac - solid) / dv.sum(), 0.0, volfrac)))
    best = [np.inf, full(start)]

    def f(y: NDArray, grad: NDArray) -> float:
        x = full(y)
        c, dc = problem.evaluate(x, gradient=bool(grad.size))
        objective.append(c)
        times.append(time.perf_counter() - t0)
        if c < best[0] and float(area @ (H @ x)) <= volfrac * total * (1 + 1e-6):
            best[0], best[1] = c, x
        if grad.size:
            grad[:] = dc[active]
        return c

    def volume(y: NDArray, grad: NDArray) -> float:
        if grad.size:
            grad[:] = dv
        return float(area @ (H @ full(y))) / total - volfrac

    opt = nlopt.opt(nlopt.LD_MMA, active.size)
    opt.set_lower_bounds(np.zeros(active.size))
    opt.set_upper_bounds(np.ones(active.size))
    opt.set_min_objective(f)
    opt.add_inequality_constraint(volume, 1e-8)
    opt.set_maxeval(int(iterations) + 1)
    opt.set_stopval(float(rtol))
    opt.set_initial_step(0.1)  # asymptotes: about the textbook's move limit
    try:
        opt.optimize(start)
    except nlopt.RoundoffLimited:  # keep the best design found
        pass
    if not np.isfinite(best[0]):  # no feasible evaluation: report the start's objective
        best[0] = problem.evaluate(best[1], gradient=False)[0]
    return problem.result(best[1], objective, times, t0, "mma", final=best[0])


def inverter_response(
    body: Any, layout: Any, modulus: ArrayLike, *, adjoint: bool = True
) -> tuple[float, float, NDArray | None]:
    """Input and output displacements ``(u_in, u_out)`` of the inverter with ``modulus``
    (n_elements,), and ``d u_out / d s`` (n_elements,) when ``adjoint`` (else None)."""
    from ..linalg.kkt import factor_spd

    m = body.with_modulus(modulus)
    n = body.n_dofs
    springs = np.zeros(n)
    springs[layout.input_dof] += layout.k_in
    springs[layout.output_dof] += layout.k_out
    K = m.stiffness() + sp.diags(springs)
    keep = np.ones(n, dtype=bool)
    keep[layout.fixed] = False
    free = np.flatnonzero(keep)
    f = np.zeros(n)
    f[layout.input_dof] = layout.force
    factor = factor_spd(K[free][:, free].tocsc(), certify=False)
    if factor is None:
        raise ValueError("the inverter's stiffness is singular: check the layout's supports")
    u = np.zeros(n)
    u[free] = factor.solve(f[free])
    if not adjoint:
        return float(u[layout.input_dof]), float(u[layout.output_dof]), None
    e = np.zeros(n)
    e[layout.output_dof] = 1.0
    lam = np.zeros(n)
    lam[free] = factor.solve(e[free])
    ops = body._ops
    g = -np.einsum("ei,eij,ej->e", lam[ops.edofs], ops.Ke, u[ops.edofs])
    return float(u[layout.input_dof]), float(u[layout.output_dof]), g


def simp_inverter(
    body: Any, layout: Any, *, volfrac: float = 0.3, radius: float, iterations: int = 100,
    e_min: float = 1e-9,
) -> tuple[SimpResult, float]:  # fmt: skip
    """SIMP + OC on the force inverter (see the module): minimise ``u_out``.

    Returns the result (``objective``: ``u_out`` per iteration) and the final ``u_in``.
    ``e_min = 1e-9`` is the textbook's (``x_min = 1e-3`` to the power 3).
    """
    from .filtered import density_filter

    _check(volfrac, iterations)
    H = density_filter(body.body.centroids, body.area, radius)
    area = body.area
    x = np.full(body.n_elements, float(volfrac))
    volume = volfrac * area.sum()
    t0 = time.perf_counter()
    objective, times = [], []
    u_in = 0.0
    for it in range(iterations + 1):
        xt = H @ x
        s, ds = simp_modulus(xt, e_min=e_min)
        last = it == iterations
        u_in, u_out, g = inverter_response(body, layout, s, adjoint=not last)
        objective.append(u_out)
        times.append(time.perf_counter() - t0)
        if last:
            break
        x = oc_update(x, H.T @ (g * ds), H.T @ area, volume, H, area)
    xt = H @ x
    res = SimpResult(
        density=xt, modulus=simp_modulus(xt, e_min=e_min)[0], objective=np.array(objective),
        volume=float(area @ xt / area.sum()), iterations=iterations, solves=iterations + 1,
        seconds=time.perf_counter() - t0, times=np.array(times),
    )  # fmt: skip
    return res, u_in
