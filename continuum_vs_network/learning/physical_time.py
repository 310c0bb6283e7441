"""Learning concurrent with the physical dynamics: the rules as ODEs in physical time.

The paper writes its rules as differential equations that can run with the material
(Sec. 5, Eq. 17-18) and then assumes quasi-staticity. Here the nodes and the learning
degrees of freedom evolve together as one system of ODEs; the material is a visco-elastic
network (:mod:`~continuum_vs_network.network.viscous`: node drag, spring dashpots, Maxwell
arms) and never has to reach equilibrium. The rule objects supply ``alpha``, ``eta``,
``dof``, the learning mask and floors, and the strain convention; ``alpha`` is a rate (per
time unit), so one quasi-static step of the rule with rate ``alpha`` is one explicit-Euler
step of length 1 of the ODE.

Forms (``form``)
----------------
``"continuous"`` (:class:`~.rules.ProspectiveConfiguration`)
    Sources and targets held at their clamp lengths all the time; ``L' = alpha k (r - L)``
    (or ``k' = -alpha (r - L)^2 / 2``) while the nodes move: autonomous, no phases, no
    memory. (It is a Maxwell arm with ``gamma2 = 1 / alpha`` on every learning spring.)
``"twin"`` (:class:`~.rules.CoupledLearning`)
    Two copies share the learning degrees of freedom and evolve together: a free copy
    (sources held) and a nudged copy (sources held, targets held at
    ``L_T (1 + S^F(t) + eta (S_T - S^F(t)))`` from the free copy's *current* target
    strains). ``L' = (alpha / eta) k (r^C(t) - r^F(t))``.
``"phases"`` (:class:`~.rules.CoupledLearning`)
    One network alternating a free phase and a nudged phase, each ``phase`` long; the free
    lengths are read at the end of the free phase (the nudge is set from them), the nudged
    ones at the end of the nudged phase, and one update for the cycle,
    ``dL = 2 phase (alpha / eta) k (r^C - r^F)``. Short phases: the material is not at
    equilibrium when it is read.

The exact gradient stays quasi-static (use :func:`~.train.train`).

Clamps are prescribed displacements of the clamped springs' end nodes, as in
:func:`~continuum_vs_network.network.dynamics.simulate` (set symmetrically along the
spring's current direction, then held); task pins are held. ``quasistatic=True`` replaces
every physical step by the equilibrium with the same held nodes (a backward-Euler step of
length ``1e12 / k``): the limit of a
vanishing ratio of learning rate to relaxation rate, computed directly.

Time steps (chosen separately)
------------------------------
``dt``: the physical step, backward Euler (L-stable, so stiff springs and rods are stable
at any ``dt``; accuracy needs ``dt`` well below the relaxation time, ``tau / 20`` in the
study). ``dt_learn = learn_every * dt``: the learning step, an explicit update with the
lengths read at its end (IMEX: implicit physics, explicit learning). GPC's rest-length
update is exponential, ``L += (1 - exp(-alpha k dt_learn)) (r - L)``, exact for lengths
held over the step and stable for any ``dt_learn``; GCL's is forward Euler and needs
``alpha k_max dt_learn <= 1`` (checked).

The error recorded is Eq. 26 at the equilibrium free state (sources held) of the learned
parameters at each output time: what the material has learned, not the instantaneous
state; ``target_length`` records the moving network's target lengths.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..network.dynamics import _boundary, relaxation_time
from ..network.model import SpringNetwork
from ..network.viscous import Stepper, Viscosity, simulate_viscous
from .rules import CoupledLearning, ExactGradient, ProspectiveConfiguration, Rule, Step
from .tasks import AllosteryTask

__all__ = ["Form", "TimeHistory", "learn_in_time", "network_relaxation_time"]

Form = Literal["continuous", "twin", "phases"]


@dataclass(frozen=True, eq=False)
class TimeHistory:
    """A run of :func:`learn_in_time`.

    Attributes
    ----------
    times : (T,) float array
        Output times (time units; 0 first).
    error : (T,) float array
        Eq. 26 at the equilibrium free state of the parameters learned by then.
    rest_length, stiffness : (T, n_springs) float arrays
    target_length : (T, n_targets) float array
        Target lengths of the moving network (the free copy for ``"twin"``).
    positions : (T, n_nodes, 2) float array
        The moving network (the free copy for ``"twin"``), for export.
    seconds : (T,) float array
        Wall-clock seconds at each output.
    rule, form : str
    dt, dt_learn : float
        Physical and learning time steps.
    quasistatic : bool
    factorisations : int
    """

    times: NDArray[np.float64]
    error: NDArray[np.float64]
    rest_length: NDArray[np.float64] = field(repr=False)
    stiffness: NDArray[np.float64] = field(repr=False)
    target_length: NDArray[np.float64] = field(repr=False)
    positions: NDArray[np.float64] = field(repr=False)
    seconds: NDArray[np.float64] = field(repr=False)
    rule: str
    form: str
    dt: float
    dt_learn: float
    quasistatic: bool
    factorisations: int = 0


def network_relaxation_time(
    net: SpringNetwork,
    task: AllosteryTask,
    viscosity: Viscosity,
    *,
    reference: str = "initial",
    fraction: float = 1e-2,
) -> float:
    """Relaxation time of ``net`` after the task's source step (time units).

    The sources are stepped to their clamp lengths with the task's pins held and the
    response integrated (:func:`~continuum_vs_network.network.viscous.simulate_viscous`,
    200 steps per run); the time is
    :func:`~continuum_vs_network.network.dynamics.relaxation_time` (the largest net force
    stays below ``fraction`` of its start; 1 % by default, which the slow modes dominate),
    from a run at least 3 times longer (doubled until it is).
    """
    clamps = task.source_clamps(net, reference)
    k_mean = float(np.mean(net.stiffness))
    t_end = 4.0 * (viscosity.drag + viscosity.dashpot) / k_mean * max(net.n_nodes, 4) ** 0.5
    for _ in range(30):
        traj = simulate_viscous(
            net, viscosity, dt=t_end / 200, t_end=t_end, pinned=task.pinned, clamped=clamps
        )
        try:
            tau = relaxation_time(traj, fraction)
        except ValueError:
            tau = math.inf
        if 3.0 * tau <= t_end:
            return tau
        t_end *= 2.0
    raise RuntimeError("the network does not relax after the source step (is it rigid?)")


def _equilibrium_stepper(net: SpringNetwork, free: NDArray, tol: float) -> Stepper:
    """A backward-Euler step of length ``1e12 / k_mean`` with unit drag: its proximal term
    ``1e-12 k_mean |x - x0|^2 / 2`` is negligible, so one step is the equilibrium with the
    held coordinates (Newton with a line search, the factorisation reused)."""
    return Stepper(net, Viscosity(drag=1.0), free, 1e12 / float(np.mean(net.stiffness)), tol=tol)


class _Copy:
    """One moving network: positions, arms, held coordinates, and its stepper."""

    def __init__(self, net, vis, pins, clamps, x, dt, quasistatic, tol) -> None:
        self.x, self.free = _boundary(net, pins, None, clamps, x)
        self.pins = pins
        self.quasistatic = quasistatic
        self.arm = net.lengths(self.x) if vis.has_arm and not quasistatic else None
        if quasistatic:  # equilibria: arms relaxed carry no force
            self.stepper = _equilibrium_stepper(net, self.free, tol)
        else:
            self.stepper = Stepper(net, vis, self.free, dt, tol=tol)

    def hold(self, net: SpringNetwork, clamps: dict[int, float]) -> NDArray:
        """Positions with the clamped nodes moved to ``clamps``' lengths."""
        return _boundary(net, self.pins, None, clamps, self.x)[0]

    def advance(self, net: SpringNetwork, x_held: NDArray | None = None) -> None:
        self.x, _, self.arm = self.stepper.step(net, self.x, x_held=x_held, arm=self.arm)

    @property
    def factorisations(self) -> int:
        return self.stepper.factorisations


