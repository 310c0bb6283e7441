"""Is a trained network's output caused by its inputs? Coupling of sources and targets.

An allosteric task asks for target strains ``S_T`` *while* the sources are clamped at
their strains. A network can meet it without transmitting anything: a target that learns
its own rest length, or bulk springs that prestress the targets, put the targets at
``S_T`` whatever the sources do. Such a solution is trivial, not learned allostery.

The measurement (:func:`measure_coupling`) solves the free state of the trained network
with the source strains scaled by ``lambda`` (a source sweep; ``lambda = 1`` is the task,
``lambda = 0`` clamps every source at zero strain, "sources off") and of the initial
network with the sources on and off. Per target, with strains in the run's
``strain_reference``:

* ``transmitted = S(lambda=1) - S(lambda=0)``: the part of the trained target strain the
  sources cause (``transmitted_0`` the same for the initial network);
* ``offset = S(lambda=0) - S_initial(lambda=0)``: the part that stays when the sources are
  off, built into the network by learning (prestress, a target's own rest length);
* ``change = S(lambda=1) - S_initial(lambda=1) = (transmitted - transmitted_0) + offset``:
  what learning changed in the task's output.

Two trivial ways to meet a task are told apart from learned allostery:

1. the targets stop responding to the sources and sit at their goal (a target that
   learned its own rest length): ``|transmitted|`` is small against ``|offset|``;
2. the sources' drive is left as it was and prestress shifts the targets by the missing
   amount: the change of the drive, ``transmitted - transmitted_0``, contributes nothing
   to ``change``.

The **source share** is the smaller of the two fractions (Euclidean norms and dot products
over the targets)::

    share = min( |transmitted| / (|transmitted| + |offset|),
                 clip((transmitted - transmitted_0) . change / |change|^2, 0, 1) )

the first 0 when both norms vanish, the second 1 when nothing changed (``change = 0``). The
second is the fraction of the learned change delivered by a changed response to the
sources, projected onto that change. An untrained network has share 1; either trivial
solution has share ~0.

Verdict (:func:`coupling_verdict`), the rule stated once here:

* ``"coupled"``: share >= :data:`COUPLED_AT` (0.5): the sources cause at least half of the
  target strain (turning them off takes the targets at least halfway back to rest);
* ``"decoupled"``: share < :data:`DECOUPLED_BELOW` (0.1): with the sources off the targets
  keep more than 90 % of their strain. The threshold sits an order of magnitude above what
  a network that is trivial by construction shows (a target whose rest length is set to its
  goal and made stiff: share < 0.01, ``tests/test_learning_coupling.py``) and an order below
  what an untrained network shows (1: its targets are strained by the sources only); the
  solver's tolerance (1e-10 of the force scale) cannot move a share by 0.1;
* ``"partially coupled"`` in between.

A task met (:func:`outcome`) by a decoupled network is reported as *met trivially*, never
as learned.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..network.equilibrium import EquilibriumError
from ..network.model import SpringNetwork
from .states import Solver, Tracker
from .tasks import AllosteryTask, StrainReference, check_strain_reference

__all__ = [
    "COUPLED_AT",
    "DECOUPLED_BELOW",
    "MET_AT",
    "SCALES",
    "Coupling",
    "body_source_share",
    "coupling_verdict",
    "measure_coupling",
    "outcome",
    "source_share",
]

#: source share at and above which a trained network is "coupled"
COUPLED_AT = 0.5
#: source share below which it is "decoupled"
DECOUPLED_BELOW = 0.1
#: final C/C0 at or below which a task counts as met (two decades of error reduction)
MET_AT = 1e-2
#: source-strain scale factors of the sweep (0: sources off, 1: the task)
SCALES = (0.0, 0.5, 1.0, 1.5, 2.0)


def source_share(
    on: ArrayLike, off: ArrayLike, initial_off: ArrayLike, initial_on: ArrayLike
) -> float:
    """The source share of the module docstring, in [0, 1].

    Parameters
    ----------
    on, off : (n_targets,) float arrays
        Target outputs of the trained network with the sources at the task's strains and
        at zero strain.
    initial_off, initial_on : (n_targets,) float arrays
        The same for the initial network.
    """
    arrays = [np.asarray(a, dtype=np.float64).ravel() for a in (on, off, initial_off, initial_on)]
    if len({a.size for a in arrays}) != 1:
        raise ValueError(
            "on, off, initial_off and initial_on need one entry per target, got "
            + ", ".join(str(a.size) for a in arrays)
        )
    if not np.all(np.isfinite(np.concatenate(arrays))):
        raise ValueError("on, off, initial_off and initial_on must be finite")
    on, off, base_off, base_on = arrays
    transmitted = on - off
    offset = off - base_off
    t, o = float(np.linalg.norm(transmitted)), float(np.linalg.norm(offset))
    responds = t / (t + o) if t + o > 0 else 0.0
    change = on - base_on
    c2 = float(change @ change)
    if c2 == 0.0:
        return responds
    delivered = float((transmitted - (base_on - base_off)) @ change) / c2
    return min(responds, min(max(delivered, 0.0), 1.0))


def body_source_share(initial, trained, task) -> float:
    """:func:`source_share` of a trained continuum ``trained`` (a
    :class:`~continuum_vs_network.continuum.learnable.LearnableBody`) started from
    ``initial`` on its ``task`` (a ``MaterialTask``): the target strains of its free state
    with the sources on and off, against the initial body's."""
    import dataclasses

    off = dataclasses.replace(task, source_strain=np.zeros(task.n_sources))
    return source_share(
        trained.free_state(task).target_strain,
        trained.free_state(off).target_strain,
        initial.free_state(off).target_strain,
        initial.free_state(task).target_strain,
    )


