"""Node tasks: the output is node displacements, not spring strains.

Source springs are clamped at strains as in an :class:`~.tasks.AllosteryTask`; the output
is chosen coordinates of chosen nodes, absolute or relative to another node (as in
laltman2/LearningNetworks' node tasks). Target ``t`` is ``(node a, optional node b, coordinate
c, desired displacement u)``: its output is ``y_t = x_{a,c} - x_{b,c}`` (``y_t = x_{a,c}``
without ``b``), which should move by ``u`` from its value in the network the task was made
on: ``y^* = y^0 + u``. The error is ``C = sum_T (y_T - y_T^*)^2 / 2`` (length units).

Every rule takes a node task where it takes a spring task, and every state that holds the
outputs at given values (:meth:`NodeTask.hold`) is found one way: an absolute target's
coordinate is pinned there; a relative target is a linear two-node constraint
``x_{a,c} - x_{b,c} = v``, held by its reaction, an equal and opposite external force ``+f``
on ``a`` and ``-f`` on ``b`` (coordinate ``c``), found by Newton's method on the
multipliers ``f`` (each step one linear solve per relative target with the state's KKT
matrix, then one loaded equilibrium).

* coupled learning nudges the outputs, ``y^N = y^F + eta (y^* - y^F)``, and holds them there;
* prospective configuration and directed aging hold them at ``y^*``;
* the exact gradient solves one adjoint with load ``B^T (y - y^*)``
  (:func:`node_cost_gradient`; ``B`` the outputs' selector, rows ``e_{a,c} - e_{b,c}``).

To first order in ``eta`` coupled learning's update over ``alpha`` is ``-d/dtheta`` of
``(y - y^*)^T K (y - y^*) / 2``, ``K = (B H^{-1} B^T)^{-1}`` the outputs' effective
stiffness (for one target, ``-K dC/dtheta``): ``tests/test_learning_node_tasks.py`` checks
this against :func:`node_cost_gradient` for absolute and relative targets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..network.constraints import default_pins
from ..network.equilibrium import Equilibrium, EquilibriumError
from ..network.model import SpringNetwork
from .states import Tracker
from .tasks import _candidates, _frozen, _frozen_mask, _positive_normal

__all__ = ["NodeTask", "node_cost_gradient", "node_task"]

_HOLD_TOL = 1e-9  # relative targets held to this many mean rest lengths
_HOLD_ITER = 20  # Newton steps on the multipliers


def _outputs(x: NDArray, nodes: NDArray, coords: NDArray, relative_to: NDArray) -> NDArray:
    """``x[a, c] - x[b, c]`` (``b = relative_to``; ``x[a, c]`` where ``b`` is -1)."""
    out = x[nodes, coords].copy()
    b = relative_to >= 0
    out[b] -= x[relative_to[b], coords[b]]
    return out


@dataclass(frozen=True, eq=False)
class NodeTask:
    """Sources clamped at strains; target node coordinates that should move.

    Attributes
    ----------
    sources : (n_sources,) int array
    source_strain : (n_sources,) float array
    source_rest_length : (n_sources,) float array
        Reference rest lengths of the sources (the clamp length is ``L (S + 1)``).
    nodes : (n_targets,) int array
        Target nodes ``a`` (a node may appear twice, once per coordinate).
    coords : (n_targets,) int array
        0 (x) or 1 (y) for each target.
    reference : (n_targets,) float array
        The outputs ``y^0`` when the task was made.
    displacement : (n_targets,) float array
        Desired displacements ``u_T`` from ``reference``.
    pinned : (n_nodes, 2) bool array
    relative_to : (n_targets,) int array
        Node ``b`` each output is measured against, ``-1`` for an absolute target
        (the default: every target absolute).
    """

    sources: NDArray[np.int64]
    source_strain: NDArray[np.float64]
    source_rest_length: NDArray[np.float64]
    nodes: NDArray[np.int64]
    coords: NDArray[np.int64]
    reference: NDArray[np.float64]
    displacement: NDArray[np.float64]
    pinned: NDArray[np.bool_]
    relative_to: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        if self.relative_to is None:
            object.__setattr__(self, "relative_to", np.full(np.shape(self.nodes), -1))
        rel = np.atleast_1d(np.asarray(self.relative_to))
        if rel.dtype.kind not in "iu" or np.any(rel < -1):
            raise check.ArgumentError(
                "relative_to", self.relative_to, "node indices, -1 for an absolute target"
            )
        rel = rel.astype(np.int64).reshape(-1)
        rel.setflags(write=False)
        object.__setattr__(self, "relative_to", rel)
        for name in ("sources", "nodes", "coords"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.int64, name))
        for name in ("source_strain", "source_rest_length", "reference", "displacement"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.float64, name))
        object.__setattr__(self, "pinned", _frozen_mask(self.pinned))
        if not (self.source_strain.shape == self.source_rest_length.shape == self.sources.shape):
            raise ValueError("source_strain and source_rest_length need one entry per source")
        m = self.nodes.shape
        if not (
            self.coords.shape == self.reference.shape == self.displacement.shape == m
            and self.relative_to.shape == m
        ):
            raise ValueError(
                "coords, reference, displacement and relative_to need one entry per target node"
            )
        if self.nodes.size == 0:
            raise ValueError("a node task needs at least one target coordinate")
        if np.any((self.coords != 0) & (self.coords != 1)):
            raise ValueError("coords must be 0 (x) or 1 (y)")
        rel = self.relative_to
        if np.any(rel == self.nodes):
            raise ValueError("a target is measured relative to its own node")
        if np.any(rel >= self.pinned.shape[0]):
            raise ValueError(f"relative_to names node {rel.max()}, the mask has fewer")
        pairs = self.nodes * 2 + self.coords
        if np.unique(pairs).size != pairs.size:
            raise ValueError("a target coordinate is named twice")
        if np.any(self.pinned[self.nodes, self.coords]):
            raise ValueError("a target coordinate is pinned: it cannot move")
        if np.any(self.source_strain <= -1.0):
            raise ValueError("source_strain must be > -1 (a positive clamp length)")

    @classmethod
    def create(
        cls,
        net: SpringNetwork,
        sources: ArrayLike,
        source_strain: ArrayLike,
        nodes: ArrayLike,
        coords: ArrayLike,
        displacement: ArrayLike,
        *,
        pinned: ArrayLike | None = None,
        relative_to: ArrayLike | None = None,
    ) -> NodeTask:
        """A node task on ``net``: records the sources' rest lengths, the outputs ``y^0``
        and the pins (default: away from the sources and every target node ``a`` and
        ``b``). ``relative_to``: node ``b`` per target, ``-1`` (or None: all) absolute."""
        if not isinstance(net, SpringNetwork):
            raise check.ArgumentError("net", net, "a SpringNetwork")
        sources = check.index_array(
            "sources", np.atleast_1d(sources), net.n_springs, what="spring indices"
        )
        nodes = check.index_array("nodes", np.atleast_1d(nodes), net.n_nodes, what="node indices")
        coords = np.broadcast_to(np.asarray(coords), nodes.shape).astype(np.int64)
        if np.any((coords != 0) & (coords != 1)):
            raise check.ArgumentError("coords", coords.tolist(), "0 (x) or 1 (y) per target node")
        rel = np.full(nodes.shape, -1, dtype=np.int64)
        if relative_to is not None:
            given = np.broadcast_to(np.asarray(relative_to), nodes.shape)
            if given.dtype.kind not in "iu" or np.any(given < -1) or np.any(given >= net.n_nodes):
                raise check.ArgumentError(
                    "relative_to", relative_to, f"node indices below {net.n_nodes} or -1 per target"
                )
            rel = given.astype(np.int64)
        if pinned is None:
            every = np.concatenate([nodes, rel[rel >= 0]])
            touching = np.flatnonzero(np.isin(net.springs, every).any(axis=1))
            pinned = default_pins(net, avoid=np.concatenate([sources, touching]))
        task = cls(
            sources=sources,
            source_strain=np.broadcast_to(np.asarray(source_strain, float), sources.shape),
            source_rest_length=net.rest_length[sources],
            nodes=nodes,
            coords=coords,
            reference=_outputs(net.positions, nodes, coords, rel),
            displacement=np.broadcast_to(np.asarray(displacement, float), nodes.shape),
            pinned=pinned,
            relative_to=rel,
        )
        task.check(net)
        return task

    # -- what rules and train read --------------------------------------------------------
    @property
    def targets(self) -> NDArray[np.int64]:
        """No target springs (bulk learning freezes the sources only)."""
        return np.empty(0, dtype=np.int64)

    @property
    def n_sources(self) -> int:
        return int(self.sources.size)

    @property
    def n_targets(self) -> int:
        return int(self.nodes.size)

    @property
    def desired(self) -> NDArray[np.float64]:
        """Desired target coordinates ``x^* = reference + displacement``, (n_targets,)."""
        return self.reference + self.displacement

    def check(self, net: SpringNetwork) -> None:
        if self.sources.size and int(self.sources.max()) >= net.n_springs:
            raise ValueError(f"task names spring {self.sources.max()}, network has {net.n_springs}")
        top = max(int(self.nodes.max()), int(self.relative_to.max()))
        if top >= net.n_nodes or self.pinned.shape != (net.n_nodes, 2):
            raise ValueError(f"task does not fit a network of {net.n_nodes} nodes")

    def source_clamps(self, net: SpringNetwork, strain_reference: str = "initial") -> dict:
        """``{source: clamp length}`` (the recorded reference rest lengths; node tasks
        measure no strain, so both conventions give the same clamps)."""
        lengths = self.source_rest_length * (self.source_strain + 1.0)
        return dict(zip(self.sources.tolist(), lengths.tolist()))

    @property
    def relative(self) -> NDArray[np.bool_]:
        """True for the targets measured against another node, (n_targets,)."""
        return self.relative_to >= 0

    def outputs(self, positions: ArrayLike) -> NDArray:
        """Outputs ``y`` of ``positions``: target coordinates, minus node ``b``'s for a
        relative target, (n_targets,)."""
        return _outputs(np.asarray(positions, float), self.nodes, self.coords, self.relative_to)

    def selector(self, n_nodes: int) -> NDArray:
        """``B``: row ``t`` is ``d y_t / d x``, (n_targets, n_nodes, 2) with entries 0, +-1."""
        B = np.zeros((self.n_targets, n_nodes, 2))
        t = np.arange(self.n_targets)
        B[t, self.nodes, self.coords] = 1.0
        b = self.relative
        B[t[b], self.relative_to[b], self.coords[b]] = -1.0
        return B

    def error(self, net: SpringNetwork, positions: ArrayLike, strain_reference: str = "") -> float:
        """``C = sum (y_T - y_T^*)^2 / 2`` at free-state ``positions`` (length units)."""
        return float(0.5 * np.sum((self.outputs(positions) - self.desired) ** 2))

    def hold(
        self,
        net: SpringNetwork,
        tracker: Tracker,
        x: ArrayLike,
        values: ArrayLike,
        *,
        key: str,
    ) -> Equilibrium:
        """The equilibrium with the sources clamped and the outputs held at ``values``.

        Absolute targets: the coordinate is pinned at its value. Relative targets: the
        two-node constraint's reaction (equal and opposite forces on ``a`` and ``b``) by
        Newton's method on the multipliers from the state with the absolute targets held
        (see the module), to ``|y - values| <= 1e-9`` mean rest lengths. ``x``: warm start,
        (n_nodes, 2).

        Raises
        ------
        EquilibriumError
            A state cannot be found or the relative targets cannot be held.
        """
        from .sensitivity import Sensitivity

        values = np.asarray(values, dtype=float)
        rel = self.relative
        pinned = self.pinned.copy()
        ab = ~rel
        pinned[self.nodes[ab], self.coords[ab]] = True
        x0 = np.array(x, dtype=float)
        x0[self.nodes[ab], self.coords[ab]] = values[ab]
        clamps = self.source_clamps(net)
        eq = tracker.solve(net, pinned, clamps, x0, key=key)
        if not rel.any():
            return eq
        B = self.selector(net.n_nodes)[rel]
        want = values[rel]
        force = np.zeros(int(rel.sum()))
        tol = _HOLD_TOL * float(np.mean(net.rest_length))
        for _ in range(_HOLD_ITER):
            miss = want - self.outputs(eq.positions)[rel]
            if np.max(np.abs(miss)) <= tol:
                return eq
            sens = Sensitivity(net, pinned, clamps, eq)
            V = np.stack([sens.solve(row)[0] for row in B])  # H^-1 B^T, (m, n_nodes, 2)
            compliance = np.einsum("inc,jnc->ij", B, V)
            step = np.linalg.solve(compliance, miss)
            for _ in range(6):  # halve the force step where the loaded state is not found
                try:
                    guess = eq.positions + np.einsum("i,inc->nc", step, V)
                    eq = tracker.solve(
                        net, pinned, clamps, eq.positions, key=key, guess=guess,
                        load=np.einsum("i,inc->nc", force + step, B),
                    )  # fmt: skip
                    break
                except EquilibriumError:
                    step = 0.5 * step
            else:
                raise EquilibriumError("node task: a loaded state on the way is not found")
            force = force + step
        raise EquilibriumError(
            f"node task: relative targets not held to {tol:.3g} in {_HOLD_ITER} Newton steps"
        )

    def with_source_strain(self, source_strain: ArrayLike) -> NodeTask:
        import dataclasses

        strain = np.broadcast_to(np.asarray(source_strain, float), self.sources.shape)
        return dataclasses.replace(self, source_strain=strain)

    # -- files ------------------------------------------------------------------------------
    _FIELDS = (
        "sources",
        "source_strain",
        "source_rest_length",
        "nodes",
        "coords",
        "reference",
        "displacement",
        "pinned",
        "relative_to",
    )

    def to_arrays(self) -> dict[str, NDArray]:
        return {f: getattr(self, f) for f in self._FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> NodeTask:
        return cls(**{f: arrays[f] for f in cls._FIELDS if f in arrays})


def node_task(
    net: SpringNetwork,
    rng: np.random.Generator,
    *,
    n_sources: int = 1,
    n_targets: int = 2,
    source_std: float = 0.1,
    displacement_std: float = 0.05,
    relative: bool = False,
    candidates: ArrayLike | None = None,
) -> NodeTask:
    """Random node task: ``n_sources`` source springs (strains ``N(0, source_std)``) and
    ``n_targets`` target coordinates of distinct nodes away from the sources, with desired
    displacements ``N(0, displacement_std)`` in units of the mean rest length. With
    ``relative`` each target is measured against another distinct node away from the
    sources (node ``b``), and the displacement is of ``a`` relative to ``b``."""
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    displacement_std = check.real("displacement_std", displacement_std, low=0, low_open=True)
    relative = check.boolean("relative", relative)
    pool = _candidates(net, candidates)
    sources = rng.choice(pool, size=n_sources, replace=False)
    near = np.unique(net.springs[sources])
    free_nodes = np.setdiff1d(np.arange(net.n_nodes), near)
    need = n_targets * (2 if relative else 1) + 2
    if free_nodes.size < need:
        raise ValueError(f"the network has too few nodes away from the sources ({free_nodes.size})")
    drawn = rng.choice(free_nodes, size=n_targets * (2 if relative else 1), replace=False)
    nodes = drawn[:n_targets]
    relative_to = drawn[n_targets:] if relative else None
    coords = rng.integers(0, 2, n_targets)
    scale = float(np.mean(net.rest_length))
    return NodeTask.create(
        net,
        sources,
        _positive_normal(rng, 0.0, source_std, n_sources),
        nodes,
        coords,
        scale * rng.normal(0.0, displacement_std, n_targets),
        relative_to=relative_to,
    )


def node_cost_gradient(
    net: SpringNetwork, task: NodeTask, eq: Equilibrium, *, dof: str = "rest_length",
    outputs: ArrayLike | None = None,
) -> NDArray:  # fmt: skip
    """Exact gradient of the node task error with respect to every spring's ``L`` or ``k``.

    ``eq`` is the free state (sources clamped). One adjoint solve with the KKT matrix of
    the free state, load ``dC/dx = B^T (y - y^*)`` (``outputs`` replaces the measured
    ``y``: read-out noise).
    """
    from .sensitivity import Sensitivity, length_jacobian_rows

    x = np.asarray(eq.positions, float)
    out = task.outputs(x) if outputs is None else np.asarray(outputs, float)
    sens = Sensitivity(net, task.pinned, task.source_clamps(net), eq)
    b = np.einsum("t,tnc->nc", out - task.desired, task.selector(net.n_nodes))
    v, _ = sens.solve(b)
    dr = length_jacobian_rows(net, x, v)
    if dof == "rest_length":
        return net.stiffness * dr
    return -(net.lengths(x) - net.rest_length) * dr
