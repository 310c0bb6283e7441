"""The continuum's mechanism tasks: an allosteric 1 -> 1 task between disc-ended material
springs, its rest example, and the classical force inverter's layout.

The body is the rectangle ``[0, width] x [0, height]`` (structured triangles,
:func:`mechanism_mesh`; ``refine`` halves the element size ``refine`` times, nested).

Allosteric task (:func:`allosteric_task`): the source is a material spring between two
small discs (radius ``radius``) a distance ``gap`` apart, centred at ``source`` and
oriented along ``direction``: clamped at strain ``source_strain``, it is the continuum's
clamped spring. The target is the same at ``target``; it should follow at ``ratio``:
``S_T = ratio * S_S``. Rigid motion is removed by three fixed DOFs at the middle of the
bottom and top edges (``x, y`` at the bottom, ``x`` at the top): the clamps are internal
(equal and opposite forces), so these carry no load. The rest example
(:func:`rest_example`: sources at 0, targets at 0) is the network's anchor
(:func:`~continuum_vs_network.learning.examples.anchored`); a modulus field learned without
eigenstrain meets it identically (its free state is ``u = 0``), which the scene measures
rather than assumes.

Force inverter (:func:`inverter_layout`; Sigmund 1997, and the textbook's half model,
Bendsøe & Sigmund 2003, sec. 2.6): the half ``[0, 2] x [0, 1]`` of a 2 x 2 square, the
symmetry line at ``y = 1`` (``u_y = 0`` there), the corner ``(0, 0)`` fixed, an input force
``f_in`` in ``+x`` at ``(0, 1)`` against an input spring ``k_in``, and an output spring
``k_out`` at ``(2, 1)``; the mechanism should move its output in ``-x``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check

__all__ = [
    "InverterLayout",
    "allosteric_task",
    "inverter_layout",
    "mechanism_mesh",
    "nearest_dofs",
    "rest_example",
]


def _positive(name: str, value: float) -> float:
    return check.real(name, value, low=0, low_open=True)


def mechanism_mesh(width: float, height: float, h: float, *, refine: int = 0) -> Any:
    """Structured ``MeshTri1`` of ``[0, width] x [0, height]`` with element size ``h``,
    refined ``refine`` times (each refinement splits a triangle in four: nested meshes)."""
    from .mesh import rectangle_mesh

    if int(refine) != refine or refine < 0:
        raise ValueError(f"refine must be an integer >= 0, got {refine!r}")
    mesh = rectangle_mesh(_positive("width", width), _positive("height", height), h=h)
    return mesh.refined(int(refine)) if refine else mesh


def nearest_dofs(body: Any, point: ArrayLike, components: tuple[int, ...]) -> NDArray[np.int64]:
    """The displacement DOFs (``components`` of ``0, 1``) of the vertex nearest ``point``."""
    eb = getattr(body, "body", body)
    loc, comp = eb.dof_locations, eb.dof_component
    x = np.asarray(point, dtype=float)
    d = np.hypot(*(loc - x).T)
    node = d <= d.min() + 1e-12 * max(1.0, float(np.ptp(loc)))
    out = [int(np.flatnonzero(node & (comp == c))[0]) for c in components]
    return np.array(out, dtype=np.int64)


def _ends(centre: ArrayLike, direction: ArrayLike, gap: float) -> tuple[NDArray, NDArray]:
    c = np.asarray(centre, dtype=float).reshape(2)
    d = np.asarray(direction, dtype=float).reshape(2)
    n = np.hypot(*d)
    if not n > 0:
        raise ValueError(f"direction must be a non-zero vector, got {direction!r}")
    half = 0.5 * _positive("gap", gap) * d / n
    return c - half, c + half


def allosteric_task(
    body: Any,
    *,
    source: ArrayLike,
    target: ArrayLike,
    gap: float,
    radius: float,
    source_strain: float,
    ratio: float,
    direction: ArrayLike = (0.0, 1.0),
):
    """The 1 -> 1 allosteric task of the module on ``body`` (LearnableBody or ElasticBody).

    Parameters
    ----------
    source, target : (2,) float
        Centres of the source and target material springs (length units).
    gap : float
        Distance between a spring's two disc centres (> 0).
    radius : float
        Disc radius of the ends (>= 0; 0: point ends, no length scale).
    source_strain : float
        Clamped strain of the source.
    ratio : float
        ``S_T / S_S`` asked for.
    direction : (2,) float
        Orientation of both springs (default vertical).

    Returns
    -------
    MaterialTask
    """
    from .material_task import MaterialTask

    sa, sb = _ends(source, direction, gap)
    ta, tb = _ends(target, direction, gap)
    lo = body.body.mesh.p.min(axis=1) if hasattr(body, "body") else body.mesh.p.min(axis=1)
    hi = body.body.mesh.p.max(axis=1) if hasattr(body, "body") else body.mesh.p.max(axis=1)
    mid = 0.5 * (lo[0] + hi[0])
    fixed = np.concatenate(
        [nearest_dofs(body, (mid, lo[1]), (0, 1)), nearest_dofs(body, (mid, hi[1]), (0,))]
    )
    s = float(source_strain)
    return MaterialTask(
        source_a=sa[None], source_b=sb[None], source_strain=[s],
        target_a=ta[None], target_b=tb[None], target_strain=[float(ratio) * s],
        fixed=fixed, radius=float(radius),
    )  # fmt: skip


def rest_example(task: Any):
    """The task's rest example: the same springs, sources and targets at strain 0."""
    import dataclasses

    return dataclasses.replace(
        task,
        source_strain=np.zeros(task.n_sources),
        target_strain=np.zeros(task.n_targets),
    )


@dataclass(frozen=True)
class InverterLayout:
    """Where the force inverter is held, pushed and read (see the module).

    Attributes
    ----------
    fixed : (n_fixed,) int array
        DOFs at zero: ``u_y`` on the symmetry line ``y = height``, both at ``(0, 0)``.
    input_dof, output_dof : int
        ``u_x`` at ``(0, height)`` and at ``(width, height)``.
    force, k_in, k_out : float
        Input force and the input and output springs (force / length).
    """

    fixed: NDArray[np.int64]
    input_dof: int
    output_dof: int
    force: float
    k_in: float
    k_out: float


def inverter_layout(
    body: Any, *, force: float = 1.0, k_in: float = 0.1, k_out: float = 0.1
) -> InverterLayout:
    """The inverter's supports, input and output on ``body``'s rectangle (see the module)."""
    eb = getattr(body, "body", body)
    lo, hi = eb.mesh.p.min(axis=1), eb.mesh.p.max(axis=1)
    loc, comp = eb.dof_locations, eb.dof_component
    top = np.flatnonzero((np.abs(loc[:, 1] - hi[1]) <= 1e-9 * (hi[1] - lo[1])) & (comp == 1))
    fixed = np.union1d(top, nearest_dofs(eb, lo, (0, 1)))
    return InverterLayout(
        fixed=fixed.astype(np.int64),
        input_dof=int(nearest_dofs(eb, (lo[0], hi[1]), (0,))[0]),
        output_dof=int(nearest_dofs(eb, (hi[0], hi[1]), (0,))[0]),
        force=float(force),
        k_in=_positive("k_in", k_in),
        k_out=_positive("k_out", k_out),
    )
