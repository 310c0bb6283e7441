"""Node tasks: the output is node displacements, not spring strains.

Source springs are clamped at strains as in an :class:`~.tasks.AllosteryTask`; the output
is chosen coordinates of chosen nodes, which should move by given displacements from their
positions in the network the task was made on (absolute displacements, per coordinate, as in
laltman2/LearningNetworks' node tasks). The error is
``C = sum_T (x_T - x_T^*)^2 / 2`` with ``x_T^* = x_T^0 + u_T`` (length units).

Every rule takes a node task where it takes a spring task:

* coupled learning nudges the target coordinates, ``x^N = x^F + eta (x^* - x^F)``, and holds
  them there (node clamps: the coordinate is pinned at that value);
* prospective configuration and directed aging pin the targets at ``x^*``;
* the exact gradient solves one adjoint with the target coordinates' error as load
  (:func:`node_cost_gradient`).

To first order in ``eta`` coupled learning's update over ``alpha`` is ``-d/dtheta`` of
``(x_T - x^*)^T K (x_T - x^*) / 2``, ``K`` the targets' effective stiffness (for one
target coordinate, ``-K dC/dtheta``): ``tests/test_learning_node_tasks.py`` checks this
against :func:`node_cost_gradient`.

Not implemented: *relative* displacements (one node against another), which need a linear
constraint between two nodes rather than a pin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..network.constraints import default_pins
from ..network.equilibrium import Equilibrium
from ..network.model import SpringNetwork
from .tasks import _candidates, _frozen, _frozen_mask, _positive_normal

__all__ = ["NodeTask", "node_cost_gradient", "node_task"]


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
        Target nodes (a node may appear twice, once per coordinate).
    coords : (n_targets,) int array
        0 (x) or 1 (y) for each target.
    reference : (n_targets,) float array
        The target coordinates when the task was made.
    displacement : (n_targets,) float array
        Desired displacements ``u_T`` from ``reference``.
    pinned : (n_nodes, 2) bool array
    """

    sources: NDArray[np.int64]
    source_strain: NDArray[np.float64]
    source_rest_length: NDArray[np.float64]
    nodes: NDArray[np.int64]
    coords: NDArray[np.int64]
    reference: NDArray[np.float64]
    displacement: NDArray[np.float64]
    pinned: NDArray[np.bool_]

    def __post_init__(self) -> None:
        for name in ("sources", "nodes", "coords"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.int64, name))
        for name in ("source_strain", "source_rest_length", "reference", "displacement"):
            object.__setattr__(self, name, _frozen(getattr(self, name), np.float64, name))
        object.__setattr__(self, "pinned", _frozen_mask(self.pinned))
        if not (self.source_strain.shape == self.source_rest_length.shape == self.sources.shape):
            raise ValueError("source_strain and source_rest_length need one entry per source")
        m = self.nodes.shape
        if not (self.coords.shape == self.reference.shape == self.displacement.shape == m):
            raise ValueError("coords, reference and displacement need one entry per target node")
        if self.nodes.size == 0:
            raise ValueError("a node task needs at least one target coordinate")
        if np.any((self.coords != 0) & (self.coords != 1)):
            raise ValueError("coords must be 0 (x) or 1 (y)")
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
    ) -> NodeTask:
        """A node task on ``net``: records the sources' rest lengths, the target
        coordinates and the pins (default: away from the sources and the target nodes)."""
        if not isinstance(net, SpringNetwork):
            raise check.ArgumentError("net", net, "a SpringNetwork")
        sources = check.index_array(
            "sources", np.atleast_1d(sources), net.n_springs, what="spring indices"
        )
        nodes = check.index_array("nodes", np.atleast_1d(nodes), net.n_nodes, what="node indices")
        coords = np.broadcast_to(np.asarray(coords), nodes.shape).astype(np.int64)
        if np.any((coords != 0) & (coords != 1)):
            raise check.ArgumentError("coords", coords.tolist(), "0 (x) or 1 (y) per target node")
        if pinned is None:
            touching = np.flatnonzero(np.isin(net.springs, nodes).any(axis=1))
            pinned = default_pins(net, avoid=np.concatenate([sources, touching]))
        task = cls(
            sources=sources,
            source_strain=np.broadcast_to(np.asarray(source_strain, float), sources.shape),
            source_rest_length=net.rest_length[sources],
            nodes=nodes,
            coords=coords,
            reference=net.positions[nodes, coords],
            displacement=np.broadcast_to(np.asarray(displacement, float), nodes.shape),
            pinned=pinned,
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
        if int(self.nodes.max()) >= net.n_nodes or self.pinned.shape != (net.n_nodes, 2):
            raise ValueError(f"task does not fit a network of {net.n_nodes} nodes")

    def source_clamps(self, net: SpringNetwork, strain_reference: str = "initial") -> dict:
        """``{source: clamp length}`` (the recorded reference rest lengths; node tasks
        measure no strain, so both conventions give the same clamps)."""
        lengths = self.source_rest_length * (self.source_strain + 1.0)
        return dict(zip(self.sources.tolist(), lengths.tolist()))

    def outputs(self, positions: ArrayLike) -> NDArray:
        """Target coordinates of ``positions``, (n_targets,)."""
        return np.asarray(positions, float)[self.nodes, self.coords]

    def error(self, net: SpringNetwork, positions: ArrayLike, strain_reference: str = "") -> float:
        """``C = sum (x_T - x_T^*)^2 / 2`` at free-state ``positions`` (length units)."""
        return float(0.5 * np.sum((self.outputs(positions) - self.desired) ** 2))

    def node_clamps(self, x: ArrayLike, values: ArrayLike) -> tuple[NDArray, NDArray]:
        """Pins and start positions that hold the target coordinates at ``values``:
        ``(pinned, x0)`` for :meth:`~.states.Tracker.solve`."""
        pinned = self.pinned.copy()
        pinned[self.nodes, self.coords] = True
        x0 = np.array(x, dtype=float)
        x0[self.nodes, self.coords] = values
        return pinned, x0

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
    )

    def to_arrays(self) -> dict[str, NDArray]:
        return {f: getattr(self, f) for f in self._FIELDS}

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray]) -> NodeTask:
        return cls(**{f: arrays[f] for f in cls._FIELDS})


