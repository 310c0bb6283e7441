"""One learning step and the warm starts between steps: what a rule returns.

A :class:`Step` holds the change of the learning degrees of freedom (``dof``: rest lengths,
stiffnesses, both together in the rows :data:`JOINT`, or a continuum's ``eigenstrain`` or
``modulus``) and the states the rule found; :meth:`Step.apply` gives the next network and
raises :class:`LearningError` where a value would leave its range. :class:`Warm` carries the
equilibria from one step to the next.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..network.equilibrium import Equilibrium
from ..network.model import SpringNetwork
from .rates import RateState

__all__ = ["JOINT", "Dof", "LearningError", "Step", "Warm", "check_finite_update"]

Dof = Literal["rest_length", "stiffness", "both", "eigenstrain", "modulus"]
#: the rows of a joint (``dof="both"``) update, in order
JOINT = ("rest_length", "stiffness")


class LearningError(RuntimeError):
    """A learning step that cannot be applied (a rest length or stiffness left its range)."""


@dataclass(frozen=True)
class Warm:
    """Warm starts carried from one learning step to the next.

    Attributes
    ----------
    free, clamped : (n_nodes, 2) float arrays or None
        The last free and clamped equilibria.
    previous_free : (n_nodes, 2) float array or None
        The free equilibrium one step earlier: with ``free`` it extrapolates the next free
        state (a guess for the fast solver; the warm start stays ``free``).
    examples : tuple of Warm or None
        One warm start per example of a :class:`~.examples.TaskSet`.
    rate : RateState or None
        The learning rate's state and the dofs' initial values (:mod:`.rates`); None
        before the first step.
    """

    free: NDArray | None = None
    clamped: NDArray | None = None
    previous_free: NDArray | None = None
    examples: tuple[Warm, ...] | None = None
    rate: RateState | None = None

    def example(self, e: int) -> Warm:
        """The warm start of example ``e`` (empty when there is none)."""
        return self.examples[e] if self.examples is not None else Warm()

    def free_guess(self) -> NDArray | None:
        """Linear extrapolation ``2 free - previous_free`` (or ``free``)."""
        if self.free is None or self.previous_free is None:
            return None
        return 2.0 * np.asarray(self.free) - np.asarray(self.previous_free)


@dataclass(frozen=True, eq=False)
class Step:
    """One learning step: the change of the learning degrees of freedom and the states.

    Attributes
    ----------
    delta : (n_springs,) float array, or (2, n_springs) for ``dof="both"``
        Change of ``L`` or ``k`` (masks and floors applied); for ``"both"`` the rows are
        the changes of ``L`` and of ``k`` (:data:`JOINT`), learned together.
    dof : {"rest_length", "stiffness", "both"}
    free : Equilibrium or None
        Free state (sources clamped) of the network before the step, when the rule used one.
    clamped : Equilibrium or None
        Nudged (GCL) or clamped (GPC) state, when the rule used one.
    clamp_lengths : (n_targets,) float array or None
        Lengths the targets were clamped at in ``clamped``.
    measured_free, measured_clamped : (n_springs,) float arrays or None
        Spring lengths as the rule read them (with read-out noise, if any).
    raw : (n_springs,) float array
        The rule's update before masks and floors.
    examples : tuple of Step or None
        For a :class:`~.examples.TaskSet`: each example's step (its states and raw
        update, masked, as its ``delta``); ``delta`` is their summed ``raw`` made a step
        once (rate, floors and range).
    rate : RateState or None
        The rate's state after this step (carried to the next by :attr:`warm`).
    """

    delta: NDArray[np.float64]
    dof: Dof
    free: Equilibrium | None
    clamped: Equilibrium | None
    clamp_lengths: NDArray | None = None
    measured_free: NDArray | None = field(default=None, repr=False)
    measured_clamped: NDArray | None = field(default=None, repr=False)
    raw: NDArray | None = field(default=None, repr=False)
    previous: Warm | None = field(default=None, repr=False)
    examples: tuple[Step, ...] | None = field(default=None, repr=False)
    rate: RateState | None = field(default=None, repr=False)

    @property
    def warm(self) -> Warm:
        """Warm starts for the next step (this step's states; the older ones kept)."""
        if self.examples is not None:
            return Warm(examples=tuple(s.warm for s in self.examples), rate=self.rate)
        before = self.previous or Warm()
        return Warm(
            free=before.free if self.free is None else self.free.positions,
            clamped=before.clamped if self.clamped is None else self.clamped.positions,
            previous_free=before.free if self.free is not None else before.previous_free,
            rate=self.rate,
        )

    def apply(self, net: SpringNetwork) -> SpringNetwork:
        """The network after this step.

        Raises
        ------
        LearningError
            A rest length would become ``<= 0`` or a stiffness ``< 0`` (set a floor).
        """
        if not isinstance(net, SpringNetwork):  # another learning medium (.medium)
            try:
                return net.apply_update(self.dof, self.delta)
            except ValueError as err:
                raise LearningError(str(err)) from err
        check_finite_update(self.delta, self.dof)
        if self.dof == "both":  # rest lengths and stiffnesses together: rows JOINT
            for dof, row in zip(JOINT, self.delta):
                net = _apply_one(net, dof, row)
            return net
        return _apply_one(net, self.dof, self.delta)


def _apply_one(net: SpringNetwork, dof: str, delta: NDArray) -> SpringNetwork:
    """``net`` with ``delta`` added to its rest lengths or stiffnesses (checked)."""
    rest = dof == "rest_length"
    new = (net.rest_length if rest else net.stiffness) + delta
    check_finite_update(new, dof)
    bad = np.flatnonzero(new <= 0 if rest else new < 0)
    if bad.size:
        j = int(bad[0])
        name, bound, floor = (
            ("rest length", "<= 0", "min_rest_length")
            if rest
            else ("stiffness", "< 0", "min_stiffness")
        )
        raise LearningError(
            f"{name} of spring {j} would become {new[j]:.3g} {bound} "
            f"({bad.size} springs); set {floor} to floor it"
        )
    return net.with_rest_length(new) if rest else net.with_stiffness(new)


def check_finite_update(values: NDArray, dof: str) -> None:
    """A non-finite update (an overflow: learning rate too large, a diverged state) stops."""
    values = np.asarray(values)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        j = int(bad[0]) % values.shape[-1]
        value = values.ravel()[bad[0]]
        raise LearningError(
            f"the {dof} update of spring {j} is not finite ({value}; {bad.size} springs): "
            f"the step overflowed (lower the learning rate)"
        )
