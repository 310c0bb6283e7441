"""What learning in physical time needs from a medium: copies that move, readings, updates.

:func:`~.physical_time.learn_in_time` runs one loop (continuous, twin and phase forms) for
every medium; a medium adapter supplies

* ``copy(target_strain, start)``: a moving copy with the sources held and the targets held
  at ``target_strain`` (None: free), from ``start`` (None: the medium at rest);
* ``advance(medium, copy, target_strain)``: one damped step of the copy with those clamps;
* ``read(medium, copy)``: the state the rule reads (a network's spring lengths, a body's
  displacement) and ``target_strain(medium, reading)``;
* ``update(rule, medium, free, clamped, dt_learn)``: the medium after one learning step
  from two readings (``free`` None for GPC): the rule's local update per spring or per
  element, masked and floored by the rule;
* ``error(medium)``: Eq. 26 at the equilibrium free state; ``positions`` and
  ``learning_arrays`` for the record.

A rule with a raw rate ``alpha`` (per time unit) steps ``alpha dt_learn`` times its line. A
rule without one (``alpha=None``, an :class:`~.rates.Adaptive` rate: GCL's default) learns
with :class:`AdaptiveClock`, the package's per-spring Adam rate in physical time: one
adaptive step per ``step_time`` of physical time, a learning step of length ``dt_learn``
taking ``dt_learn / step_time`` of a step (with ``dt_learn = step_time`` it is
:func:`~.train.train`'s step exactly). A spring (an element's modulus) reads only its own
history, as in :mod:`.rates`.

:class:`NetworkTime` steps a :class:`~..network.model.SpringNetwork` with
:class:`~..network.stepper.Stepper` (drag, dashpots, Maxwell arms), its clamps held by
default as the continuum holds them, by the clamped springs' lengths only (``clamp=
"strain"``: each clamped spring a :func:`~..network.strain_clamp.rod_clamped` rod at the
clamp length, no node held; the lengths read are the clamp lengths up to the rod's strain
error ``~ 1 / ROD_FACTOR`` of the clamp's change), or by the clamped springs' end nodes
(``clamp="nodes"``: prescribed positions set symmetrically along the spring); :class:`BodyTime` a
learning medium (:class:`~..continuum.learnable.LearnableBody`) with the medium's
:meth:`damped_stepper` (drag, Kelvin-Voigt, Maxwell arms; clamps exact). Every moving copy
carries its own arms' internal variables (a network's arm lengths, a body's internal
strains), relaxed at its start.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.typing import NDArray

from ..network.held_boundary import held_boundary
from ..network.model import SpringNetwork
from ..network.stepper import Stepper
from ..network.strain_clamp import ROD_FACTOR, rod_clamped
from ..network.viscous import Viscosity
from .medium import check_rule_on_medium
from .ranges import clip_to_range
from .rates import NOISE, Adaptive
from .rules import ProspectiveConfiguration, Step

__all__ = ["AdaptiveClock", "BodyTime", "NetworkTime", "held_free_state"]


class AdaptiveClock:
    """The adaptive (Adam) rate of :class:`~.rates.Adaptive` in physical time.

    Each learning step of length ``dt_learn`` is ``u = dt_learn / step_time`` adaptive
    steps: the running averages decay by ``beta1**u`` and ``beta2**u``, the bias
    corrections use the steps elapsed (a real number), and the change is ``step * u *
    scale * m_hat / sqrt(v_hat)``. With ``u = 1`` every step is
    :meth:`~.rates.Adaptive.delta`'s.

    Parameters
    ----------
    rate : Adaptive
    initial : (n,) float array
        The learning dofs at the start (the physical range is relative to them).
    scale : float
        The dof's scale (the mean initial stiffness or modulus; a rest length's: the task's
        largest strain times the mean initial rest length).
    step_time : float
        Physical time of one adaptive step (> 0).
    """

    def __init__(self, rate: Adaptive, initial: NDArray, scale: float, step_time: float) -> None:
        self.rate, self.scale, self.step_time = rate, float(scale), float(step_time)
        self.initial = np.array(initial, dtype=np.float64)
        self.first = np.zeros_like(self.initial)
        self.second = np.zeros_like(self.initial)
        self.elapsed = 0.0

    def delta(self, line: NDArray, dt_learn: float) -> NDArray:
        """The change of the dofs over one learning step from the rule's line (alpha = 1)."""
        r, u = self.rate, float(dt_learn) / self.step_time
        b1, b2 = r.beta1**u, r.beta2**u
        self.first = b1 * self.first + (1.0 - b1) * line
        self.second = b2 * self.second + (1.0 - b2) * line * line
        self.elapsed += u
        m_hat = self.first / (1.0 - r.beta1**self.elapsed)
        root = np.sqrt(self.second / (1.0 - r.beta2**self.elapsed))
        floor = NOISE * np.max(root, initial=0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            direction = np.where(root > 0, m_hat / np.maximum(root + floor, 1e-300), 0.0)
        return r.step * u * self.scale * direction


def _clock(rule, initial: NDArray, scale: float, step_time: float | None):
    """The rule's :class:`AdaptiveClock` (None for a raw rate ``alpha``)."""
    rate = rule.adaptive
    if rate is None:
        return None
    if not isinstance(rate, Adaptive):
        raise ValueError(
            f"{rule.name}: learning in time takes a raw alpha or an Adaptive rate, got "
            f"{type(rate).__name__}; give alpha"
        )
    if step_time is None or not (np.isfinite(step_time) and step_time > 0):
        raise ValueError(
            f"step_time must be > 0 for a rule without alpha (an adaptive rate), got {step_time}"
        )
    return AdaptiveClock(rate, initial, scale, step_time)


def _rod_tol(net: SpringNetwork, rods: SpringNetwork, tol: float) -> float:
    """The tolerance relative to ``rods``' force scale of ``tol`` relative to ``net``'s,
    not below ``100 eps ROD_FACTOR`` (:func:`~..network.strain_clamp.simulate_strain_clamped`)."""
    tol = max(float(tol), 100.0 * np.finfo(float).eps * ROD_FACTOR)
    return tol * net.force_scale / rods.force_scale


def _equilibrium_stepper(net: SpringNetwork, free: NDArray, tol: float) -> Stepper:
    """A backward-Euler step of length ``1e12 / k_mean`` with unit drag: its proximal term
    ``1e-12 k_mean |x - x0|^2 / 2`` is negligible, so one step is the equilibrium with the
    held coordinates (Newton with a line search, the factorisation reused)."""
    return Stepper(net, Viscosity(drag=1.0), free, 1e12 / float(np.mean(net.stiffness)), tol=tol)


def held_free_state(
    net: SpringNetwork,
    task,
    *,
    reference: str = "initial",
    tol: float = 1e-10,
    clamp: str = "strain",
) -> NDArray:
    """Free state (n_nodes, 2) of ``net`` as learning in time holds it: the task's sources
    at their clamp lengths (``reference`` convention), its pins held, the rest at
    equilibrium (the state :meth:`NetworkTime.error` reads). ``clamp="strain"``: the
    sources as rods, no node held; ``"nodes"``: by their end nodes, set symmetrically
    along each spring from ``net.positions`` and held.

    Raises
    ------
    RuntimeError
        The equilibrium step does not converge.
    """
    check_clamp(clamp)
    clamps = task.source_clamps(net, reference)
    if clamp == "strain":
        rods = rod_clamped(net, clamps)
        free = held_boundary(net, task.pinned, None, None, net.positions)[1]
        stepper = _equilibrium_stepper(net, free, _rod_tol(net, rods, tol))
        return stepper.step(rods, net.positions)[0]
    x, free = held_boundary(net, task.pinned, None, clamps, net.positions)
    return _equilibrium_stepper(net, free, tol).step(net, x)[0]


def check_clamp(clamp: str) -> None:
    """Refuse a ``clamp`` other than ``"strain"`` or ``"nodes"``."""
    if clamp not in ("strain", "nodes"):
        raise ValueError(f"clamp must be 'strain' or 'nodes', got {clamp!r}")


class _Copy:
    """One moving network: positions (and the previous ones, for the predictor), arms,
    held coordinates and its stepper."""

    def __init__(self, x, free, arm, stepper) -> None:
        self.x, self.free, self.arm, self.stepper = x, free, arm, stepper
        self.previous = None

    def step(self, net, held, arm=None):
        """One step to the held positions ``held``, from the linear predictor
        ``2 x - x_previous`` (the converged step does not depend on it)."""
        guess = None if self.previous is None else 2.0 * self.x - self.previous
        x1, _, arm1 = self.stepper.step(net, self.x, x_held=held, arm=arm, guess=guess)
        self.previous, self.x = self.x, x1
        return arm1


class NetworkTime:
    """A spring network in time (module docstring); ``viscosity``: a network Viscosity."""

    def __init__(
        self, net, task, rule, viscosity, dt, quasistatic, tol, step_time=None, clamp="strain"
    ) -> None:
        if not isinstance(viscosity, Viscosity):
            raise ValueError(f"viscosity must be a Viscosity, got {type(viscosity).__name__}")
        check_clamp(clamp)
        self.clamp = clamp
        self.task, self.ref, self.vis = task, rule.strain_reference, viscosity
        self.dt, self.quasistatic, self.tol = dt, quasistatic, tol
        self._free_eq = None
        self.clock = None
        if rule.adaptive is not None:
            from .rule_base import _strain_scale

            if rule.dof not in ("stiffness", "rest_length"):
                raise ValueError("an adaptive rate in time learns stiffness or rest_length")
            values = net.stiffness if rule.dof == "stiffness" else net.rest_length
            scale = float(np.mean(values))
            if rule.dof == "rest_length":
                scale *= _strain_scale(task)
            self.clock = _clock(rule, values, scale, step_time)

    def _clamps(self, net, target_strain):
        task, ref = self.task, self.ref
        clamps = task.source_clamps(net, ref)
        if target_strain is not None:
            lengths = task.target_rest(net, ref) * (1.0 + np.asarray(target_strain))
            clamps.update(zip(task.targets.tolist(), lengths.tolist()))
        return clamps

    def _stepped(self, net, copy: _Copy, clamps):
        """The network a step takes: ``net`` (end nodes held) or its rods (strain clamps;
        the copy's stepper tolerance set against ``net``'s force scale)."""
        if self.clamp == "nodes":
            return net
        rods = rod_clamped(net, clamps)
        copy.stepper.tol = _rod_tol(net, rods, self.tol)
        return rods

    def copy(self, net, target_strain, start=None) -> _Copy:
        x0 = net.positions if start is None else start.x
        clamps = self._clamps(net, target_strain) if self.clamp == "nodes" else None
        x, free = held_boundary(net, self.task.pinned, None, clamps, x0)
        if self.quasistatic:  # equilibria: arms relaxed carry no force
            return _Copy(x, free, None, _equilibrium_stepper(net, free, self.tol))
        arm = net.lengths(x) if self.vis.has_arm else None
        return _Copy(x, free, arm, Stepper(net, self.vis, free, self.dt, tol=self.tol))

    def take(self, copy: _Copy, other: _Copy) -> None:
        """``copy`` continues from ``other``'s state (one network, another clamp set)."""
        copy.x, copy.arm, copy.previous = other.x, other.arm, other.previous

    def advance(self, net, copy: _Copy, target_strain) -> None:
        clamps = self._clamps(net, target_strain)
        if self.clamp == "nodes":
            held = held_boundary(net, self.task.pinned, None, clamps, copy.x)[0]
            copy.arm = copy.step(net, held, copy.arm)
        else:
            copy.arm = copy.step(self._stepped(net, copy, clamps), None, copy.arm)

    def read(self, net, copy: _Copy) -> NDArray:
        return net.lengths(copy.x)

    def target_strain(self, net, reading: NDArray) -> NDArray:
        return self.task.target_strains(net, reading[self.task.targets], self.ref)

    def update(self, rule, net, free, clamped, dt_learn) -> SpringNetwork:
        """GPC: ``L += (1 - exp(-alpha k dt)) (r^C - L)`` (exact for lengths held over the
        step) or ``k -= alpha dt (r^C - L)^2 / 2``; GCL: forward Euler of Eq. 13-15. Under
        an adaptive rate (:class:`AdaptiveClock`) the line (``alpha = 1``, masked) steps
        through the clock and the physical range of the rule applies, as in training."""
        k, L = net.stiffness, net.rest_length
        clock = self.clock
        if clock is not None:
            if isinstance(rule, ProspectiveConfiguration):
                line = (
                    (k * (clamped - L)) if rule.dof == "rest_length" else -0.5 * (clamped - L) ** 2
                )
            elif rule.dof == "rest_length":
                line = (1.0 / rule.eta) * k * (clamped - free)
            else:
                line = (1.0 / (2 * rule.eta)) * ((free - L) ** 2 - (clamped - L) ** 2)
            raw = clock.delta(rule._delta(net, self.task, line), dt_learn)
            delta = rule._bounded(net, rule.dof, raw, clock.initial)
            return Step(delta=delta, dof=rule.dof, free=None, clamped=None).apply(net)
        if isinstance(rule, ProspectiveConfiguration):
            if rule.dof == "rest_length":
                raw = -np.expm1(-rule.alpha * k * dt_learn) * (clamped - L)
            else:
                raw = -0.5 * rule.alpha * dt_learn * (clamped - L) ** 2
        elif rule.dof == "rest_length":
            raw = dt_learn * (rule.alpha / rule.eta) * k * (clamped - free)
        else:
            raw = dt_learn * (rule.alpha / (2 * rule.eta)) * ((free - L) ** 2 - (clamped - L) ** 2)
        delta = rule._bounded(net, rule.dof, rule._delta(net, self.task, raw), None)
        step = Step(delta=delta, dof=rule.dof, free=None, clamped=None)
        return step.apply(net)

    def rate_bound(self, rule, net) -> float:
        """``alpha k_max``: forward-Euler learning needs ``rate_bound * dt_learn <= 1``
        (0 for GPC's exact rest-length update and for an adaptive rate, whose step is
        bounded by its ``step``)."""
        if self.clock is not None:
            return 0.0
        if isinstance(rule, ProspectiveConfiguration) and rule.dof == "rest_length":
            return 0.0
        return rule.alpha * float(np.max(net.stiffness))

    def error(self, net) -> float:
        task, ref = self.task, self.ref
        if self._free_eq is None:
            self._free_eq = self.copy(net, None)
            self._free_eq.stepper = _equilibrium_stepper(net, self._free_eq.free, self.tol)
        eq = self._free_eq
        if self.clamp == "strain":
            eq.step(self._stepped(net, eq, self._clamps(net, None)), None)
            return task.error(net, eq.x, ref)
        held = None  # "initial": the clamps stay where they were set
        if ref == "current":
            held = held_boundary(net, task.pinned, None, self._clamps(net, None), eq.x)[0]
        eq.step(net, held)
        return task.error(net, eq.x, ref)

    def positions(self, net, copy: _Copy) -> NDArray:
        return copy.x.copy()

    def target_length(self, net, copy: _Copy) -> NDArray:
        return net.lengths(copy.x, self.task.targets)

    def learning_arrays(self, net) -> tuple[NDArray, NDArray]:
        return net.rest_length.copy(), net.stiffness.copy()

    def factorisations(self, copies) -> int:
        return sum(c.stepper.factorisations for c in copies)


class BodyTime:
    """A learning medium in time (module docstring); ``viscosity``: a continuum Damping
    (or a network Viscosity, mapped by
    :func:`~continuum_vs_network.continuum.viscoelastic.lattice_damping`)."""

    def __init__(self, medium, task, rule, viscosity, dt, quasistatic, tol, step_time=None) -> None:
        if isinstance(viscosity, Viscosity):
            from ..continuum.viscoelastic import lattice_damping

            viscosity = lattice_damping(viscosity)
        check_rule_on_medium(medium, task, rule)
        if not callable(getattr(medium, "damped_stepper", None)):
            raise ValueError(
                f"net: a {type(medium).__name__} has no damped steps (damped_stepper); "
                "learning in time takes a SpringNetwork or a LearnableBody"
            )
        self.task = task
        self.stepper = medium.damped_stepper(task, viscosity, np.inf if quasistatic else dt)
        self.ref = "initial"
        self.clock = None
        if rule.adaptive is not None:
            if medium.learning_dof(rule.dof) != "modulus":
                raise ValueError(
                    "an adaptive rate in time serves a continuum's modulus field only; give "
                    "alpha for its eigenstrain"
                )
            values = medium.parameters("modulus")
            self.clock = _clock(rule, values, float(np.mean(values)), step_time)

    def copy(self, medium, target_strain, start=None):
        if start is None:
            u = np.zeros(medium.n_dofs)
            return SimpleNamespace(u=u, arm=self.stepper.rest_arm(u))
        return SimpleNamespace(u=start.u, arm=start.arm)

    def take(self, copy, other) -> None:
        copy.u, copy.arm = other.u, other.arm

    def advance(self, medium, copy, target_strain) -> None:
        copy.u, copy.arm = self.stepper.step(medium, copy.u, target_strain, arm=copy.arm)

    def read(self, medium, copy) -> NDArray:
        return copy.u

    def target_strain(self, medium, reading: NDArray) -> NDArray:
        return self.stepper.target_strain(reading)

    def update(self, rule, medium, free, clamped, dt_learn):
        """Forward Euler of the rule's local update per element (:mod:`.medium`); under an
        adaptive rate the line (``alpha = 1``) steps through :class:`AdaptiveClock`, then
        the floor and the rule's stiffness range, as in training."""
        dof = rule.dof
        state = SimpleNamespace(u=clamped)
        clock = self.clock
        alpha = 1.0 if clock is not None else rule.alpha * dt_learn
        if isinstance(rule, ProspectiveConfiguration):
            raw = -alpha * medium.local_gradient(state, dof)
        else:
            minus = SimpleNamespace(u=free)
            raw = -alpha / rule.eta * medium.local_gradient(state, dof, minus=minus)
        mask = rule.learning_mask(medium, self.task)
        raw = np.where(mask if raw.ndim == 1 else mask[:, None], raw, 0.0)
        if clock is not None:
            raw = clock.delta(raw, dt_learn)
        delta = medium.floor(dof, raw, rule.min_stiffness)
        if clock is not None:
            delta = clip_to_range(medium.modulus, delta, clock.initial, rule.stiffness_range)
        return Step(delta=delta, dof=dof, free=None, clamped=None).apply(medium)

    def rate_bound(self, rule, medium) -> float:
        """``alpha`` times the largest eigenvalue of ``s_e C_e`` (Mandel form: ``2 (lam +
        mu)`` or ``2 mu``): forward Euler needs ``rate_bound * dt_learn <= 1``."""
        if self.clock is not None:
            return 0.0
        lam, mu = np.asarray(medium.body.lam), np.asarray(medium.body.mu)
        c = np.maximum(2 * (lam + mu), 2 * mu) * np.ones(medium.n_elements)
        return rule.alpha * float(np.max(medium.modulus * c))

    def error(self, medium) -> float:
        from ..continuum.learning_states import free_target_strain

        return self.task.error(free_target_strain(medium, self.task))

    def positions(self, medium, copy) -> NDArray:
        return medium.vertex_positions(copy.u)

    def target_length(self, medium, copy) -> NDArray:
        return self.task.target_length * (1.0 + self.stepper.target_strain(copy.u))

    def learning_arrays(self, medium) -> tuple[NDArray, NDArray]:
        return medium.eigenstrain.copy(), medium.modulus.copy()

    def factorisations(self, copies) -> int:
        return self.stepper.factorisations
