"""A learnable elastic material: element-wise eigenstrain and modulus fields (scikit-fem).

Energy of a body with per-element eigenstrain (rest strain) ``eps0_e`` and modulus scale
``s_e`` (plane strain or plane stress through the 2D Lamé parameters of its ``Material``)::

    E(u) = sum_e s_e / 2 int_e (eps(u) - eps0_e) : C_e : (eps(u) - eps0_e) dA

``eps0`` plays the spring rest length's role (learning dof ``"eigenstrain"``), ``s`` the
spring stiffness's (dof ``"modulus"``). Strains are held in Mandel form
``m = (eps_xx, eps_yy, sqrt(2) eps_xy)``, in which ``eps : C : eps = m . C_m . m`` and the
Euclidean norm is the Frobenius norm; fields are reported as tensors
``(eps_xx, eps_yy, eps_xy)``.

The element operators (stiffness of a unit modulus ``K_e``, eigenstrain coupling
``G_e = int B^T C``, integrated strain ``int B``) are computed once per mesh; the global
stiffness for any modulus field is then one weighted sum into a fixed sparsity pattern.

Local quantities (per unit area of the element, so that a learning rate is a property of
the material, not of the mesh; derived in :mod:`.learning_states`):

- ``dE/d eps0_e = -s_e C_e : (<eps>_e - eps0_e)`` (``<eps>_e``: the element's mean strain);
- ``dE/d s_e = (1/2) <(eps - eps0) : C_e : (eps - eps0)>_e`` (its mean energy density at
  unit modulus).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from .element_operators import ISOTROPIC, _Operators, _operators, mandel, tensor
from .materials import Material

__all__ = [
    "EigenstrainKind",
    "LearnableBody",
    "MaterialDof",
    "learnable_body",
]

MaterialDof = Literal["eigenstrain", "modulus"]
EigenstrainKind = Literal["tensor", "isotropic"]


@dataclass(frozen=True, eq=False)
class LearnableBody:
    """An elastic body whose eigenstrain and modulus fields learn (a learning medium).

    Build with :func:`learnable_body`; change with :meth:`with_eigenstrain`,
    :meth:`with_modulus`. The same rule objects and :func:`~continuum_vs_network.train`
    that train a :class:`~continuum_vs_network.SpringNetwork` train it (the medium
    protocol: :mod:`continuum_vs_network.learning.medium`).

    Attributes
    ----------
    body : ElasticBody
        Mesh, P1/P2 basis and Lamé parameters (plane strain or stress via the Material).
    eigenstrain : (n_elements, 3) float array
        Rest strain of each element, tensor components ``(xx, yy, xy)``.
    modulus : (n_elements,) float array
        Modulus scale ``s_e >= 0`` of each element (1: the body's material).
    kind : {"tensor", "isotropic"}
        What an eigenstrain update may change: the full symmetric tensor, or only a
        dilation ``e I`` (then an update is ``(n_elements,)``).
    """

    body: Any
    eigenstrain: NDArray[np.float64]
    modulus: NDArray[np.float64]
    kind: EigenstrainKind = "tensor"
    _ops: _Operators = field(default=None, repr=False)  # type: ignore[assignment]
    _cache: dict = field(default_factory=dict, repr=False)

    # -- sizes ------------------------------------------------------------------------
    @property
    def n_elements(self) -> int:
        return self.body.n_elements

    @property
    def n_dofs(self) -> int:
        return self.body.n_dofs

    @property
    def area(self) -> NDArray[np.float64]:
        """Element areas, (n_elements,)."""
        return self._ops.area

    def unit_shape(self, dof: MaterialDof) -> tuple[int, ...]:
        """Shape of one update of ``dof``: (n_elements,) or (n_elements, 3)."""
        if dof == "eigenstrain" and self.kind == "tensor":
            return (self.n_elements, 3)
        return (self.n_elements,)

    # -- changed copies ---------------------------------------------------------------
    def with_eigenstrain(self, eigenstrain: ArrayLike) -> LearnableBody:
        """A copy with a new eigenstrain field ((n, 3) tensor, or (n,) dilations ``e I``).
        The stiffness factorisations are shared (they do not depend on it)."""
        e = _eigenstrain(eigenstrain, self.n_elements)
        return dataclasses.replace(self, eigenstrain=e, _cache=self._cache)

    def with_modulus(self, modulus: ArrayLike) -> LearnableBody:
        """A copy with a new modulus field (n_elements,) >= 0."""
        s = _modulus(modulus, self.n_elements)
        return dataclasses.replace(self, modulus=s, _cache={})

    def parameters(self, dof: MaterialDof) -> NDArray[np.float64]:
        """The learning degrees of freedom of ``dof``, shaped as an update."""
        if dof == "modulus":
            return self.modulus
        if self.kind == "isotropic":
            return 0.5 * (self.eigenstrain[:, 0] + self.eigenstrain[:, 1])
        return mandel(self.eigenstrain)

    def with_parameters(self, dof: MaterialDof, values: ArrayLike) -> LearnableBody:
        """A copy with the learning degrees of freedom ``values`` (see :meth:`parameters`)."""
        v = np.asarray(values, dtype=float)
        if v.shape != self.unit_shape(dof):
            raise ValueError(f"{dof} values must have shape {self.unit_shape(dof)}, got {v.shape}")
        if dof == "modulus":
            return self.with_modulus(v)
        if self.kind == "isotropic":
            e = self.eigenstrain.copy()
            e[:, :2] += (v - 0.5 * (e[:, 0] + e[:, 1]))[:, None]
            return self.with_eigenstrain(e)
        return self.with_eigenstrain(tensor(v))

    # -- physics ----------------------------------------------------------------------
    def stiffness(self) -> sp.csr_matrix:
        """Global stiffness ``sum_e s_e K_e`` (n_dofs, n_dofs), assembled in the fixed pattern."""
        ops = self._ops
        data = np.bincount(
            ops.scatter,
            weights=(self.modulus[:, None, None] * ops.Ke).ravel(),
            minlength=ops.cols.size,
        )
        return sp.csr_matrix((data, ops.cols, ops.indptr), shape=(ops.n_dofs, ops.n_dofs))

    def load(self) -> NDArray[np.float64]:
        """Eigenstrain load ``sum_e s_e G_e m0_e`` (n_dofs,)."""
        ops = self._ops
        fe = np.einsum("eib,eb->ei", ops.Ge, mandel(self.eigenstrain)) * self.modulus[:, None]
        return np.bincount(ops.edofs.ravel(), weights=fe.ravel(), minlength=ops.n_dofs)

    def energy(self, u: ArrayLike) -> float:
        """Elastic energy ``E(u)`` (energy per thickness)."""
        return float(np.sum(self.modulus * self._unit_energy(np.asarray(u, float))))

    def eigenstrain_energy(self) -> float:
        """Energy of the undeformed body, ``sum_e s_e A_e eps0 : C : eps0 / 2``."""
        ops = self._ops
        m0 = mandel(self.eigenstrain)
        dens = np.einsum("ea,eab,eb->e", m0, ops.C, m0)
        return float(0.5 * np.sum(self.modulus * ops.area * dens))

    def _unit_energy(self, u: NDArray, v: NDArray | None = None) -> NDArray:
        """Per element ``int (eps(u)-eps0):C:(eps(v)-eps0) / 2`` at unit modulus (v=u)."""
        ops = self._ops
        ue = u[ops.edofs]
        ve = ue if v is None else v[ops.edofs]
        m0 = mandel(self.eigenstrain)
        Cm0 = np.einsum("eab,eb->ea", ops.C, m0)
        quad = np.einsum("ei,eij,ej->e", ue, ops.Ke, ve)
        cross = np.einsum("ei,eib,eb->e", ue + ve, ops.Ge, m0)
        const = ops.area * np.einsum("ea,ea->e", m0, Cm0)
        return 0.5 * (quad - cross + const)

    def mean_strain(self, u: ArrayLike) -> NDArray[np.float64]:
        """Mean strain of each element, tensor components (n_elements, 3)."""
        ops = self._ops
        m = np.einsum("eai,ei->ea", ops.Bbar, np.asarray(u, float)[ops.edofs])
        return tensor(m / ops.area[:, None])

    def energy_gradient(
        self, u: ArrayLike, dof: MaterialDof, *, minus: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """``dE/d theta`` per unit element area at fixed displacement ``u`` (see the module).

        With ``minus``, the difference ``dE/dtheta(u) - dE/dtheta(minus)``, computed
        without cancellation (it is linear in ``u - minus`` for the eigenstrain).
        Shape :meth:`unit_shape`.
        """
        ops = self._ops
        u = np.asarray(u, float)
        if dof == "modulus":
            if minus is None:
                return self._unit_energy(u) / ops.area
            w = np.asarray(minus, float)
            d, s = (u - w)[ops.edofs], (u + w)[ops.edofs]
            m0 = mandel(self.eigenstrain)
            diff = 0.5 * np.einsum("ei,eij,ej->e", d, ops.Ke, s)
            diff -= np.einsum("ei,eib,eb->e", d, ops.Ge, m0)
            return diff / ops.area
        if dof != "eigenstrain":
            raise ValueError(f"dof must be 'eigenstrain' or 'modulus', got {dof!r}")
        if minus is None:
            m = np.einsum("eai,ei->ea", ops.Bbar, u[ops.edofs]) / ops.area[:, None]
            m = m - mandel(self.eigenstrain)
        else:
            d = (u - np.asarray(minus, float))[ops.edofs]
            m = np.einsum("eai,ei->ea", ops.Bbar, d) / ops.area[:, None]
        g = -self.modulus[:, None] * np.einsum("eab,eb->ea", ops.C, m)
        return g @ ISOTROPIC if self.kind == "isotropic" else g

    def parameter_gradient(
        self, u: ArrayLike, p: ArrayLike, dof: MaterialDof
    ) -> NDArray[np.float64]:
        """``p . (df/dtheta - dK/dtheta u)`` per unit element area: the adjoint gradient
        of a cost whose adjoint state is ``p`` at the equilibrium ``u``."""
        ops = self._ops
        pe = np.asarray(p, float)[ops.edofs]
        if dof == "modulus":
            ue = np.asarray(u, float)[ops.edofs]
            m0 = mandel(self.eigenstrain)
            fe = np.einsum("eib,eb->ei", ops.Ge, m0) - np.einsum("eij,ej->ei", ops.Ke, ue)
            return np.einsum("ei,ei->e", pe, fe) / ops.area
        g = self.modulus[:, None] * np.einsum("ei,eib->eb", pe, ops.Ge) / ops.area[:, None]
        return g @ ISOTROPIC if self.kind == "isotropic" else g

    def vertex_positions(self, u: ArrayLike) -> NDArray[np.float64]:
        """Deformed vertex positions (n_vertices, 2) for displacement ``u``."""
        from .body import vertex_displacement

        return self.body.mesh.p.T + vertex_displacement(self.body, u)

    # -- the learning-medium protocol (continuum_vs_network.learning.medium) ------------
    def learning_dof(self, dof: str) -> MaterialDof:
        """The field a rule's ``dof`` names here: ``"rest_length"`` / ``"eigenstrain"`` ->
        ``"eigenstrain"``; ``"stiffness"`` / ``"modulus"`` -> ``"modulus"``."""
        table = {
            "rest_length": "eigenstrain",
            "eigenstrain": "eigenstrain",
            "stiffness": "modulus",
            "modulus": "modulus",
        }
        if dof not in table:
            raise ValueError(
                f"dof must be 'eigenstrain' (or 'rest_length') or 'modulus' (or 'stiffness') "
                f"on a LearnableBody, got {dof!r}"
            )
        return table[dof]  # type: ignore[return-value]

    def check_task(self, task: Any) -> None:
        """Raise ``ValueError`` unless ``task`` is a MaterialTask that fits this body."""
        from .material_task import MaterialTask

        if not isinstance(task, MaterialTask):
            raise ValueError(f"a LearnableBody learns a MaterialTask, got {type(task).__name__}")
        task.check(self)

    def free_state(self, task: Any, *, tracker: Any = None) -> Any:
        """Sources clamped: :func:`.learning_states.free_state`."""
        from .learning_states import free_state

        return free_state(self, task, tracker=tracker)

    def clamped_state(self, task: Any, target_strain: ArrayLike, *, tracker: Any = None) -> Any:
        """Sources and targets clamped: :func:`.learning_states.clamped_state`."""
        from .learning_states import clamped_state

        return clamped_state(self, task, target_strain, tracker=tracker)

    def local_gradient(self, state: Any, dof: str, *, minus: Any = None) -> NDArray[np.float64]:
        """:meth:`energy_gradient` of a state (minus another state's)."""
        return self.energy_gradient(
            state.u, self.learning_dof(dof), minus=None if minus is None else minus.u
        )

    def task_gradient(
        self, task: Any, free: Any, dof: str, *, cost: str = "strain", tracker: Any = None
    ) -> NDArray[np.float64]:
        """Adjoint ``dC/dtheta`` per unit area of Eq. 26 (``cost="strain"``) or of the
        length cost ``sum_T |ab|^2 (S^F_T - S_T)^2 / 2`` (``cost="length"``)."""
        from .learning_states import cost_gradient

        weight = None if cost == "strain" else np.diag(task.target_length**2)
        return cost_gradient(
            self, task, free, self.learning_dof(dof), weight=weight, tracker=tracker
        )

    def learning_mask(
        self, task: Any, *, learn_sources: bool = True, learn_targets: bool = True
    ) -> NDArray[np.bool_]:
        """Elements whose fields may learn, (n_elements,) bool: not those a source (or
        target) material spring crosses, nor its disc ends, when ``learn_sources``
        (``learn_targets``) is False."""
        key = (
            "mask",
            learn_sources,
            learn_targets,
            task.source_a.tobytes(),
            task.target_a.tobytes(),
            task.source_b.tobytes(),
            task.target_b.tobytes(),
            task.radius,
        )
        if key in self._ops.memo:
            return self._ops.memo[key]
        mask = np.ones(self.n_elements, dtype=bool)
        for learn, a, b in (
            (learn_sources, task.source_a, task.source_b),
            (learn_targets, task.target_a, task.target_b),
        ):
            if not learn:
                mask[self.elements_crossed(a, b)] = False
                mask[self._end_elements(a, b, task.radius)] = False
        mask.setflags(write=False)
        self._ops.memo[key] = mask
        return mask

    def _end_elements(self, a: NDArray, b: NDArray, radius: float) -> NDArray[np.int64]:
        """Elements of the disc ends of material springs (none for point ends)."""
        if radius == 0:
            return np.zeros(0, dtype=np.int64)
        from .probes import disc_elements

        ends = [disc_elements(self.body, x, radius) for x in np.vstack([a, b])]
        return np.unique(np.concatenate(ends))

    def elements_crossed(self, a: ArrayLike, b: ArrayLike) -> NDArray[np.int64]:
        """Elements that the segments ``a_i -> b_i`` pass through (both sides of an edge)."""
        from .probes import locate

        a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
        t = np.linspace(0.02, 0.98, 17)
        pts = []
        for ai, bi in zip(a, b):
            d = bi - ai
            nrm = np.array([-d[1], d[0]]) * 1e-6
            for side in (nrm, -nrm):
                pts.append(ai + t[:, None] * d + side)
        cells, _ = locate(self.body, np.vstack(pts), tol=1e-3)
        return np.unique(cells)

    def apply_update(self, dof: str, delta: ArrayLike) -> LearnableBody:
        """The body after adding ``delta`` to the learning degrees of freedom of ``dof``.
        ``ValueError`` when a modulus would become negative."""
        dof = self.learning_dof(dof)
        new = self.parameters(dof) + np.asarray(delta, float)
        if dof == "modulus" and np.any(new < 0):
            j = int(np.argmin(new))
            raise ValueError(
                f"modulus of element {j} would become {new[j]:.3g} < 0; set min_stiffness"
            )
        return self.with_parameters(dof, new)

    def floor(self, dof: str, raw: NDArray, minimum: float | None) -> NDArray:
        """``raw`` with decreases stopped at ``minimum`` (moduli only; eigenstrain has none)."""
        if minimum is None or self.learning_dof(dof) != "modulus":
            return raw
        old = self.modulus
        return np.maximum(old + raw, np.minimum(old, minimum)) - old

    def damped_stepper(self, task: Any, damping: Any, dt: float) -> Any:
        """Backward-Euler steps of this body against ``damping`` under ``task``'s clamps
        (:class:`.damped_states.DampedStepper`): learning in physical time."""
        from .damped_states import DampedStepper

        return DampedStepper(self, task, damping, dt)

    def measurements(self, task: Any, free: Any, dof: str, mask: NDArray) -> dict[str, Any]:
        """What :func:`~continuum_vs_network.train` records of a free state
        (:func:`.learning_states.free_state_measurements`)."""
        from .learning_states import free_state_measurements

        return free_state_measurements(self, task, free, dof, mask)

    def to_arrays(self) -> dict[str, NDArray]:
        """Plain arrays that :meth:`from_arrays` rebuilds the body from."""
        return {
            "p": self.body.mesh.p,
            "t": self.body.mesh.t,
            "order": np.array(self.body.order),
            "lam": self.body.lam,
            "mu": self.body.mu,
            "kind": np.array(self.kind),
            "eigenstrain": self.eigenstrain,
            "modulus": self.modulus,
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> LearnableBody:
        """Inverse of :meth:`to_arrays`."""
        from skfem import MeshTri1

        lam, mu = np.asarray(arrays["lam"]), np.asarray(arrays["mu"])
        mesh = MeshTri1(np.asarray(arrays["p"], float), np.asarray(arrays["t"]), sort_t=False)
        out = learnable_body(
            mesh,
            Material(float(lam[0]), float(mu[0])),
            order=int(arrays["order"]),
            kind=str(arrays["kind"]),
            eigenstrain=arrays["eigenstrain"],
            modulus=arrays["modulus"],
        )
        if np.any(lam != lam[0]) or np.any(mu != mu[0]):
            from .body import ElasticBody

            eb = out.body
            body = ElasticBody(
                eb.mesh, eb.basis, eb.order, lam, mu, eb.dof_locations, eb.dof_component
            )
            ops = _operators(body.basis, lam, mu)
            out = dataclasses.replace(out, body=body, _ops=ops, _cache={})
        return out

    def __repr__(self) -> str:
        return (
            f"LearnableBody(P{self.body.order}, n_elements={self.n_elements}, "
            f"n_dofs={self.n_dofs}, kind={self.kind!r})"
        )


def _eigenstrain(value: ArrayLike, n: int) -> NDArray[np.float64]:
    e = np.asarray(value, dtype=float)
    if e.shape == (n,):
        e = np.column_stack([e, e, np.zeros(n)])
    elif e.ndim == 0:
        e = np.tile([float(e), float(e), 0.0], (n, 1))
    if e.shape != (n, 3):
        raise ValueError(
            f"eigenstrain must have shape ({n}, 3) (tensor xx, yy, xy) or ({n},) "
            f"(dilations), got {np.shape(value)}"
        )
    if not np.all(np.isfinite(e)):
        raise ValueError("eigenstrain must be finite")
    e = np.ascontiguousarray(e)
    e.setflags(write=False)
    return e


def _modulus(value: ArrayLike, n: int) -> NDArray[np.float64]:
    s = np.array(np.broadcast_to(np.asarray(value, dtype=float), (n,)))
    if not np.all(np.isfinite(s)) or np.any(s < 0):
        raise ValueError("modulus must be finite and >= 0 in every element")
    s.setflags(write=False)
    return s


def learnable_body(
    mesh: Any,
    material: Material,
    *,
    order: int = 1,
    kind: EigenstrainKind = "tensor",
    eigenstrain: ArrayLike = 0.0,
    modulus: ArrayLike = 1.0,
) -> LearnableBody:
    """A learnable body on ``mesh`` (skfem ``MeshTri1``).

    Parameters
    ----------
    mesh : skfem.MeshTri1
    material : Material
        2D Lamé parameters; plane strain or plane stress is chosen when the material is
        made (``Material.from_young(E, nu, plane=...)``).
    order : {1, 2}
        P1 (the lattice's own resolution: on a lattice's triangles its stiffness is the
        lattice's) or P2.
    kind : {"tensor", "isotropic"}
        What eigenstrain learning may change.
    eigenstrain : scalar, (n_elements,) or (n_elements, 3) float array
        Initial rest strain (tensor components; a scalar or (n,) array is a dilation).
    modulus : scalar or (n_elements,) float array
        Initial modulus scale (>= 0).
    """
    from .body import elastic_body

    if kind not in ("tensor", "isotropic"):
        raise ValueError(f"kind must be 'tensor' or 'isotropic', got {kind!r}")
    body = elastic_body(mesh, material, order=order)
    n = body.n_elements
    ops = _operators(body.basis, np.asarray(body.lam), np.asarray(body.mu))
    return LearnableBody(body, _eigenstrain(eigenstrain, n), _modulus(modulus, n), kind, ops)
