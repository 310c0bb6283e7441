"""Resource estimates of a scene, checked when it is loaded (before anything is allocated).

A scene whose estimated peak memory exceeds what this machine has available
(:func:`continuum_vs_network._validate.available_memory`) is refused with a
:class:`~.schema.SceneError` naming the key that drives the estimate, the estimate and the
memory available. The estimates are upper-bound-minded sums of the arrays each part of a
run keeps (bytes per node, per history entry, per unit); the per-node solver cost was
measured (Newton ``relax`` on a 200 x 200 lattice: about 10 kB per node at peak), the
others are counted from the array shapes. Large networks stay possible on large machines:
the limit is the memory available, not a fixed size.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from .. import _validate as check

if TYPE_CHECKING:
    from .schema import Scene

__all__ = ["Estimate", "check_grid", "check_resources", "estimate"]

# the estimates of the kinds that have one are named in the kind registry
# (:data:`~.schema.KINDS`, ``limits``)

#: peak bytes per network node of an equilibrium solve (sparse Newton, factorisation fill)
SOLVE_BYTES_PER_NODE = 10_000
#: bytes of a stored network per node (positions; springs, k, L for ~3 springs per node)
NETWORK_BYTES_PER_NODE = 16 + 3 * (16 + 8 + 8)
#: bytes of bookkeeping per unit (Unit object, fingerprint, JSON record, result entry)
UNIT_BYTES = 8_000
#: bytes per finite-element degree of freedom of a sparse direct solve in 2D (estimate)
FE_BYTES_PER_DOF = 3_000
#: bytes per sweep point: its scene (measured: 4 kB each for 1000 points) plus its records,
#: table row and executor bookkeeping (estimate)
POINT_BYTES = 16_000
#: number of nodes of the paper's patch
PAPER_NODES = 10


class Estimate:
    """Estimated peak bytes of a scene, as parts ``(table, key, bytes, what)``."""

    def __init__(self) -> None:
        self.parts: list[tuple[str, str, float, str]] = []

    def add(self, table: str, key: str, nbytes: float, what: str) -> None:
        self.parts.append((table, key, float(nbytes), what))

    @property
    def total(self) -> float:
        return sum(p[2] for p in self.parts)

    def largest(self) -> tuple[str, str, float, str]:
        return max(self.parts, key=lambda p: p[2])


def _history_bytes(steps: int, n_targets: int) -> int:
    from ..learning.record import record_bytes

    return record_bytes(steps, n_targets)


def estimate(scene: Scene) -> Estimate:
    """Estimated peak memory of running ``scene``, part by part (its kind's estimate,
    :attr:`~.schema.Kind.limits`; empty for a kind without one)."""
    from .schema import KINDS

    est = Estimate()
    KINDS[scene.kind].estimate(scene, est)
    return est


def learning(scene: Scene, est: Estimate) -> None:
    """A learning scene: its solves, trial histories and units."""
    net, L = scene.network, scene.learning
    nodes = PAPER_NODES if net.builder == "paper" else net.n_nodes
    n_targets = 1 if scene.task.kind == "paper" else scene.task.n_targets
    n_sources = 1 if scene.task.kind == "paper" else scene.task.n_sources
    methods = len(scene.solver.methods) if scene.solver is not None else 1
    # a GCL rule runs once per nudge when etas lists several
    rules = sum(len(L.etas) if r.startswith("gcl") and L.etas else 1 for r in L.rules)
    runs = methods * rules * len(L.noise)
    units = runs * L.trials
    est.add("network", "n_nodes", nodes * SOLVE_BYTES_PER_NODE, f"solving {nodes} nodes")
    # every trial's history and its initial and final networks are merged in memory
    per_trial = _history_bytes(L.steps, n_targets) + 2 * nodes * NETWORK_BYTES_PER_NODE
    key = "steps" if L.steps / 300 > L.trials / 10 else "trials"
    est.add("learning", key, 2 * units * per_trial, f"{units} trial histories of {L.steps} steps")
    est.add("learning", "trials", units * UNIT_BYTES, f"{units} units")
    if L.sweeps:
        per_point = 8 * (2 * n_sources + n_targets + 4)
        est.add(
            "learning",
            "sweep_points",
            L.trials * L.sweep_points * per_point,
            f"sweeps of {L.sweep_points} points",
        )


def continuum_learning(scene: Scene, est: Estimate) -> None:
    """Both media learning: the lattice, its continuum's unknowns, the histories."""
    net, L, c = scene.network, scene.learning, scene.continuum
    nodes = net.size**2
    dofs = 2 * nodes * 4**c.refine * (4 if c.order == 2 else 1)
    est.add("network", "size", nodes * SOLVE_BYTES_PER_NODE, f"solving {nodes} nodes")
    what = f"{dofs} finite-element unknowns (refine {c.refine}, order {c.order})"
    est.add("network", "size", dofs * FE_BYTES_PER_DOF, what)
    runs = len(L.rules) * L.trials * (c.refine + 2)  # the network and every refinement
    key = "steps" if L.steps / 300 > L.trials / 10 else "trials"
    est.add("learning", key, 2 * runs * _history_bytes(L.steps, scene.task.n_targets),
            f"{runs} histories of {L.steps} steps")  # fmt: skip


