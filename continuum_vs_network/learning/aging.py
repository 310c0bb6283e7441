"""Directed aging (Pashine et al. 2019; Hexner et al. 2020): a clamped-only learning rule.

The trainer imposes the task: sources *and* targets are clamped at their strains (the
fully clamped state of :class:`~.rules.ProspectiveConfiguration`), and the material ages
under the stress this applies. Hexner et al. (2020) study two microscopic models; this
package implements both, per spring ``j`` of the clamped state ``r^C``::

    rest lengths creep ("l-model")    dL_j = alpha (r_j^C - L_j)
    stiffnesses weaken ("k-model")    dk_j = -(alpha / 2) k_j (r_j^C / L_j - 1)^2

(the rate ``alpha`` is dimensionless per step in both; the k-model's weakening is
proportional to a spring's stiffness and its squared clamped strain, so a spring under no
stress does not age and ``k`` stays positive while ``alpha S^2 / 2 < 1``).

Relation to the gradient. With ``E^C = sum_j k_j (r_j^C - L_j)^2 / 2`` the clamped
energy, ``dE^C/dL_j = -k_j (r_j^C - L_j)`` and ``dE^C/dk_j = (r_j^C - L_j)^2 / 2``, so::

    aging of L:   dL_j = -(alpha / k_j) dE^C/dL_j
    aging of k:   dk_j = -(alpha k_j / L_j^2) dE^C/dk_j

Both are the gradient of the clamped energy preconditioned by positive per-spring
weights: a descent direction of ``E^C`` (its directional derivative ``-sum w_j
(dE/dtheta_j)^2 <= 0``). Generalised prospective configuration descends the same energy
without the weights: ``dL = alpha k (r^C - L)``, i.e. **GPC of rest lengths is directed
aging of rest lengths with a k-weighted rate**; with uniform stiffness ``k`` the two are
equal when ``alpha_aging = k alpha_gpc``. Neither is the gradient of the task error: both
relax the network towards a state that *can hold* the imposed strains, which lowers the
task error only as far as the free state follows the clamped one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from .rates import Rate, Scaled
from .rules import Rule, Step

__all__ = ["DirectedAging"]


@dataclass(frozen=True, kw_only=True)
class DirectedAging(Rule):
    """Directed aging of rest lengths (creep) or stiffnesses (weakening); see the module.

    Parameters
    ----------
    alpha : float or None
        Aging rate per step (> 0, dimensionless). None (the default): the scale-free
        ``rate`` (:class:`~.rates.Scaled` unless given).
    """

    alpha: float | None = field(default=None, kw_only=False)
    default_rate: ClassVar[Rate] = Scaled()

    @property
    def uses_free_state(self) -> bool:
        return False

    def _update(self, net, task, warm, tracker, read, rng) -> Step:
        def local(dof: str, k, L, r_c):
            if dof == "rest_length":
                return self._alpha * (r_c - L)
            return -0.5 * self._alpha * k * (r_c / L - 1.0) ** 2

        return self._clamped_only_step(net, task, warm, tracker, read, rng, local)

    def _medium_step(self, medium, task, tracker) -> Step:
        raise ValueError("directed aging is implemented for spring networks only")