def coupling_verdict(share: float) -> str:
    """``"coupled"``, ``"partially coupled"`` or ``"decoupled"`` (rule: module docstring)."""
    if not np.isfinite(share) or not (0.0 <= share <= 1.0):
        raise ValueError(f"share must be in [0, 1], got {share}")
    if share >= COUPLED_AT:
        return "coupled"
    if share < DECOUPLED_BELOW:
        return "decoupled"
    return "partially coupled"


def outcome(error_ratio: float, verdict: str | None) -> str:
    """What a run achieved: its final ``C/C0`` and its coupling verdict together.

    ``"learned (coupled)"`` / ``"learned, partially coupled"`` when ``C/C0 <= MET_AT`` and
    the network is (partially) coupled; ``"met trivially (decoupled)"`` when the task is
    met by a decoupled network; ``"not met"`` when ``C/C0 > MET_AT``; ``"not measured"``
    when either number is missing.
    """
    if verdict is None or error_ratio is None or not np.isfinite(error_ratio):
        return "not measured"
    if error_ratio > MET_AT:
        return "not met"
    if verdict == "decoupled":
        return "met trivially (decoupled)"
    if verdict == "coupled":
        return "learned (coupled)"
    return "learned, partially coupled"


@dataclass(frozen=True, eq=False)
class Coupling:
    """The coupling measurement of one trained network.

    Attributes
    ----------
    scales : (n_points,) float array
        Source-strain scale factors ``lambda`` of the sweep (they include 0 and 1).
    sweep : (n_points, n_targets) float array
        Target strains of the trained network at ``lambda * task.source_strain``; NaN
        where the equilibrium could not be found.
    initial_off, initial_on : (n_targets,) float arrays
        Target strains of the initial network with the sources off and on.
    desired : (n_targets,) float array
        The task's desired target strains.
    """

    scales: NDArray[np.float64]
    sweep: NDArray[np.float64]
    initial_off: NDArray[np.float64]
    initial_on: NDArray[np.float64]
    desired: NDArray[np.float64]

    def _at(self, scale: float) -> NDArray:
        return self.sweep[int(np.flatnonzero(self.scales == scale)[0])]

    @property
    def on(self) -> NDArray:
        """Target strains with the sources on (the task), (n_targets,)."""
        return self._at(1.0)

    @property
    def off(self) -> NDArray:
        """Target strains with the sources off (zero strain), (n_targets,)."""
        return self._at(0.0)

    @property
    def share(self) -> float:
        """:func:`source_share` of this network."""
        return source_share(self.on, self.off, self.initial_off, self.initial_on)

    @property
    def verdict(self) -> str:
        return coupling_verdict(self.share)