def node_task(
    net: SpringNetwork,
    rng: np.random.Generator,
    *,
    n_sources: int = 1,
    n_targets: int = 2,
    source_std: float = 0.1,
    displacement_std: float = 0.05,
    candidates: ArrayLike | None = None,
) -> NodeTask:
    """Random node task: ``n_sources`` source springs (strains ``N(0, source_std)``) and
    ``n_targets`` target coordinates of distinct nodes away from the sources, with desired
    displacements ``N(0, displacement_std)`` in units of the mean rest length."""
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    displacement_std = check.real("displacement_std", displacement_std, low=0, low_open=True)
    pool = _candidates(net, candidates)
    sources = rng.choice(pool, size=n_sources, replace=False)
    near = np.unique(net.springs[sources])
    free_nodes = np.setdiff1d(np.arange(net.n_nodes), near)
    if free_nodes.size < n_targets + 2:
        raise ValueError(f"the network has too few nodes away from the sources ({free_nodes.size})")
    nodes = rng.choice(free_nodes, size=n_targets, replace=False)
    coords = rng.integers(0, 2, n_targets)
    scale = float(np.mean(net.rest_length))
    return NodeTask.create(
        net,
        sources,
        _positive_normal(rng, 0.0, source_std, n_sources),
        nodes,
        coords,
        scale * rng.normal(0.0, displacement_std, n_targets),
    )


def node_cost_gradient(
    net: SpringNetwork, task: NodeTask, eq: Equilibrium, *, dof: str = "rest_length",
    outputs: ArrayLike | None = None,
) -> NDArray:  # fmt: skip
    """Exact gradient of the node task error with respect to every spring's ``L`` or ``k``.

    ``eq`` is the free state (sources clamped). One adjoint solve with the KKT matrix of
    the free state, load ``dC/dx = (x_T - x^*)`` on the target coordinates (``outputs``
    replaces the measured ``x_T``: read-out noise).
    """
    from .sensitivity import Sensitivity, length_jacobian_rows

    x = np.asarray(eq.positions, float)
    out = task.outputs(x) if outputs is None else np.asarray(outputs, float)
    sens = Sensitivity(net, task.pinned, task.source_clamps(net), eq)
    b = np.zeros_like(x)
    b[task.nodes, task.coords] = out - task.desired
    v, _ = sens.solve(b)
    dr = length_jacobian_rows(net, x, v)
    if dof == "rest_length":
        return net.stiffness * dr
    return -(net.lengths(x) - net.rest_length) * dr
