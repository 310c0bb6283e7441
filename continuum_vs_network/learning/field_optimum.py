"""The exact optimum of a continuum's modulus field: what the task allows within the range.

:func:`field_optimum` minimises a task's error ``C`` (Eq. 26 of the material springs'
strains) over the design of a :class:`~.filtered.FilteredModulus` (or the modulus of a
:class:`~.learnable.LearnableBody`) with L-BFGS-B (scipy) on the exact (adjoint) gradient
that :class:`~continuum_vs_network.ExactGradient` uses (the medium's ``task_gradient``, the
same masks), within the physical range of the stiffnesses relative to the untrained field
(:data:`~continuum_vs_network.learning.ranges.STIFFNESS_RANGE`).

The search runs in ``y = log(design)`` (gradient ``design * dC/d design``; the bounds become
``log`` of the range; an elastic response depends on modulus *ratios*, so ``dC/ds`` scales
as ``1/s``), each variable weighted by ``sqrt(area / total area)`` of its element: the
gradient of an element's value scales with its area, and weighted, the steps and the
gradient's norm do not change with the element size, nor does the number of evaluations
(``docs/solver-notes.md#field-optimum``). It is the continuum's
:func:`~continuum_vs_network.learning.optimum.exact_optimum`, and its result has the same
shape (:class:`FieldOptimum`). Each evaluation is one factorisation, one free state and one
adjoint (no further solve, :mod:`~continuum_vs_network.continuum.learning_states`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .ranges import STIFFNESS_RANGE, check_range

__all__ = ["FieldOptimum", "field_optimum"]


@dataclass(frozen=True, eq=False)
class FieldOptimum:
    """Result of :func:`field_optimum`.

    Attributes
    ----------
    medium : FilteredModulus or LearnableBody
        The medium at the optimum.
    error, error_initial : float
        ``C`` at the optimum and of the starting medium.
    iterations, evaluations : int
        L-BFGS-B iterations; evaluations (one factorisation and free state each).
    converged : bool
    message : str
    contrast : float
        ``max(s) / min(s)`` of the learning elements' modulus at the optimum.
    seconds : float
        Wall-clock time of the search.
    errors, times : (evaluations,) float arrays
        ``C`` and the cumulative seconds at every evaluation (error against run time).
    """

    medium: Any
    error: float
    error_initial: float
    iterations: int
    evaluations: int
    converged: bool
    message: str
    contrast: float
    seconds: float
    errors: NDArray[np.float64]
    times: NDArray[np.float64]

    @property
    def ratio(self) -> float:
        """``C / C0``."""
        return self.error / self.error_initial


def field_optimum(
    medium: Any,
    task: Any,
    *,
    dof: str = "modulus",
    stiffness_range: tuple[float, float] | None = STIFFNESS_RANGE,
    eigenstrain_range: tuple[float, float] | None = None,
    max_iter: int = 200,
    rtol: float = 1e-6,
    log: bool = True,
) -> FieldOptimum:
    """Minimise ``C`` over the learning elements' design of ``dof`` (see the module).

    Parameters
    ----------
    medium : FilteredModulus, LearnableBody or FilteredFields
        The untrained medium: the range and ``error_initial`` refer to it.
    task : MaterialTask (MaterialExamples on a FilteredFields: the summed error)
    dof : str
        ``"modulus"`` (default), or on a
        :class:`~.filtered_fields.FilteredFields` ``"eigenstrain"`` or ``"both"``: the
        columns of ``medium.parameters(dof)``, the modulus column (``"both"``: column 0)
        searched in ``log`` and bounded by ``stiffness_range``, the eigenstrain columns
        (Mandel components of the design, in the medium's strain unit ``scale``) in the
        design itself, bounded by ``eigenstrain_range``.
    stiffness_range : (low, high) or None
        Each modulus design value stays within ``[low, high]`` times its initial value
        (None: only ``>= 0``).
    eigenstrain_range : (low, high) or None
        Bounds of every eigenstrain design value (units of the medium's ``scale``); None
        (default): unbounded.
    max_iter : int
        Most L-BFGS-B iterations (>= 1).
    rtol : float
        Stop as soon as ``C / C0 <= rtol`` (> 0).
    log : bool
        Search the modulus in ``log(design)`` (default; needs a range with ``low > 0``),
        else in the design itself.
    """
    from scipy.optimize import minimize

    rng_ = check_range("stiffness_range", stiffness_range)
    if eigenstrain_range is not None:
        lo_e, hi_e = (float(v) for v in eigenstrain_range)
        if not lo_e < hi_e:
            raise ValueError(f"eigenstrain_range must have low < high, got {eigenstrain_range!r}")
    if int(max_iter) != max_iter or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not (np.isfinite(rtol) and rtol > 0):
        raise ValueError(f"rtol must be a finite number > 0, got {rtol!r}")
    d = medium.learning_dof(dof) if hasattr(medium, "learning_dof") else dof
    if d not in ("modulus", "eigenstrain", "both"):
        raise ValueError(f"dof must be 'modulus', 'eigenstrain' or 'both', got {dof!r}")
    medium.check_task(task)
    p0 = np.array(medium.parameters(d), dtype=float)
    shape = p0.shape
    cols = p0.reshape(shape[0], -1)
    ncol = cols.shape[1]
    # which columns are modulus (log, stiffness range) and which eigenstrain (linear)
    is_mod = np.zeros(ncol, bool)
    if d in ("modulus", "both"):
        is_mod[0] = True
    elem_mask = medium.learning_mask(task, learn_sources=False, learn_targets=False)
    mask = np.repeat(elem_mask[:, None], ncol, axis=1)
    area = medium.area
    e0 = task.error(medium.free_state(task).target_strain)
    if e0 == 0:
        raise ValueError("the untrained medium already meets the task (C0 = 0)")
    low = np.full_like(cols, -np.inf)
    high = np.full_like(cols, np.inf)
    if eigenstrain_range is not None:
        low[:, ~is_mod], high[:, ~is_mod] = lo_e, hi_e
    x0m = cols[:, is_mod]
    low[:, is_mod] = x0m * (rng_[0] if rng_ else 0.0)
    high[:, is_mod] = x0m * rng_[1] if rng_ else np.inf
    logm = is_mod & bool(log)
    if np.any(logm) and not (np.all(low[:, logm][elem_mask] > 0) and np.all(x0m > 0)):
        raise ValueError("log=True needs a stiffness_range with low > 0 and a design > 0")
    y0 = cols.copy()
    if np.any(logm):
        y0[:, logm] = np.log(cols[:, logm])
        low[:, logm] = np.log(np.where(elem_mask[:, None], low[:, logm], 1.0))
        high[:, logm] = np.log(np.where(elem_mask[:, None], high[:, logm], 1.0))

    def to_x(y: NDArray) -> NDArray:
        x = np.array(y, dtype=float).reshape(cols.shape)
        if np.any(logm):
            x[:, logm] = np.exp(x[:, logm])
        return x

    def as_param(x: NDArray) -> NDArray:
        return x.reshape(shape)

    # the search runs in z = w y, w = sqrt(area / total area): the Euclidean metric of z is
    # the field's area-weighted mean square, so neither the steps nor the gradient's norm
    # change with the element size (in y, the gradient scales with the area)
    w = np.sqrt(area / area.sum())[:, None] * np.ones((1, ncol))
    bounds = [
        (None if not np.isfinite(lo) else lo * s, None if not np.isfinite(hi) else hi * s) if m
        else (v * s, v * s)
        for lo, hi, v, m, s in zip(low.ravel(), high.ravel(), y0.ravel(), mask.ravel(), w.ravel())
    ]  # fmt: skip
    a = area[:, None]
    errors: list[float] = []
    times: list[float] = []
    best = [np.inf, cols]
    t0 = time.perf_counter()

    class _Done(Exception):
        pass

    def fun(z: NDArray) -> tuple[float, NDArray]:
        x = to_x(z / w.ravel())
        m = medium.with_parameters(d, as_param(x))
        free = m.free_state(task)
        c = task.error(free.target_strain)
        g = np.asarray(m.task_gradient(task, free, d), float).reshape(cols.shape) * a
        g = np.where(mask, g, 0.0)
        g[:, logm] = g[:, logm] * x[:, logm]
        errors.append(c / e0)
        times.append(time.perf_counter() - t0)
        if c < best[0]:
            best[0], best[1] = c, np.array(x)
        if c <= rtol * e0:
            raise _Done
        return c / e0, (g / w).ravel() / e0

    try:
        res = minimize(
            fun, (y0 * w).ravel(), jac=True, method="L-BFGS-B", bounds=bounds,
            options={"maxiter": int(max_iter), "ftol": 1e-15, "gtol": 1e-14},
        )  # fmt: skip
        nit, converged, message = int(res.nit), bool(res.success), str(res.message)
    except _Done:
        nit, converged, message = -1, True, f"C <= {rtol:g} C0"
    out = medium.with_parameters(d, as_param(best[1]))
    s = out.modulus[elem_mask]
    return FieldOptimum(
        medium=out,
        error=float(best[0]),
        error_initial=float(e0),
        iterations=nit,
        evaluations=len(errors),
        converged=converged,
        message=message,
        contrast=float(s.max() / s.min()) if s.size and s.min() > 0 else float("inf"),
        seconds=time.perf_counter() - t0,
        errors=np.array(errors),
        times=np.array(times),
    )