def accuracy(scene: Scene, est: Estimate) -> None:
    """The finest mesh of Lamé's annulus and the longest time series."""
    a = scene.accuracy
    # Lamé's annulus (radii 1 and 2, area 3 pi) meshed at the finest h: about
    # area / (0.43 h^2) vertices, four times as many unknowns per vertex for P2
    vertices = 3 * math.pi / (0.43 * min(a.mesh_sizes) ** 2)
    dofs = 2 * vertices * (4 if any(e.startswith("P2") for e in a.elements) else 1)
    est.add("accuracy", "mesh_sizes", dofs * FE_BYTES_PER_DOF, f"{dofs:.0f} FE unknowns")
    frames = max(a.steps) + 1
    est.add("accuracy", "steps", frames * 2 * a.size**2 * 16, f"{frames} time steps")


def beyond_paper(scene: Scene, est: Estimate) -> None:
    """The largest lattice and the histories of every study."""
    net, L = scene.network, scene.learning
    n = max(net.sizes)
    nodes = n * n
    est.add("network", "sizes", nodes * SOLVE_BYTES_PER_NODE, f"solving a {n} x {n} lattice")
    runs = len(net.sizes) * len(L.examples) + 2 * len(L.rules) + 2
    est.add(
        "learning", "steps", runs * _history_bytes(L.steps, 2 * max(L.examples)),
        f"{runs} histories of {L.steps} steps",
    )  # fmt: skip


def lattice(scene: Scene, est: Estimate) -> None:
    """transmission, relaxation, stability and solvers: the largest lattice, its continuum
    and (relaxation) the trajectories."""
    net = scene.network
    sizes, key = (net.sizes, "sizes") if net.sizes else ((net.size,), "size")  # stability: size
    n = max(sizes)
    nodes = n * n
    est.add("network", key, nodes * SOLVE_BYTES_PER_NODE, f"solving a {n} x {n} lattice")
    dofs = 0
    if scene.continuum is not None:
        c = scene.continuum
        vertices = nodes * 4**c.refine
        dofs = 2 * vertices * (4 if c.order == 2 else 1)
        what = f"{dofs} finite-element unknowns (refine {c.refine}, order {c.order})"
        est.add("network", key, dofs * FE_BYTES_PER_DOF, what)
    if scene.dynamics is not None:
        d = scene.dynamics
        frames = math.ceil(d.steps_per_tau * d.duration) + 1
        key = "steps_per_tau" if d.steps_per_tau / 20 > d.duration / 12 else "duration"
        # the network trajectory (and its displacements), and the continuum's
        est.add("dynamics", key, frames * (3 * nodes * 16 + 2 * dofs * 8), f"{frames} time steps")


def check_resources(scene: Scene, file: str) -> None:
    """Raise :class:`~.schema.SceneError` when ``scene`` would not fit in memory."""
    from .schema import SceneError

    est = estimate(scene)
    avail = check.available_memory()
    if est.total <= avail:
        return
    table, key, _, _ = est.largest()
    parts = "; ".join(
        f"{what}: {check.format_bytes(b)}"
        for _, _, b, what in sorted(est.parts, key=lambda p: -p[2])
    )
    spec = getattr(scene, table)
    value = getattr(spec, key) if spec is not None else None
    raise SceneError(
        file,
        table,
        key,
        f"{value!r} is too large: the scene needs about {check.format_bytes(est.total)} of "
        f"memory ({parts}) but {check.format_bytes(avail)} are available",
    )


def check_grid(n_points: int, file: str) -> None:
    """Raise :class:`~.schema.SceneError` when a sweep of ``n_points`` would not fit in memory.

    Checked before the grid is expanded (expanding it is where the memory would go).
    """
    from .schema import SceneError

    need = n_points * POINT_BYTES
    avail = check.available_memory()
    if need > avail:
        raise SceneError(
            file,
            "sweep",
            "",
            f"the grid has {n_points} points, too many: expanding and tracking them needs "
            f"about {check.format_bytes(need)} of memory but {check.format_bytes(avail)} are "
            f"available; sweep fewer values",
        )
