"""How a rule reads a state: relative read-out noise and temperature.

Every spring length a rule reads is ``r (1 + noise xi)`` with ``xi ~ N(0, 1)``, taken at
one thermal draw around the equilibrium when ``temperature`` (``k_B T``) is positive
(:func:`~.thermal.thermal_sample`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .step import LearningError

__all__ = ["Readout"]


@dataclass(frozen=True)
class Readout:
    """How a rule reads a state: relative read-out noise and temperature (``k_B T``)."""

    noise: float = 0.0
    temperature: float = 0.0

    def lengths(self, net, state, pinned, clamps, rng) -> NDArray:
        """Spring lengths of ``state`` as read: one thermal draw around it
        (:func:`~.thermal.thermal_sample`) when ``temperature > 0``, then read-out noise."""
        x = state.positions
        if self.temperature > 0:
            from .thermal import thermal_sample

            try:
                x = thermal_sample(net, pinned, clamps, state, self.temperature, rng)
            except ValueError as err:
                raise LearningError(str(err)) from err
        return _noisy(net.lengths(x), self.noise, rng)


def _noisy(lengths: NDArray, noise: float, rng: np.random.Generator | None) -> NDArray:
    if noise == 0.0:
        return lengths
    return lengths * (1.0 + noise * rng.standard_normal(lengths.shape))