def _nudge(task: AllosteryTask, net: SpringNetwork, r_free: NDArray, rule: CoupledLearning):
    ref = rule.strain_reference
    s_free = task.target_strains(net, r_free[task.targets], ref)
    s_nudge = s_free + rule.eta * (task.target_strain - s_free)
    clamps = task.source_clamps(net, ref)
    clamps.update(zip(task.targets.tolist(), (task.target_rest(net, ref) * (1 + s_nudge)).tolist()))
    return clamps


def _learn(
    rule: Rule,
    net: SpringNetwork,
    task: AllosteryTask,
    r_free: NDArray | None,
    r_clamped: NDArray,
    dt_learn: float,
) -> SpringNetwork:
    """The network after one learning step of length ``dt_learn`` (rates from ``rule``)."""
    k, L = net.stiffness, net.rest_length
    if isinstance(rule, ProspectiveConfiguration):
        if rule.dof == "rest_length":
            raw = -np.expm1(-rule.alpha * k * dt_learn) * (r_clamped - L)
        else:
            raw = -0.5 * rule.alpha * dt_learn * (r_clamped - L) ** 2
    elif rule.dof == "rest_length":
        raw = dt_learn * (rule.alpha / rule.eta) * k * (r_clamped - r_free)
    else:
        raw = dt_learn * (rule.alpha / (2 * rule.eta)) * ((r_free - L) ** 2 - (r_clamped - L) ** 2)
    step = Step(delta=rule._delta(net, task, raw), dof=rule.dof, free=None, clamped=None)
    return step.apply(net)


