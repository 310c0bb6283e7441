"""A modulus field with a length scale: the density filter, and a medium that learns through it.

A modulus field learned element by element has no length scale: refined, it gathers onto
the clamps (a point constraint in 2D has a singular force, and nothing stops a field from
following it). Topology optimisation meets the same problem with a *density filter*
(Bruns & Tortorelli 2001; Sigmund 2007): the modulus of an element is the weighted mean of a
design variable over a disc of fixed radius ``r``,

    s_e = sum_j H_ej rho_j,   H_ej = w_ej A_j / sum_k w_ek A_k,   w_ej = max(0, r - |c_e - c_j|)

(``c`` element centroids, ``A`` areas; a cone of radius ``r``). ``H`` is non-negative with
rows that sum to 1, so it keeps a constant field and the bounds of ``rho`` hold for ``s``.
A material that learns this way needs the same ingredient physically: whatever sets its
local stiffness (a growth factor, a crosslinker) spreads over a distance ``r`` rather than
staying in one element, which is what makes the learned field a property of the material and
not of the mesh.

:class:`FilteredModulus` is a learning medium (:mod:`~continuum_vs_network.learning.medium`)
whose learning dof is ``rho``: the rule objects train it unchanged. Its local signals are
the body's, carried back through the filter (chain rule): per unit area of element ``j``,
``g_rho_j = (1 / A_j) sum_e H_ej A_e g_e`` with ``g_e`` the body's per-area signal (the
energy difference of coupled learning, the adjoint gradient of the exact gradient). Elements
frozen by a task (its sources' and targets' own material) keep ``s_e = rho_e``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

__all__ = ["FilteredModulus", "density_filter", "filtered_modulus"]


def density_filter(
    centroids: ArrayLike, area: ArrayLike, radius: float, *, frozen: ArrayLike | None = None
) -> sp.csr_matrix:
    """The density filter ``H`` (n, n) of the module: cone weights of ``radius``.

    Parameters
    ----------
    centroids : (n, 2) float array
        Element centroids (length units).
    area : (n,) float array
        Element areas (> 0).
    radius : float
        Filter radius (length units, >= 0; 0 or below the element spacing: the identity).
    frozen : (n,) bool array, optional
        Elements whose value is their own (rows of the identity).
    """
    from scipy.spatial import cKDTree

    c = np.asarray(centroids, dtype=float)
    a = np.asarray(area, dtype=float)
    n = c.shape[0]
    if c.shape != (n, 2) or a.shape != (n,):
        raise ValueError(f"centroids must be (n, 2) and area (n,), got {c.shape}, {a.shape}")
    if not (np.isfinite(radius) and radius >= 0):
        raise ValueError(f"radius must be finite and >= 0, got {radius}")
    if np.any(a <= 0):
        raise ValueError("area must be > 0 in every element")
    tree = cKDTree(c)
    dist = tree.sparse_distance_matrix(tree, radius, output_type="coo_matrix")
    w = np.maximum(0.0, radius - dist.data)
    keep = w > 0
    W = sp.coo_matrix((w[keep] * a[dist.col[keep]], (dist.row[keep], dist.col[keep])), (n, n))
    W = (W + sp.identity(n) * 1e-300).tocsr()  # every row holds its diagonal
    H = sp.diags(1.0 / np.asarray(W.sum(axis=1)).ravel()) @ W
    if frozen is not None:
        f = np.asarray(frozen, dtype=bool)
        if f.shape != (n,):
            raise ValueError(f"frozen must have shape ({n},), got {f.shape}")
        H = sp.diags((~f).astype(float)) @ H + sp.diags(f.astype(float))
    H = H.tocsr()
    H.eliminate_zeros()
    return H


@dataclass(frozen=True, eq=False)
class FilteredModulus:
    """A learnable body whose modulus is the filtered design ``s = H rho`` (see the module).

    Build with :func:`filtered_modulus`. Attributes: ``body`` (the LearnableBody at
    ``s = H rho``), ``design`` (n_elements,) ``rho``, ``weights`` (n, n) ``H``, ``radius``.
    """

    body: Any
    design: NDArray[np.float64]
    weights: sp.csr_matrix
    radius: float

    # -- what callers read of a body --------------------------------------------------
    @property
    def n_elements(self) -> int:
        return self.body.n_elements

    @property
    def n_dofs(self) -> int:
        return self.body.n_dofs

    @property
    def area(self) -> NDArray[np.float64]:
        return self.body.area

    @property
    def modulus(self) -> NDArray[np.float64]:
        return self.body.modulus

    @property
    def eigenstrain(self) -> NDArray[np.float64]:
        return self.body.eigenstrain

    def with_design(self, design: ArrayLike) -> FilteredModulus:
        """A copy with a new design (n_elements,) >= 0 (and its modulus ``H rho``)."""
        rho = np.array(np.broadcast_to(np.asarray(design, float), (self.n_elements,)))
        if not np.all(np.isfinite(rho)) or np.any(rho < 0):
            raise ValueError("design must be finite and >= 0 in every element")
        rho.setflags(write=False)
        body = self.body.with_modulus(self.weights @ rho)
        return dataclasses.replace(self, body=body, design=rho)

    def pull_back(self, g: NDArray) -> NDArray[np.float64]:
        """A per-area signal of the filtered field, (n,) or (n, k), as the per-area signal
        of its design."""
        a = self.body.area[:, None] if np.ndim(g) == 2 else self.body.area
        return (self.weights.T @ (a * g)) / a

    # -- the learning-medium protocol --------------------------------------------------
    def learning_dof(self, dof: str) -> str:
        """``"modulus"`` (also named ``"stiffness"``): the one field that learns here."""
        if dof not in ("modulus", "stiffness"):
            raise ValueError(
                f"dof must be 'modulus' (or 'stiffness') on a FilteredModulus, got {dof!r}"
            )
        return "modulus"

    def parameters(self, dof: str) -> NDArray[np.float64]:
        self.learning_dof(dof)
        return self.design

    def with_parameters(self, dof: str, values: ArrayLike) -> FilteredModulus:
        self.learning_dof(dof)
        return self.with_design(values)

    def check_task(self, task: Any) -> None:
        self.body.check_task(task)

    def free_state(self, task: Any, *, tracker: Any = None) -> Any:
        return self.body.free_state(task, tracker=tracker)

    def clamped_state(self, task: Any, target_strain: ArrayLike, *, tracker: Any = None) -> Any:
        return self.body.clamped_state(task, target_strain, tracker=tracker)

    def local_gradient(self, state: Any, dof: str, *, minus: Any = None) -> NDArray[np.float64]:
        return self.pull_back(self.body.local_gradient(state, self.learning_dof(dof), minus=minus))

    def task_gradient(
        self, task: Any, free: Any, dof: str, *, cost: str = "strain", tracker: Any = None
    ) -> NDArray[np.float64]:
        g = self.body.task_gradient(task, free, self.learning_dof(dof), cost=cost, tracker=tracker)
        return self.pull_back(g)

    def learning_mask(
        self, task: Any, *, learn_sources: bool = True, learn_targets: bool = True
    ) -> NDArray[np.bool_]:
        return self.body.learning_mask(
            task, learn_sources=learn_sources, learn_targets=learn_targets
        )

    def floor(self, dof: str, raw: NDArray, minimum: float | None) -> NDArray:
        """``raw`` with decreases of the design stopped at ``minimum`` (so ``s >= minimum``)."""
        if minimum is None:
            return raw
        old = self.design
        return np.maximum(old + raw, np.minimum(old, minimum)) - old

    def apply_update(self, dof: str, delta: ArrayLike) -> FilteredModulus:
        self.learning_dof(dof)
        new = self.design + np.asarray(delta, float)
        if np.any(new < 0):
            j = int(np.argmin(new))
            raise ValueError(
                f"design of element {j} would become {new[j]:.3g} < 0; set min_stiffness"
            )
        return self.with_design(new)

    def measurements(self, task: Any, free: Any, dof: str, mask: NDArray) -> dict[str, Any]:
        return self.body.measurements(task, free, "modulus", mask)

    def vertex_positions(self, u: ArrayLike) -> NDArray[np.float64]:
        return self.body.vertex_positions(u)

    def to_arrays(self) -> dict[str, NDArray]:
        H = self.weights.tocsr()
        return {
            **self.body.to_arrays(),
            "design": self.design,
            "radius": np.array(self.radius),
            "H_data": H.data,
            "H_indices": H.indices,
            "H_indptr": H.indptr,
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> FilteredModulus:
        from .learnable import LearnableBody

        body = LearnableBody.from_arrays(arrays)
        n = body.n_elements
        H = sp.csr_matrix((arrays["H_data"], arrays["H_indices"], arrays["H_indptr"]), (n, n))
        return cls(body, np.asarray(arrays["design"], float), H, float(arrays["radius"]))

    def __repr__(self) -> str:
        return f"FilteredModulus({self.body!r}, radius={self.radius:g})"


def filtered_modulus(
    body: Any, radius: float, *, design: ArrayLike = 1.0, task: Any = None
) -> FilteredModulus:
    """A :class:`FilteredModulus` on ``body`` (LearnableBody) with filter ``radius`` (length
    units) and initial ``design`` (scalar or (n_elements,), >= 0). With ``task`` (a
    MaterialTask), the elements of its sources' and targets' material (the body's
    :meth:`~.learnable.LearnableBody.learning_mask` with nothing learning there) are kept out
    of the filter: their modulus is their own design value."""
    frozen = None
    if task is not None:
        frozen = ~body.learning_mask(task, learn_sources=False, learn_targets=False)
    H = density_filter(body.body.centroids, body.area, radius, frozen=frozen)
    out = FilteredModulus(body, np.zeros(body.n_elements), H, float(radius))
    return out.with_design(design)
