"""Learning rules: coupled learning, prospective configuration and the exact gradient.

Every rule is a frozen dataclass whose :meth:`~Rule.update` takes a network and a task,
finds the equilibria it needs and returns a :class:`Step`: the change of the learning
degrees of freedom (rest lengths ``L`` or stiffnesses ``k``) for one step, plus what was
measured. Applying it (:meth:`Step.apply`) gives the next network.

Signs (derived here; Eq. 14 of the paper has its two lines of opposite sign)
------------------------------------------------------------------------------
With ``E = sum_j k_j (r_j - L_j)^2 / 2``, ``dE/dL_j = -k_j (r_j - L_j)`` and
``dE/dk_j = (r_j - L_j)^2 / 2``. At an equilibrium with fixed clamps the total
derivative of the minimum energy equals the partial one (envelope theorem), so descending
the contrastive function ``(E^C - E^F) / eta`` with rate ``alpha`` gives

* coupled learning (GCL, Eq. 14-15)::

      dL_j = (alpha / eta) k_j (r_j^C - r_j^F)
      dk_j = (alpha / (2 eta)) [(r_j^F - L_j)^2 - (r_j^C - L_j)^2]

  For a nudged state that pulls the target towards its desired length, ``r^C - r^F``
  points the same way for the springs that must change, so the rest lengths follow the
  nudge. (The second line of Eq. 14, ``k (r^F - L) - k (r^C - L)``, is the negative of
  this; implementing it literally makes the error grow: ``tests/test_learning_rules.py``
  checks that one small step of this rule lowers the error.)

* prospective configuration (GPC, Eq. 22-23), descending ``E^C`` of the fully clamped
  state::

      dL_j = alpha k_j (r_j^C - L_j)
      dk_j = -(alpha / 2) (r_j^C - L_j)^2

  Eq. 23 prints ``dk = +alpha (r - L)^2``, which ascends the energy and contradicts its
  own first line ``dk = -alpha dE/dk``; the derivation's sign and factor are used.

* exact gradient: ``d theta = -alpha dC/d theta`` with ``dC/d theta`` from the adjoint
  of the free state (:func:`~.sensitivity.cost_gradient`).

What coupled learning descends
------------------------------
To first order in ``eta``, ``GCL / alpha = -d/dtheta [(r_T - l_T)^T K (r_T - l_T) / 2]``
where ``K`` is the targets' effective stiffness (the inverse of their compliance in the
source-clamped network, :meth:`~.sensitivity.Sensitivity.compliance`) and the clamp and
desired lengths ``l`` are *held fixed* (:func:`~.sensitivity.gcl_limit`; the relative
error is O(eta): about 1e-1, 7e-3, 7e-4, 7e-5 for eta = 1e-1 ... 1e-4 on the paper's
trials). With ``strain_reference="initial"`` this is the gradient of Eq. 26 up to the
factor ``K L0^2`` (one target). With the paper's ``"current"`` convention the lengths
``l = L (S + 1)`` move with the learning ``L`` and the strain is ``r_T / L_T - 1``; GCL
ignores both dependencies, and its update is nearly orthogonal to the gradient of Eq. 26
(cosine -0.15 median, -0.45 ... 0.40 over the paper's trials). Worse, the target's own
update ``dL_T = alpha k_T L_T (S_T - S_T^F)`` is a positive feedback there: a longer
``L_T`` lowers ``S_T^F = r_T / L_T - 1`` and so lengthens it again, and ``L_T`` grows
exponentially when the target should stretch (or runs to 0 when it should shrink).
Prospective configuration in the ``"current"`` convention has the same runaway on every
clamped spring (``dL = alpha k S L``).

Options every rule honours: see :mod:`.rule_base`. The base :class:`Rule`, the
:class:`Step` a rule returns with its :class:`Warm` starts (:mod:`.step`) and
:class:`Readout` (:mod:`.readout`) are importable from here as well.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from .node_tasks import NodeTask, node_cost_gradient
from .rates import Rate, Scaled
from .readout import Readout
from .rule_base import Rule
from .sensitivity import Cost, Sensitivity, cost_gradient
from .step import JOINT, Dof, LearningError, Step, Warm

__all__ = [
    "JOINT",
    "CoupledLearning",
    "Dof",
    "ExactGradient",
    "LearningError",
    "ProspectiveConfiguration",
    "Readout",
    "Rule",
    "Step",
    "Warm",
]


def _check_rate(name: str, value: float) -> None:
    check.real(name, value, low=0, low_open=True)


@dataclass(frozen=True, kw_only=True)
class CoupledLearning(Rule):
    """Generalised coupled learning (Stern et al. 2021; Eq. 13-15).

    Free state: sources clamped. Nudged state: targets also clamped, at strains
    ``S^F + eta (S_T - S^F)`` (Eq. 13). Update ``dL = (alpha / eta) k (r^C - r^F)`` or
    ``dk = (alpha / 2 eta) [(r^F - L)^2 - (r^C - L)^2]`` (signs: module docstring).

    Parameters
    ----------
    alpha : float or None
        The paper's raw learning rate (> 0): ``delta = alpha * line``. None (the default):
        the scale-free ``rate`` (:class:`~.rates.Adaptive` unless given; :mod:`.rates`).
    eta : float
        Nudge amplitude (> 0; 1 clamps the targets at their desired strains; default 0.1).
    """

    alpha: float | None = field(default=None, kw_only=False)
    eta: float = field(default=0.1, kw_only=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_rate("eta", self.eta)

    def _update(self, net, task, warm, tracker, read, rng) -> Step:
        if isinstance(task, NodeTask):
            free, nudged, lengths, r_free, r_nudged = self._node_states(net, task, warm, tracker)
        else:
            free, nudged, lengths, r_free, r_nudged = self._states(
                net, task, warm, tracker, read, rng
            )
        k, L = net.stiffness, net.rest_length

        def local(dof: str) -> NDArray:
            if dof == "rest_length":
                return (self._alpha / self.eta) * k * (r_nudged - r_free)
            return (self._alpha / (2 * self.eta)) * ((r_free - L) ** 2 - (r_nudged - L) ** 2)

        raw = self._per_dof(local)
        return Step(
            delta=self._delta(net, task, raw),
            dof=self.dof,
            free=free,
            clamped=nudged,
            clamp_lengths=lengths,
            measured_free=r_free,
            measured_clamped=r_nudged,
            raw=raw,
        )

    def _node_states(self, net, task, warm, tracker):
        """Free state and the state with the outputs nudged and held (NodeTask.hold)."""
        free = self._free(net, task, tracker, warm)
        out = task.outputs(free.positions)
        nudge = out + self.eta * (task.desired - out)
        nudged = task.hold(net, tracker, free.positions, nudge, key="nodes")
        return free, nudged, nudge, net.lengths(free.positions), net.lengths(nudged.positions)

    def _states(self, net, task, warm, tracker, read, rng):
        """Free state and the state with the target springs nudged (Eq. 13)."""
        ref = self.strain_reference
        free = self._free(net, task, tracker, warm)
        r_free = read.lengths(net, free, task.pinned, task.source_clamps(net, ref), rng)
        s_free = task.target_strains(net, r_free[task.targets], ref)
        s_nudge = s_free + self.eta * (task.target_strain - s_free)
        lengths = task.target_rest(net, ref) * (1.0 + s_nudge)
        if np.any(lengths <= 0):
            raise LearningError(f"nudged target length {lengths.min():.3g} <= 0")
        rest = net.rest_length[task.targets]
        if np.any(lengths > 1e6 * rest):
            # no clamp holds a spring at over 1e6 x its rest length (a target whose rest
            # length ran to the floor in the "current" convention): the trial stops here
            raise LearningError(
                f"nudged target length {np.max(lengths / rest):.3g} x the target's rest length"
            )
        clamps = task.source_clamps(net, ref)
        clamps.update(zip(task.targets.tolist(), lengths.tolist()))
        guess = None
        if warm.clamped is not None and warm.free is not None:
            # the nudge moves the network about as much as it did one step earlier
            guess = free.positions + (np.asarray(warm.clamped) - np.asarray(warm.free))
        nudged = tracker.solve(net, task.pinned, clamps, free.positions, key="free", guess=guess)
        r_nudged = read.lengths(net, nudged, task.pinned, clamps, rng)
        return free, nudged, lengths, r_free, r_nudged

    def _medium_step(self, medium, task, tracker) -> Step:
        free = medium.free_state(task, tracker=tracker)
        nudge = free.target_strain + self.eta * (task.target_strain - free.target_strain)
        nudged = medium.clamped_state(task, nudge, tracker=tracker)
        raw = -(self._alpha / self.eta) * medium.local_gradient(nudged, self.dof, minus=free)
        return self._medium_result(medium, task, raw, free, nudged, nudge)


@dataclass(frozen=True, kw_only=True)
class ProspectiveConfiguration(Rule):
    """Generalised prospective configuration (Eq. 22-23): the clamped state only.

    Sources and targets are clamped at their strains (targets at the *desired* strains,
    not a nudge); the update descends that state's energy:
    ``dL = alpha k (r^C - L)`` or ``dk = -(alpha / 2) (r^C - L)^2``.

    Parameters
    ----------
    alpha : float or None
        The paper's raw learning rate (> 0). None (the default): the scale-free ``rate``
        (:class:`~.rates.Scaled` unless given: the raw line has one sign for every
        stiffness, so a per-spring adaptive rate would weaken every stressed spring alike).
    """

    alpha: float | None = field(default=None, kw_only=False)
    default_rate: ClassVar[Rate] = Scaled()

    @property
    def uses_free_state(self) -> bool:
        return False

    def _update(self, net, task, warm, tracker, read, rng) -> Step:
        def local(dof: str, k: NDArray, L: NDArray, r_c: NDArray) -> NDArray:
            if dof == "rest_length":
                return self._alpha * k * (r_c - L)
            return -0.5 * self._alpha * (r_c - L) ** 2

        return self._clamped_only_step(net, task, warm, tracker, read, rng, local)

    def _medium_step(self, medium, task, tracker) -> Step:
        clamped = medium.clamped_state(task, task.target_strain, tracker=tracker)
        raw = -self._alpha * medium.local_gradient(clamped, self.dof)
        return self._medium_result(medium, task, raw, None, clamped, task.target_strain)


@dataclass(frozen=True, kw_only=True)
class ExactGradient(Rule):
    """Gradient descent on the task error with the exact (adjoint) gradient.

    ``d theta = -alpha dC/d theta``; ``C`` is Eq. 26 (``cost="strain"``) or the length
    cost (``cost="length"``), measured with ``strain_reference`` and differentiated through
    everything that depends on the learning degrees of freedom (the reference rest
    lengths too, in the ``"current"`` convention). One free state and one extra linear
    solve with its KKT matrix per step. The reference every local rule is measured against.

    Parameters
    ----------
    alpha : float or None
        Raw learning rate (> 0): a fixed-step gradient descent. None (the default): the
        scale-free ``rate`` (:class:`~.rates.Adaptive` unless given).
    cost : {"strain", "length"}
    """

    alpha: float | None = field(default=None, kw_only=False)
    cost: Cost = "strain"

    def __post_init__(self) -> None:
        super().__post_init__()
        check.choice("cost", self.cost, ("strain", "length"))

    def _update(self, net, task, warm, tracker, read, rng) -> Step:
        free = self._free(net, task, tracker, warm)
        if isinstance(task, NodeTask):
            r_free = net.lengths(free.positions)
        else:
            clamps = task.source_clamps(net, self.strain_reference)
            r_free = read.lengths(net, free, task.pinned, clamps, rng)
        try:
            if isinstance(task, NodeTask):
                grad = self._per_dof(lambda dof: node_cost_gradient(net, task, free, dof=dof))
            else:
                sens = Sensitivity(
                    net, task.pinned, task.source_clamps(net, self.strain_reference), free
                )  # one factorisation serves both rows of dof="both"
                grad = self._per_dof(
                    lambda dof: cost_gradient(
                        net,
                        task,
                        free,
                        strain_reference=self.strain_reference,
                        dof=dof,
                        cost=self.cost,
                        target_lengths=r_free[task.targets],
                        sensitivity=sens,
                    )
                )
        except (np.linalg.LinAlgError, RuntimeError) as err:
            raise LearningError(f"exact gradient: singular KKT system ({err})") from err
        tracker.stats.factorisations += 1
        raw = -self._alpha * grad
        return Step(
            delta=self._delta(net, task, raw),
            dof=self.dof,
            free=free,
            clamped=None,
            measured_free=r_free,
            raw=raw,
        )

    def _medium_step(self, medium, task, tracker) -> Step:
        free = medium.free_state(task, tracker=tracker)
        grad = medium.task_gradient(task, free, self.dof, cost=self.cost, tracker=tracker)
        return self._medium_result(medium, task, -self._alpha * grad, free, None, None)