def learn_in_time(
    net: SpringNetwork,
    task: AllosteryTask,
    rule: Rule,
    *,
    viscosity: Viscosity,
    duration: float,
    dt: float,
    learn_every: int = 1,
    form: Form | None = None,
    phase: float | None = None,
    n_outputs: int = 50,
    quasistatic: bool = False,
    tol: float = 1e-10,
) -> TimeHistory:
    """Learn ``task`` with ``rule`` while the network moves (module docstring).

    Parameters
    ----------
    net : SpringNetwork
        Starting network (its positions are the starting state).
    task : AllosteryTask
    rule : ProspectiveConfiguration or CoupledLearning
        Rates and options; ``alpha`` is per time unit.
    viscosity : Viscosity
        Dissipation of the material.
    duration : float
        Physical time to run (> 0).
    dt : float
        Physical time step (> 0).
    learn_every : int
        Learning step ``dt_learn = learn_every * dt`` (``"continuous"`` and ``"twin"``).
    form : {"continuous", "twin", "phases"}, optional
        Default ``"continuous"`` for GPC, ``"twin"`` for GCL.
    phase : float, optional
        Duration of each phase for ``"phases"`` (rounded to whole steps, at least one).
    n_outputs : int
        About this many recorded outputs (each needs one equilibrium solve for the error).
    quasistatic : bool
        Equilibrium instead of dynamics at every physical step.
    tol : float
        Relative force tolerance of every step (and equilibrium).
    """
    if isinstance(rule, ExactGradient):
        raise ValueError("the exact gradient stays quasi-static: use train(), not learn_in_time")
    if not isinstance(rule, ProspectiveConfiguration | CoupledLearning):
        raise ValueError(
            f"rule must be ProspectiveConfiguration or CoupledLearning, got {type(rule).__name__}"
        )
    if not isinstance(viscosity, Viscosity):
        raise ValueError(f"viscosity must be a Viscosity, got {type(viscosity).__name__}")
    gpc = isinstance(rule, ProspectiveConfiguration)
    form = form or ("continuous" if gpc else "twin")
    allowed = ("continuous",) if gpc else ("twin", "phases")
    if form not in allowed:
        raise ValueError(f"form for {rule.name} must be one of {allowed}, got {form!r}")
    for name, value in (("duration", duration), ("dt", dt)):
        if not (math.isfinite(float(value)) and float(value) > 0):
            raise ValueError(f"{name} must be finite and > 0, got {value}")
    if int(learn_every) != learn_every or learn_every < 1:
        raise ValueError(f"learn_every must be an integer >= 1, got {learn_every}")
    if int(n_outputs) != n_outputs or n_outputs < 1:
        raise ValueError(f"n_outputs must be an integer >= 1, got {n_outputs}")
    task.check(net)
    ends = net.springs[np.concatenate([task.sources, task.targets])].ravel()
    if np.unique(ends).size != ends.size:
        raise ValueError(
            "learning in physical time holds every clamp by its two end nodes: the task's "
            "sources and targets must not share nodes"
        )
    dt, duration = float(dt), float(duration)
    n_steps = max(1, math.ceil(duration / dt - 1e-9))
    if form == "phases":
        if phase is None or not (math.isfinite(float(phase)) and float(phase) > 0):
            raise ValueError(f"form='phases' needs phase > 0 (a duration), got {phase}")
        if learn_every != 1:
            raise ValueError("form='phases' learns once per cycle: leave learn_every at 1")
        per_phase = max(1, round(float(phase) / dt))
        dt_learn = 2 * per_phase * dt
    else:
        per_phase = 0
        dt_learn = learn_every * dt
    if not gpc or rule.dof == "stiffness":
        bound = rule.alpha * float(np.max(net.stiffness)) * dt_learn
        if bound > 1.0:
            raise ValueError(
                f"explicit learning step too long: alpha k_max dt_learn = {bound:.3g} > 1; "
                "reduce dt, learn_every or phase"
            )

    ref = rule.strain_reference
    pins = task.pinned
    t_start = time.perf_counter()
    src = task.source_clamps(net, ref)
    free_copy = _Copy(net, viscosity, pins, src, net.positions, dt, quasistatic, tol)
    copies = [free_copy]
    if gpc:
        clamps = dict(src)
        clamps.update(zip(task.targets.tolist(), task.desired_lengths(net, ref).tolist()))
        moving = _Copy(net, viscosity, pins, clamps, net.positions, dt, quasistatic, tol)
        copies = [moving]
    elif form == "twin":
        moving = free_copy
        nudged = _Copy(
            net, viscosity, pins, _nudge(task, net, net.lengths(free_copy.x), rule),
            free_copy.x, dt, quasistatic, tol,
        )  # fmt: skip
        copies.append(nudged)
    else:
        moving = free_copy
        nudged = _Copy(
            net, viscosity, pins, _nudge(task, net, net.lengths(free_copy.x), rule),
            free_copy.x, dt, quasistatic, tol,
        )  # fmt: skip
        nudged.x = free_copy.x.copy()  # one network: the nudged mask and stepper share it
        copies.append(nudged)

    every = max(1, n_steps // int(n_outputs))
    rows: list[tuple] = []
    equilibrium = _equilibrium_stepper(net, free_copy.free, tol)  # the free state
    x_free_eq = free_copy.x

    def record(t: float, x_now: NDArray) -> None:
        nonlocal x_free_eq
        held = free_copy.hold(net, task.source_clamps(net, ref)) if ref == "current" else None
        x_free_eq = equilibrium.step(net, x_free_eq, x_held=held)[0]
        rows.append(
            (
                t,
                task.error(net, x_free_eq, ref),
                net.rest_length.copy(),
                net.stiffness.copy(),
                net.lengths(x_now)[task.targets],
                x_now.copy(),
                time.perf_counter() - t_start,
            )
        )

    record(0.0, moving.x)
    in_nudge = False
    for step in range(1, n_steps + 1):
        if gpc:
            held = moving.hold(net, clamps) if ref == "current" else None
            moving.advance(net, held)
            if step % learn_every == 0:
                net = _learn(rule, net, task, None, net.lengths(moving.x), dt_learn)
                if ref == "current":
                    clamps = dict(task.source_clamps(net, ref))
                    clamps.update(
                        zip(task.targets.tolist(), task.desired_lengths(net, ref).tolist())
                    )
        elif form == "twin":
            free_copy.advance(net, free_copy.hold(net, task.source_clamps(net, ref)))
            nudged.advance(net, nudged.hold(net, _nudge(task, net, net.lengths(free_copy.x), rule)))
            if step % learn_every == 0:
                net = _learn(
                    rule, net, task, net.lengths(free_copy.x), net.lengths(nudged.x), dt_learn
                )
        else:
            position = (step - 1) % (2 * per_phase)
            if position == per_phase:  # free phase over: read, set the nudge
                r_free = net.lengths(free_copy.x)
                nudged.x, nudged.arm = free_copy.x, free_copy.arm
                held = nudged.hold(net, _nudge(task, net, r_free, rule))
                in_nudge = True
            elif position == 0 and in_nudge:  # nudged phase over: read, learn, release
                net = _learn(rule, net, task, r_free, net.lengths(nudged.x), dt_learn)
                free_copy.x, free_copy.arm = nudged.x, nudged.arm
                in_nudge = False
            moving = nudged if in_nudge else free_copy
            moving.advance(net, held if (in_nudge and position == per_phase) else None)
        if step % every == 0 or step == n_steps:
            record(step * dt, moving.x)

    cols = [np.asarray(c) for c in zip(*rows)]
    for c in cols:
        c.setflags(write=False)
    times, error, rest, stiff, target, pos, secs = cols
    return TimeHistory(
        times=times,
        error=error,
        rest_length=rest,
        stiffness=stiff,
        target_length=target,
        positions=pos,
        seconds=secs,
        rule=rule.name,
        form=form,
        dt=dt,
        dt_learn=dt_learn,
        quasistatic=bool(quasistatic),
        factorisations=sum(c.factorisations for c in copies),
    )
