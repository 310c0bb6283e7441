"""How a rule's update becomes a step: the paper's raw rate, or a per-spring adaptive rate.

A rule computes, per spring, the line of its learning equation (Eq. 14-15, 22-23, the
adjoint gradient, directed aging): the *raw* update. Two ways turn it into a step:

* **raw** (``alpha`` given): ``delta = alpha * line``, the paper's equations as printed. The
  rate must be retuned for every dof and task (the raw line scales with the stiffness, the
  strains and the number of examples; 1e4 apart between rest lengths and stiffnesses of the
  same network). A material with a fixed susceptibility learns this way.
* **scaled** (:class:`Scaled`, the default of the clamped-only rules, GPC and directed
  aging, whose raw line has one sign for every spring): the raw rate with ``alpha`` chosen
  at the first step so that the largest change is ``step * scale``, then fixed. Scale-free
  like the adaptive rate, physical like the raw one (one susceptibility for the material).
* **adaptive** (:class:`Adaptive`, the default of GCL and the exact gradient when ``alpha``
  is left out): each spring keeps
  two running averages of its own raw updates (Adam; Kingma & Ba 2015), ``m`` of the update
  and ``v`` of its square, and steps by ``step * scale * m_hat / sqrt(v_hat)``
  (``m_hat``, ``v_hat`` bias-corrected). The step is scale-free: ``scale`` is the mean
  initial stiffness for stiffnesses and ``max |task strain| * mean initial rest length``
  for rest lengths, so ``step = 0.05`` moves a spring by at most about 5 % of the task's own
  scale per step, whatever the units, the dof or the number of examples. Stern's group
  trains with a per-edge adaptive rate (AdaGrad) for the same reason.

The adaptive rate stays local: a spring reads only its own history. A material could carry
it only with a per-bond memory of its recent updates (two internal variables per bond that
relax with the times ``1/(1 - beta1)`` and ``1/(1 - beta2)`` steps) and a response that
normalises by the second; no known material does both, so the raw rate is the physical
baseline and the adaptive one is what a designed learning machine would implement.

The state (:class:`RateState`) travels between steps with the warm starts
(:class:`~.step.Warm`), and with it the values of the learning dofs when training started,
which the physical range (:mod:`.ranges`) is relative to.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check

__all__ = ["NOISE", "Adaptive", "Rate", "RateState", "Scaled"]

#: relative size below which a spring's running update is treated as round-off
NOISE = 1e-8
_TINY = np.finfo(np.float64).tiny


@dataclass(frozen=True)
class Adaptive:
    """Per-spring adaptive rate (Adam), scale-free (see the module).

    Parameters
    ----------
    step : float
        Largest change per step as a fraction of the dof's scale (> 0; default 0.05).
    beta1, beta2 : float
        Decay factors of the running averages of the update and of its square, in [0, 1).
    """

    step: float = 0.05
    beta1: float = 0.9
    beta2: float = 0.999

    def __post_init__(self) -> None:
        check.real("step", self.step, low=0, low_open=True)
        for name in ("beta1", "beta2"):
            check.real(name, getattr(self, name), low=0, high=1, high_open=True)

    def delta(self, raw: NDArray, scale: NDArray, state: RateState) -> tuple[NDArray, RateState]:
        """The step from ``raw`` (shape of the dof: ``(n,)`` or ``(2, n)``) and the new state.

        ``scale`` broadcasts against ``raw`` (one value per row).
        """
        t = state.steps + 1
        first = self.beta1 * state.first + (1.0 - self.beta1) * raw
        second = self.beta2 * state.second + (1.0 - self.beta2) * raw * raw
        m_hat = first / (1.0 - self.beta1**t)
        root = np.sqrt(second / (1.0 - self.beta2**t))
        # updates at round-off level (below NOISE of the largest spring's) do not move a
        # spring: Adam's sign-like first steps would otherwise amplify solver noise
        floor = NOISE * np.max(root, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.where(root > 0, m_hat / np.maximum(root + floor, _TINY), 0.0)
        new = RateState(initial=state.initial, steps=t, first=first, second=second)
        return self.step * scale * direction, new


@dataclass(frozen=True)
class Scaled:
    """The raw rate made scale-free once: ``alpha`` set at the first step so that its largest
    change is ``step * scale``, then kept (see the module).

    Parameters
    ----------
    step : float
        Largest change of the first step as a fraction of the dof's scale (> 0).
    """

    step: float = 0.02

    def __post_init__(self) -> None:
        check.real("step", self.step, low=0, low_open=True)

    def delta(self, raw: NDArray, scale: NDArray, state: RateState) -> tuple[NDArray, RateState]:
        """The step from ``raw`` and the new state (the gain is fixed at the first step)."""
        if state.steps == 0:  # set the gain (again, while every raw update is 0)
            largest = np.max(np.abs(raw), axis=-1, keepdims=True)
            top = np.where(largest > 0, largest, np.inf)
            gain = np.broadcast_to(self.step * scale / top, raw.shape).astype(np.float64)
            steps = int(np.any(largest > 0))
        else:
            gain, steps = state.first, state.steps + 1
        new = RateState(initial=state.initial, steps=steps, first=gain, second=gain)
        return gain * raw, new


Rate = Adaptive | Scaled


@dataclass(frozen=True, eq=False)
class RateState:
    """What a rule carries from step to step besides the equilibria.

    Attributes
    ----------
    initial : (n_springs,) or (2, n_springs) float array
        The learning dofs when training started (rows ``JOINT`` for ``dof="both"``): the
        physical range is relative to them, and so is the adaptive rate's scale.
    steps : int
        Adaptive steps taken (0 with the raw rate).
    first, second : float arrays shaped like ``initial``
        Running averages of the raw update and of its square (:class:`Adaptive`), or the
        gain per spring (:class:`Scaled`, both); zeros with the raw rate.
    """

    initial: NDArray
    steps: int
    first: NDArray
    second: NDArray

    @classmethod
    def start(cls, initial: NDArray) -> RateState:
        initial = np.array(initial, dtype=np.float64)
        zero = np.zeros_like(initial)
        return cls(initial=initial, steps=0, first=zero, second=zero.copy())

    def to_arrays(self, prefix: str) -> dict[str, NDArray]:
        return {
            f"{prefix}initial": self.initial,
            f"{prefix}steps": np.array(self.steps),
            f"{prefix}first": self.first,
            f"{prefix}second": self.second,
        }

    @classmethod
    def from_arrays(cls, files, prefix: str) -> RateState | None:
        if f"{prefix}initial" not in files:
            return None
        return cls(
            initial=np.asarray(files[f"{prefix}initial"], dtype=np.float64),
            steps=int(files[f"{prefix}steps"]),
            first=np.asarray(files[f"{prefix}first"], dtype=np.float64),
            second=np.asarray(files[f"{prefix}second"], dtype=np.float64),
        )
