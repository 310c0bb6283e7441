"""Learning concurrent with the physical dynamics: the rules as ODEs in physical time.

The paper writes its rules as differential equations that can run with the material
(Sec. 5, Eq. 17-18) and then assumes quasi-staticity. Here the nodes and the learning
degrees of freedom evolve together as one system of ODEs; the material is a visco-elastic
network (:mod:`~continuum_vs_network.network.viscous`: node drag, spring dashpots, Maxwell
arms) or a learning medium such as the elastic continuum
(:class:`~continuum_vs_network.continuum.learnable.LearnableBody` against drag and/or
Kelvin-Voigt viscosity, :mod:`~continuum_vs_network.continuum.damped_states`), and never
has to reach equilibrium. One loop serves both media; what it needs from each (a damped
step under the clamps, the rule's local update per spring or element) is in
:mod:`.time_media`. The rule objects supply ``alpha``, ``eta``,
``dof``, the learning mask and floors, and the strain convention; ``alpha`` is a rate (per
time unit), so one quasi-static step of the rule with rate ``alpha`` is one explicit-Euler
step of length 1 of the ODE. A rule without ``alpha`` (GCL's default adaptive rate) learns
at one adaptive step per ``step_time`` (:class:`~.time_media.AdaptiveClock`): with
``dt = step_time`` the quasi-static run is :func:`~.train.train`'s, step for step.

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

In the continuum the clamps are exact constraints on the material springs' strains
(Lagrange multipliers), sources and targets are read from them, the learning unit is the
element (eigenstrain, or modulus), its update the rule's per-area local one (forward
Euler: ``alpha c_max dt_learn <= 1``, ``c_max`` the largest eigenvalue of an element's
elastic tensor, checked), ``quasistatic=True`` an exact equilibrium; quasi-static learning
in time with ``dt = 1`` is :func:`~.train.train` step for step.

In a network, by default (``clamp="strain"``) a clamp holds only the clamped spring's
length, as the continuum's: the spring becomes a stiff rod at the clamp length
(:func:`~continuum_vs_network.network.strain_clamp.rod_clamped`, stiffness ``1e6`` times
the mean; backward Euler damps its fast mode in one step), no node held, so both media are
driven the same way. ``clamp="nodes"``: clamps are prescribed displacements of the clamped
springs' end nodes, as in :func:`~continuum_vs_network.network.dynamics.simulate` (set
symmetrically along the spring's current direction, then held). Task pins are held.
``quasistatic=True`` replaces every physical step by the equilibrium with the same clamps
(a backward-Euler step of length ``1e12 / k``): the limit of a vanishing ratio of learning
rate to relaxation rate, computed directly.

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

import itertools
import math
import time
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..network.dynamics import relaxation_time, settling_time, simulate_viscous
from ..network.model import SpringNetwork
from ..network.viscous import Viscosity
from .medium import is_medium
from .rules import CoupledLearning, ExactGradient, ProspectiveConfiguration, Rule
from .tasks import AllosteryTask
from .time_media import BodyTime, NetworkTime, check_clamp

__all__ = [
    "Form",
    "TimeHistory",
    "learn_in_time",
    "network_relaxation_time",
]

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
        The learning arrays (a body: its eigenstrain (T, n_elements, 3) and modulus
        (T, n_elements) fields).
    target_length : (T, n_targets) float array
        Target lengths of the moving medium (the free copy for ``"twin"``; a body: its
        target material springs).
    positions : (T, n_nodes, 2) float array
        The moving medium (the free copy for ``"twin"``; a body: its deformed vertices),
        for export.
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
    measure: Literal["target", "force"] = "target",
    clamp: Literal["strain", "nodes"] = "strain",
) -> float:
    """Relaxation time of ``net`` after the task's source step (time units).

    The sources are stepped to their clamp lengths with the task's pins held and the
    response integrated (:func:`~continuum_vs_network.network.dynamics.simulate_viscous`,
    200 steps per run), from a run at least 3 times longer (doubled until it is).

    ``measure="target"`` (default): the time after which the target strains (what
    learning reads) stay within ``fraction`` (1 %) of their total change of their new
    equilibrium (:func:`~..network.dynamics.settling_time`; the change from the state
    before the step, the equilibrium an exact solve with the same clamps). ``measure="force"``:
    :func:`~continuum_vs_network.network.dynamics.relaxation_time`, the largest net force
    stays below ``fraction`` of its start (which local modes dominate).

    ``clamp="strain"`` (default): the sources are held as the continuum holds them, by
    their lengths only (:func:`~continuum_vs_network.network.strain_clamp.rod_clamped`
    rods, no node held; :func:`_strain_relaxation_time`); ``clamp="nodes"``: by their end
    nodes (prescribed positions, as :func:`~continuum_vs_network.network.dynamics.simulate`
    holds a clamp).
    """
    if measure not in ("target", "force"):
        raise ValueError(f"measure must be 'target' or 'force', got {measure!r}")
    check_clamp(clamp)
    if clamp == "strain":
        return _strain_relaxation_time(net, task, viscosity, reference, fraction, measure)
    clamps = task.source_clamps(net, reference)
    k_mean = float(np.mean(net.stiffness))
    rest = task.target_rest(net, reference)
    end = start = None
    if measure == "target":
        big = 1e12 / k_mean  # one backward-Euler step this long: the clamped equilibrium
        eq = simulate_viscous(net, viscosity, dt=big, t_end=big, pinned=task.pinned, clamped=clamps)
        end = net.lengths(eq.positions[-1], task.targets) / rest
        start = net.lengths(net.positions, task.targets) / rest

    def tau_of(t_end: float) -> float:
        traj = simulate_viscous(
            net, viscosity, dt=t_end / 200, t_end=t_end, pinned=task.pinned, clamped=clamps
        )
        if measure == "force":
            try:
                return relaxation_time(traj, fraction)
            except ValueError:
                return math.inf
        strains = np.stack([net.lengths(x, task.targets) / rest for x in traj.positions])
        return settling_time(traj.times, strains, start, end, fraction)

    eta = viscosity.drag + viscosity.dashpot
    return _settled(tau_of, 4.0 * eta / k_mean * max(net.n_nodes, 4) ** 0.5)


def _settled(tau_of, t_end: float) -> float:
    """``tau_of(t_end)`` (the relaxation time read from a run of length ``t_end``) from a run
    at least 3 times longer than it, doubling ``t_end`` until it is."""
    for _ in range(30):
        tau = tau_of(t_end)
        if 3.0 * tau <= t_end:
            return tau
        t_end *= 2.0
    raise RuntimeError("the network does not relax after the source step (is it rigid?)")


def _strain_relaxation_time(net, task, viscosity, reference, fraction, measure) -> float:
    """:func:`network_relaxation_time` with the sources held as rods (strain clamps).

    As the continuum's (:func:`~continuum_vs_network.continuum.damped_states.body_relaxation_time`):
    the run starts after the jump onto the clamps (the rods' fast mode, damped by three
    backward-Euler steps of ``1e-3 (c + gamma) / k``, the slow modes barely moved); the
    target strains' start is the state before the jump, their end the clamped equilibrium.
    ``"force"``: the damping force ``C (x1 - x0) / dt`` of each step (``C`` at the initial
    positions, free coordinates) against the clamped velocity's at the start, ``[C G^T; G
    0] [v; mu] = [f; 0]`` (``f`` the original springs' and arms' force, ``G`` the rods'
    chord-strain rows).
    """
    from ..linalg.kkt import factor_kkt
    from ..network.energy import spring_gradient
    from ..network.held_boundary import held_boundary
    from ..network.length_jacobian import strain_jacobian
    from ..network.stepper import Stepper
    from ..network.strain_clamp import ROD_FACTOR, rod_clamped
    from ..network.viscous import dashpot_matrix

    clamps = task.source_clamps(net, reference)
    rods = rod_clamped(net, clamps)
    tol = max(1e-10, 100.0 * np.finfo(float).eps * ROD_FACTOR) * net.force_scale
    tol /= rods.force_scale
    k_mean = float(np.mean(net.stiffness))
    rest = task.target_rest(net, reference)
    x0 = net.positions
    free = held_boundary(net, task.pinned, None, None, x0)[1]
    arm0 = net.lengths(x0) if viscosity.has_arm else None
    eta = viscosity.drag + viscosity.dashpot
    jumper = Stepper(rods, viscosity, free, 1e-3 * eta / k_mean, tol=tol)
    xj, arm_j = x0, arm0
    for _ in range(3):
        xj, _, arm_j = jumper.step(rods, xj, arm=arm_j)
    start = net.lengths(x0, task.targets) / rest
    end = None
    fdofs = free.ravel()
    if measure == "target":
        big = 1e12 / k_mean
        eq = simulate_viscous(rods, viscosity, dt=big, t_end=big, pinned=task.pinned, tol=tol)
        end = net.lengths(eq.positions[-1], task.targets) / rest
        f0 = None
    else:
        C = dashpot_matrix(x0, net, viscosity.dashpot) + viscosity.drag * sp.identity(
            2 * net.n_nodes
        )
        C = C.tocsr()[fdofs][:, fdofs]
        force = -spring_gradient(xj, net.springs, net.stiffness, net.rest_length)
        if arm0 is not None:
            k2 = np.full(net.n_springs, viscosity.arm_stiffness)
            force = force - spring_gradient(xj, net.springs, k2, arm_j)
        G = strain_jacobian(xj, net.springs[list(clamps)]).tocsc()[:, fdofs]
        v0, _ = factor_kkt(C.tocsc(), G).solve(force.ravel()[fdofs])
        f0 = float(np.max(np.abs(C @ v0))) if v0.size else 0.0
        if f0 == 0:
            return 0.0

    def tau_of(t_end: float) -> float:
        traj = simulate_viscous(
            rods, viscosity, dt=t_end / 200, t_end=t_end, pinned=task.pinned, x0=xj,
            arm0=arm_j, tol=tol,
        )  # fmt: skip
        if measure == "force":
            pos = np.asarray(traj.positions).reshape(len(traj.times), -1)[:, fdofs]
            d = np.array([np.max(np.abs(C @ (b - a))) for a, b in itertools.pairwise(pos)])
            d /= t_end / 200
            return settling_time(traj.times[1:], d[:, None], np.array([f0]), np.zeros(1), fraction)
        strains = np.stack([net.lengths(x, task.targets) / rest for x in traj.positions])
        return settling_time(traj.times, strains, start, end, fraction)

    return _settled(tau_of, 4.0 * eta / k_mean * max(net.n_nodes, 4) ** 0.5)


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
    step_time: float | None = None,
    clamp: Literal["strain", "nodes"] = "strain",
) -> TimeHistory:
    """Learn ``task`` with ``rule`` while the medium moves (module docstring).

    Parameters
    ----------
    net : SpringNetwork or LearnableBody
        Starting network (its positions are the starting state) or learning medium (at
        rest, zero displacement).
    task : AllosteryTask (a network) or MaterialTask (a body)
    rule : ProspectiveConfiguration or CoupledLearning
        Rates and options; ``alpha`` is per time unit.
    viscosity : Viscosity or Damping
        Dissipation of the material (a body: a continuum Damping, or a network Viscosity
        mapped by :func:`~continuum_vs_network.continuum.viscoelastic.lattice_damping`).
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
    step_time : float, optional
        A rule without ``alpha`` (an adaptive rate): physical time of one adaptive step
        (> 0; required then, ignored with ``alpha``).
    clamp : {"strain", "nodes"}
        A network's clamps (sources, nudged targets): by the clamped springs' lengths only
        (default; stiff rods, as the continuum's exact strain constraints) or by their end
        nodes (module docstring). Ignored for a body.
    """
    if isinstance(rule, ExactGradient):
        raise ValueError("the exact gradient stays quasi-static: use train(), not learn_in_time")
    if not isinstance(rule, ProspectiveConfiguration | CoupledLearning):
        raise ValueError(
            f"rule must be ProspectiveConfiguration or CoupledLearning, got {type(rule).__name__}"
        )
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
    dt, duration = float(dt), float(duration)
    check_clamp(clamp)
    if isinstance(net, SpringNetwork):
        task.check(net)
        ends = net.springs[np.concatenate([task.sources, task.targets])].ravel()
        if clamp == "nodes" and np.unique(ends).size != ends.size:
            raise ValueError(
                "clamp='nodes' holds every clamp by its two end nodes: the task's "
                "sources and targets must not share nodes"
            )
        media: NetworkTime | BodyTime = NetworkTime(
            net, task, rule, viscosity, dt, quasistatic, tol, step_time, clamp
        )
    elif is_medium(net):
        media = BodyTime(net, task, rule, viscosity, dt, quasistatic, tol, step_time)
    else:
        raise ValueError(
            f"net must be a SpringNetwork or a learning medium, got {type(net).__name__}"
        )
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
    bound = media.rate_bound(rule, net) * dt_learn
    if bound > 1.0:
        raise ValueError(
            f"explicit learning step too long: alpha c_max dt_learn = {bound:.3g} > 1 "
            "(c_max: the largest stiffness); reduce dt, learn_every or phase"
        )

    t_start = time.perf_counter()
    desired = np.asarray(task.target_strain, float)
    free_copy = media.copy(net, None)
    copies = [free_copy]

    def nudge(reading):
        s_free = media.target_strain(net, reading)
        return s_free + rule.eta * (task.target_strain - s_free)

    if gpc:
        moving = media.copy(net, desired)
        copies = [moving]
    else:
        moving = free_copy
        nudged = media.copy(net, nudge(media.read(net, free_copy)), start=free_copy)
        copies.append(nudged)

    every = max(1, n_steps // int(n_outputs))
    rows: list[tuple] = []

    def record(t: float, copy) -> None:
        rest, stiff = media.learning_arrays(net)
        rows.append(
            (
                t,
                media.error(net),
                rest,
                stiff,
                media.target_length(net, copy),
                media.positions(net, copy),
                time.perf_counter() - t_start,
            )
        )

    record(0.0, moving)
    in_nudge = False
    s_nudge = None
    for step in range(1, n_steps + 1):
        if gpc:
            media.advance(net, moving, desired)
            if step % learn_every == 0:
                net = media.update(rule, net, None, media.read(net, moving), dt_learn)
        elif form == "twin":
            media.advance(net, free_copy, None)
            media.advance(net, nudged, nudge(media.read(net, free_copy)))
            if step % learn_every == 0:
                net = media.update(
                    rule, net, media.read(net, free_copy), media.read(net, nudged), dt_learn
                )
        else:
            position = (step - 1) % (2 * per_phase)
            if position == per_phase:  # free phase over: read, set the nudge
                r_free = media.read(net, free_copy)
                media.take(nudged, free_copy)
                s_nudge = nudge(r_free)
                in_nudge = True
            elif position == 0 and in_nudge:  # nudged phase over: read, learn, release
                net = media.update(rule, net, r_free, media.read(net, nudged), dt_learn)
                media.take(free_copy, nudged)
                in_nudge = False
            moving = nudged if in_nudge else free_copy
            media.advance(net, moving, s_nudge if in_nudge else None)
        if step % every == 0 or step == n_steps:
            record(step * dt, moving)

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
        factorisations=media.factorisations(copies),
    )