def _target_strains(
    net: SpringNetwork,
    task: AllosteryTask,
    scales: NDArray,
    strain_reference: str,
    tracker: Tracker,
) -> NDArray:
    """Target strains at every scale, continued from ``lambda = 1`` outwards; NaN past a
    failed solve on either side, or past a scale that strains a source to ``<= -0.9``."""
    out = np.full((scales.size, task.n_targets), np.nan)
    start = tracker.solve(
        net, task.pinned, task.source_clamps(net, strain_reference), None, key="free"
    ).positions
    one = np.flatnonzero(scales == 1.0)
    out[one] = task.target_strains(net, net.lengths(start, task.targets), strain_reference)
    for side in (scales > 1.0, scales < 1.0):
        x = start
        for i in np.flatnonzero(side)[np.argsort(np.abs(scales[side] - 1.0))]:
            strain = scales[i] * task.source_strain
            if np.any(strain <= -0.9):  # a source would be squeezed to under 10 % of L
                break
            t = task.with_source_strain(strain)
            try:
                eq = tracker.solve(
                    net, task.pinned, t.source_clamps(net, strain_reference), x, key="free"
                )
            except EquilibriumError:
                break
            x = eq.positions
            out[i] = t.target_strains(net, net.lengths(x, task.targets), strain_reference)
    return out


def measure_coupling(
    initial: SpringNetwork,
    trained: SpringNetwork,
    task: AllosteryTask,
    *,
    strain_reference: StrainReference = "initial",
    scales: Sequence[float] = SCALES,
    solver: Solver | None = None,
) -> Coupling:
    """Target strains of ``trained`` over a source sweep and of ``initial`` sources off and on.

    Parameters
    ----------
    initial, trained : SpringNetwork
        The network before and after training (same topology).
    task : AllosteryTask
    strain_reference : {"initial", "current"}
        The run's strain convention (clamp lengths and read-out).
    scales : sequence of float
        Source-strain scale factors; must contain 0 and 1.
    solver : Solver, optional

    Returns
    -------
    Coupling

    Raises
    ------
    EquilibriumError
        The trained network's state at the task (``lambda = 1``) or with the sources off,
        or the initial network's, cannot be found.
    """
    check_strain_reference(strain_reference)
    s = np.unique(np.asarray(scales, dtype=np.float64))
    if not (np.any(s == 0.0) and np.any(s == 1.0)):
        raise ValueError(f"scales must contain 0 and 1, got {list(scales)}")
    if np.any(~np.isfinite(s)) or np.any(s < 0):
        raise ValueError(f"scales must be finite and >= 0, got {list(scales)}")
    if initial.springs.shape != trained.springs.shape:
        raise ValueError("initial and trained must have the same springs")
    tracker = Tracker(solver or Solver())
    sweep = _target_strains(trained, task, s, strain_reference, tracker)
    if not np.all(np.isfinite(sweep[(s == 0.0) | (s == 1.0)])):
        raise EquilibriumError(
            "coupling: the trained network's state at the task or with the sources off "
            "could not be found"
        )
    off_task = task.with_source_strain(np.zeros(task.n_sources))
    initial_tracker = Tracker(solver or Solver())
    initial_strains = []
    for t in (off_task, task):
        eq = initial_tracker.solve(
            initial, task.pinned, t.source_clamps(initial, strain_reference), None, key="free"
        )
        initial_strains.append(
            t.target_strains(initial, initial.lengths(eq.positions, task.targets), strain_reference)
        )
    return Coupling(
        scales=s,
        sweep=sweep,
        initial_off=initial_strains[0],
        initial_on=initial_strains[1],
        desired=np.array(task.target_strain),
    )
