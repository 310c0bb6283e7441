"""Allosteric tasks on a continuum: material springs as sources and targets.

A *material spring* between material points ``a`` and ``b`` reads the relative extension
``(u(b) - u(a)) . e_ab / |ab|`` (a linear functional of the displacement:
:func:`~.probes.chord_strain_probe`). On P1 elements over a lattice's own triangles it is
exactly a spring's strain in linear response. Sources clamp it exactly (a Lagrange
multiplier); targets are read from it. The strain is measured against the undeformed body,
the network's ``strain_reference="initial"`` convention (a material point has no rest
length of its own).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MaterialTask"]

_FIELDS = (
    "source_a",
    "source_b",
    "source_strain",
    "target_a",
    "target_b",
    "target_strain",
    "fixed",
    "radius",
)


def _frozen(value: ArrayLike, shape: tuple, name: str, dtype=np.float64) -> NDArray:
    arr = np.array(value, dtype=dtype, copy=True)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if dtype is np.float64 and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class MaterialTask:
    """Source material springs clamped at strains; target material springs to reach strains.

    Attributes
    ----------
    source_a, source_b : (n_sources, 2) float arrays
        End points of the source springs (material points of the undeformed body).
    source_strain : (n_sources,) float array
    target_a, target_b : (n_targets, 2) float arrays
    target_strain : (n_targets,) float array
        Desired free-state strains.
    fixed : (n_fixed,) int array
        Displacement DOFs held at zero in every state (rigid-body motion removed).
    radius : float
        Size of a spring's ends (length units, >= 0): 0 reads the displacement at the
        points ``a`` and ``b``; > 0 its area mean over a disc of that radius about each
        (:func:`~.probes.material_spring_probe`), a clamp with a size of its own.
    """

    source_a: NDArray[np.float64]
    source_b: NDArray[np.float64]
    source_strain: NDArray[np.float64]
    target_a: NDArray[np.float64]
    target_b: NDArray[np.float64]
    target_strain: NDArray[np.float64]
    fixed: NDArray[np.int64]
    radius: float = 0.0

    def __post_init__(self) -> None:
        ns = np.shape(self.source_strain)[0] if np.ndim(self.source_strain) else -1
        nt = np.shape(self.target_strain)[0] if np.ndim(self.target_strain) else -1
        if ns < 1 or nt < 1:
            raise ValueError("a material task needs at least one source and one target")
        vals = {
            "source_a": _frozen(self.source_a, (ns, 2), "source_a"),
            "source_b": _frozen(self.source_b, (ns, 2), "source_b"),
            "source_strain": _frozen(self.source_strain, (ns,), "source_strain"),
            "target_a": _frozen(self.target_a, (nt, 2), "target_a"),
            "target_b": _frozen(self.target_b, (nt, 2), "target_b"),
            "target_strain": _frozen(self.target_strain, (nt,), "target_strain"),
            "fixed": _frozen(
                np.unique(np.asarray(self.fixed, np.int64)),
                (np.unique(np.asarray(self.fixed)).size,),
                "fixed",
                np.int64,
            ),
        }
        for name, v in vals.items():
            object.__setattr__(self, name, v)
        radius = float(np.asarray(self.radius))
        if not (np.isfinite(radius) and radius >= 0):
            raise ValueError(f"radius must be finite and >= 0, got {self.radius!r}")
        object.__setattr__(self, "radius", radius)
        for kind in ("source", "target"):
            d = vals[f"{kind}_b"] - vals[f"{kind}_a"]
            if np.any(np.hypot(d[:, 0], d[:, 1]) == 0):
                raise ValueError(f"every {kind} spring needs two distinct end points")
        if self.fixed.size < 3:
            raise ValueError(
                f"fixed must hold at least 3 DOFs (rigid-body motion), got {self.fixed.size}"
            )

    @property
    def n_sources(self) -> int:
        return int(self.source_strain.size)

    @property
    def n_targets(self) -> int:
        return int(self.target_strain.size)

    @property
    def target_length(self) -> NDArray[np.float64]:
        """Undeformed lengths ``|b - a|`` of the target springs, (n_targets,)."""
        return np.hypot(*(self.target_b - self.target_a).T)

    def check(self, medium) -> None:
        """Raise ``ValueError`` if the task does not fit the body of ``medium``."""
        n = medium.n_dofs
        if self.fixed.size and (self.fixed[0] < 0 or self.fixed[-1] >= n):
            raise ValueError(f"fixed names DOFs outside 0..{n - 1}")

    def error(self, target_strain: ArrayLike) -> float:
        """Task error ``C = sum_T (S_T^F - S_T)^2 / 2`` (Eq. 26) of free target strains."""
        d = np.asarray(target_strain, float) - self.target_strain
        return float(0.5 * np.sum(d**2))

    def to_arrays(self) -> dict[str, NDArray]:
        """Plain arrays (the fields) for files."""
        return {f: np.asarray(getattr(self, f)) for f in _FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> MaterialTask:
        """Inverse of :meth:`to_arrays`."""
        return cls(**{f: np.asarray(arrays[f]) for f in _FIELDS if f in arrays})

    @classmethod
    def from_network(cls, net, task, body) -> MaterialTask:
        """The network task ``task`` on ``body``: every source and target spring becomes
        the material spring between its end nodes' positions, with the same strains; the
        network's pinned coordinates become the fixed DOFs at those nodes' positions.

        Parameters
        ----------
        net : SpringNetwork
        task : AllosteryTask
        body : LearnableBody or ElasticBody
            A body whose mesh has a vertex at every pinned node (for example one built on
            :func:`~.mesh.network_mesh` of ``net``).
        """
        x = net.positions
        s, t = net.springs[task.sources], net.springs[task.targets]
        elastic = getattr(body, "body", body)
        loc, comp = elastic.dof_locations, elastic.dof_component
        fixed = []
        tol = 1e-9 * max(1.0, float(np.ptp(x)))
        for node, c in zip(*np.nonzero(task.pinned)):
            hit = np.flatnonzero((np.hypot(*(loc - x[node]).T) <= tol) & (comp == c))
            if hit.size != 1:
                raise ValueError(f"pinned node {node} is not a vertex of the body's mesh")
            fixed.append(int(hit[0]))
        return cls(
            source_a=x[s[:, 0]],
            source_b=x[s[:, 1]],
            source_strain=task.source_strain,
            target_a=x[t[:, 0]],
            target_b=x[t[:, 1]],
            target_strain=task.target_strain,
            fixed=np.array(fixed, dtype=np.int64),
        )
