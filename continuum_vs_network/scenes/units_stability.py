"""Units of stability scenes: every stiff, extreme or degenerate case, converged or raised.

Equilibrium cases (``stability/<case>/<method>``), every method of ``[solver] methods``; the
lattice is ``[network] size`` x ``size`` with position noise and the spring nearest the
centre clamped:

* ``stiff_<r>``: a random ``stiff_fraction`` of the springs ``r`` times stiffer; the soft
  spring nearest the centre clamped at ``[task] strain``;
* ``rod_<k>``: the paper's clamp rod of stiffness ``k`` at ``[task] strain``;
* ``strain_<s>``: an exact clamp at the extreme strain ``s`` (``[solver] ramp`` continuation
  steps); ``s = -0.999`` clamps the spring to 1e-3 of its rest length;
* ``collinear_<h>``: a triangle whose apex lies ``h`` above its base (base 2, sides of rest
  length 1.2): a nearly singular tangent stiffness; closed form: the apex rises to
  ``sqrt(1.2^2 - 1)``;
* ``float32``: the lattice given as float32 arrays, against the same lattice in float64;
* ``floppy``: the lattice with springs removed until three fewer than ``2 N - 3`` remain
  (every node keeps two); must raise ``ValueError``.

Each records converged, the error raised, time, iterations and, independently of the
solver, the *local imbalance* at the returned positions: the largest net force on a free
coordinate, clamp-normal components removed (least squares), over that node's own force
scale ``sum_j k_j L_j`` (:func:`local_imbalance`), with the clamp error and a closed-form
check where one exists.

Dynamics (``stability/dynamics/...``): the explicit scheme at multiples of its stability
limit (above 1 it must refuse), and backward Euler and Newmark at multiples of the explicit
limit on a lattice with stiff springs (``[stability] implicit_stiffness``).

Continuum locking (``stability/locking/<element>_nu<nu>``): Lamé's cylinder at Poisson's
ratios ``[stability] poisson`` with P1 and curved P2; error against the closed form and
whether a ``LockingWarning`` was raised.

Learning with stiff springs (``stability/learning/stiff_<r>``): coupled learning on a
lattice with stiff springs; completed steps, stop reason, error ratio.
"""

from __future__ import annotations

import functools
import math
import time
from typing import Any

import numpy as np

from .results.stability import EquilibriumCaseResult, LockingResult, StepResult, StiffLearningResult
from .schema import Scene
from .timing import single_threaded
from .units import Unit, UnitContext
from .units_physics import centre_spring, lattice
from .units_solvers import warm_up

__all__ = ["case_name", "cases", "local_imbalance", "plan_stability"]

_FLOPPY_MODES = 3  # zero modes by counting in the floppy case


def cases(scene: Scene) -> list[tuple[str, float]]:
    """Equilibrium cases ``(kind, value)`` in table order."""
    out = [("stiff", float(r)) for r in scene.network.stiffness_ratios]
    out += [("rod", float(k)) for k in scene.solver.rod_stiffnesses]
    if scene.task is not None:
        out += [("strain", float(s)) for s in scene.task.strains]
    st = scene.stability
    if st is not None:
        out += [("collinear", float(h)) for h in st.collinear_heights]
        if st.float32:
            out.append(("float32", 0.0))
        if st.floppy:
            out.append(("floppy", 0.0))
    return out


def case_name(kind: str, value: float) -> str:
    """``stiff_1e+06``, ``strain_-0.999``, ``float32``, ... (a unit key component)."""
    return kind if kind in ("float32", "floppy") else f"{kind}_{value:g}"


def plan_stability(scene: Scene) -> list[Unit]:
    """Every case, one timed unit each (serial, main process)."""
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "solver", "stability") if k in d}
    units = [
        Unit(
            key=f"stability/{case_name(kind, value)}/{method}",
            func=equilibrium_unit,
            params={"case": kind, "value": value, "method": method},
            depends=depends,
            parallel=False,
        )
        for kind, value in cases(scene)
        for method in scene.solver.methods
    ]
    st = scene.stability
    if st is None:
        return units

    def add(key: str, func, params: dict) -> None:
        units.append(Unit(key=key, func=func, params=params, depends=depends, parallel=False))

    for f in st.explicit_dt:
        add(f"stability/dynamics/explicit_{f:g}", dynamics_unit, {"scheme": "explicit", "f": f})
    for scheme in ("implicit", "newmark"):
        for f in st.implicit_dt:
            add(f"stability/dynamics/{scheme}_{f:g}", dynamics_unit, {"scheme": scheme, "f": f})
    for element in ("P1", "P2_curved"):
        for nu in st.poisson:
            add(
                f"stability/locking/{element}_nu{nu:g}",
                locking_unit,
                {"element": element, "poisson": nu},
            )
    for r in st.learning_stiffness_ratios:
        add(f"stability/learning/stiff_{r:g}", learning_unit, {"ratio": r})
    return units


# -- the independent check ---------------------------------------------------------------
def local_imbalance(
    net, x: np.ndarray, free: np.ndarray, clamped: list[int] | tuple[int, ...] = ()
) -> float:
    """Largest relative net force on a free coordinate at ``x``.

    ``max_ic |F_ic| / f_i`` with ``F`` the spring forces on the free coordinates minus
    their component along the clamped springs' length gradients (a clamp or rod pushes
    along its spring), the tensions fitted to minimise ``sum (F_ic / f_i)^2`` (the
    definition of :func:`~continuum_vs_network.relax`'s ``relative_residual``; an
    unweighted fit judges a soft node by a stiff neighbour's absolute force), and
    ``f_i = sum_{j at i} k_j L_j`` (springs with ``k > 0`` in ``net``; a node with none
    takes ``mean(k) mean(L)``).

    Parameters
    ----------
    net : SpringNetwork
    x : (n_nodes, 2) float array
    free : (n_nodes, 2) bool array
        Free coordinates.
    clamped : sequence of int
        Clamped springs.
    """
    from ..network.energy import spring_gradient

    x = np.asarray(x, dtype=np.float64)
    g = spring_gradient(x, net.springs, net.stiffness, net.rest_length).ravel()
    fi = np.flatnonzero(np.asarray(free).ravel())
    force = -g[fi]
    w = net.stiffness * net.rest_length
    scale = np.bincount(net.springs[:, 0], w, net.n_nodes) + np.bincount(
        net.springs[:, 1], w, net.n_nodes
    )
    fallback = float(np.mean(net.stiffness) * np.mean(net.rest_length)) or 1.0
    scale = np.repeat(np.where(scale > 0, scale, fallback), 2)[fi]
    if len(clamped):
        A = np.zeros((len(clamped), 2 * net.n_nodes))
        for row, j in enumerate(clamped):
            a, b = net.springs[j]
            d = x[b] - x[a]
            u = d / max(float(np.hypot(*d)), 1e-300)
            A[row, 2 * a : 2 * a + 2] = -u
            A[row, 2 * b : 2 * b + 2] = u
        Af = A[:, fi] / scale  # the fit weighted by 1 / f_i, as relax defines it
        mu, *_ = np.linalg.lstsq(Af.T, force / scale, rcond=None)
        force = force - (Af.T @ mu) * scale
    return float(np.max(np.abs(force) / scale)) if fi.size else 0.0


# -- equilibrium cases ---------------------------------------------------------------------
def _floppy_springs(net) -> np.ndarray:
    """Mask of the springs kept in the floppy case: springs are removed (in index order,
    each only if both its nodes keep two or more) until the network has ``_FLOPPY_MODES``
    fewer springs than the ``2 N - 3`` a rigid one needs at least."""
    keep = np.ones(net.n_springs, dtype=bool)
    degree = np.bincount(net.springs.ravel(), minlength=net.n_nodes)
    excess = net.n_springs - (2 * net.n_nodes - 3 - _FLOPPY_MODES)
    for j, (a, b) in enumerate(net.springs):
        if excess <= 0:
            break
        if degree[a] > 2 and degree[b] > 2:
            keep[j] = False
            degree[a] -= 1
            degree[b] -= 1
            excess -= 1
    return keep


def _collinear(height: float):
    from ..network.model import SpringNetwork

    net = SpringNetwork(
        [[0.0, 0.0], [2.0, 0.0], [1.0, height]],
        [[0, 1], [1, 2], [2, 0]],
        [1.0, 1.0, 1.0],
        [2.0, 1.2, 1.2],
    )
    return net, np.array([[1, 1], [0, 1], [0, 0]], dtype=bool)


def _equilibrium_problem(scene: Scene, kind: str, value: float):
    """``(net, clamped, options)`` of a lattice case."""
    net = lattice(scene, scene.network.size, default_noise=0.1)
    options: dict[str, Any] = {}
    strain = scene.task.strain
    if kind == "stiff":
        rng = np.random.default_rng([scene.seed, 1])
        stiff = rng.random(net.n_springs) < scene.network.stiff_fraction
        net = net.with_stiffness(np.where(stiff, value, 1.0))
        x = net.positions
        mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
        dist = np.where(stiff, np.inf, np.hypot(*(mid - x.mean(axis=0)).T))
        spring = int(np.argmin(dist))
    else:
        spring = centre_spring(net)
        if kind == "rod":
            options.update(clamp="rod", rod_stiffness=value)
        elif kind == "strain":
            strain = value
            options.update(ramp=scene.solver.ramp)
    return net, {spring: float(net.clamp_length(spring, strain))}, options


@single_threaded
def equilibrium_unit(scene: Scene, params: dict, ctx: UnitContext) -> EquilibriumCaseResult:
    """One method on one case; an error raised is recorded, not raised."""
    from ..network.constraints import default_pins
    from ..network.equilibrium import EquilibriumError, relax
    from ..network.model import SpringNetwork

    kind, value, method = params["case"], params["value"], params["method"]
    warm_up(method)
    s = scene.solver
    check, check_name = math.nan, ""
    if kind == "collinear":
        net, pins = _collinear(value)
        clamped, options = {}, {}
    else:
        net, clamped, options = _equilibrium_problem(scene, kind, value)
        if kind == "floppy":
            keep = _floppy_springs(net)
            net = SpringNetwork(
                net.positions, net.springs[keep], net.stiffness[keep], net.rest_length[keep]
            )
            clamped = {}
        pins = default_pins(net, avoid=list(clamped))
    solve_net = net
    if kind == "float32":
        solve_net = SpringNetwork(
            net.positions.astype(np.float32),
            net.springs.astype(np.int32),
            net.stiffness.astype(np.float32),
            net.rest_length.astype(np.float32),
        )
        # the float64 comparison: the same (rounded) numbers held in float64
        net = SpringNetwork(
            solve_net.positions, net.springs, solve_net.stiffness, solve_net.rest_length
        )
    case = functools.partial(
        EquilibriumCaseResult, case=kind, value=value, method=method, n_nodes=net.n_nodes
    )
    error = ""
    t0 = time.perf_counter()
    try:
        eq = relax(
            solve_net,
            pinned=pins,
            clamped=clamped,
            method=method,
            tol=s.tol,
            max_seconds=s.max_seconds,
            **options,
        )
    except EquilibriumError as err:
        eq = err.state
        error = f"EquilibriumError: {err.reason}"
    except Exception as err:  # a stability table reports every failure, with its type
        return case(error=f"{type(err).__name__}: {err}", seconds=time.perf_counter() - t0)
    x = np.asarray(eq.positions)
    if kind == "collinear":
        check = abs(abs(float(x[2, 1])) - math.sqrt(1.2**2 - 1.0))
        check_name = "apex height error"
    elif kind == "float32":
        ref = relax(net, pinned=pins, clamped=clamped, method="newton", tol=s.tol)
        check = float(np.max(np.abs(x - ref.positions))) / float(np.mean(net.rest_length))
        check_name = "|x - x(float64 Newton)| / mean L"
    if clamped:
        j = next(iter(clamped))
        clamp_err = abs(float(net.lengths(x, j)) - clamped[j]) / float(net.rest_length[j])
    else:
        clamp_err = 0.0
    return case(
        error=error,
        converged=bool(eq.converged),
        imbalance=local_imbalance(net, x, ~np.asarray(pins, dtype=bool), list(clamped)),
        clamp_error=clamp_err,
        seconds=float(eq.seconds),
        iterations=int(eq.iterations),
        check=check,
        check_name=check_name,
    )


# -- dynamics ------------------------------------------------------------------------------
@single_threaded
def dynamics_unit(scene: Scene, params: dict, ctx: UnitContext) -> StepResult:
    """One scheme at ``f`` times the explicit stability limit; refusal or failure recorded."""
    from ..network.dynamics import simulate, stability_limit

    st = scene.stability
    net = lattice(scene, scene.network.size, default_noise=0.1)
    scheme, f = params["scheme"], params["f"]
    if scheme != "explicit":
        rng = np.random.default_rng([scene.seed, 2])
        stiff = rng.random(net.n_springs) < scene.network.stiff_fraction
        net = net.with_stiffness(np.where(stiff, st.implicit_stiffness, 1.0))
    x = net.positions
    width = float(np.ptp(x[:, 0]))
    left = np.flatnonzero(x[:, 0] < x[:, 0].min() + 0.6)
    right = np.flatnonzero(x[:, 0] > x[:, 0].max() - 0.6)
    prescribed = {int(i): (float(x[i, 0] - 0.01 * width), float(x[i, 1])) for i in right}
    limit = float(stability_limit(net, damping=1.0, inertia=True))
    dt = f * limit
    steps = 200 if scheme == "explicit" else 20
    run = functools.partial(StepResult, **params, dt=dt, dt_limit=limit, steps=steps)
    try:
        tr = simulate(
            net,
            dt=dt,
            t_end=steps * dt,
            pinned=left,
            prescribed=prescribed,
            damping=1.0,
            inertia=True,
            scheme=scheme,
            record_every=steps,
        )
    except (ValueError, RuntimeError) as err:
        return run(error=f"{type(err).__name__}: {err}")
    mech = tr.energy + tr.kinetic
    return run(
        energy_start=float(mech[0]),
        energy_end=float(mech[-1]),
        imbalance=local_imbalance(net, tr.positions[-1], tr.free),
        seconds=float(tr.seconds[-1]),
    )


# -- continuum locking ---------------------------------------------------------------------
@single_threaded
def locking_unit(scene: Scene, params: dict, ctx: UnitContext) -> LockingResult:
    """Lamé's cylinder at one Poisson's ratio: error, DOFs, whether a warning was raised."""
    from .units_accuracy import lame_error

    out = lame_error(params["element"], scene.stability.locking_h, params["poisson"])
    return LockingResult(**params, **out)


# -- learning with stiff springs -----------------------------------------------------------
@single_threaded
def learning_unit(scene: Scene, params: dict, ctx: UnitContext) -> StiffLearningResult:
    """Coupled learning on a lattice with stiff springs: steps done, stop reason, C/C0."""
    from ..learning.rules import CoupledLearning
    from ..learning.tasks import stern_task
    from ..learning.train import train

    st = scene.stability
    net = lattice(scene, scene.network.size, default_noise=0.1)
    rng = np.random.default_rng([scene.seed, 3])
    stiff = rng.random(net.n_springs) < scene.network.stiff_fraction
    net = net.with_stiffness(np.where(stiff, params["ratio"], 1.0))
    task = stern_task(net, 3, 2, np.random.default_rng([scene.seed, 4]))
    rule = CoupledLearning(1e-3, 0.1, strain_reference="initial")
    t0 = time.perf_counter()
    run = functools.partial(StiffLearningResult, **params, steps=st.learning_steps)
    try:
        hist = train(net, task, rule, st.learning_steps, seeds=(scene.seed,), progress=False)
    except Exception as err:  # recorded: the table says what was raised
        return run(
            error=f"{type(err).__name__}: {err}",
            completed=0,
            ratio_error=math.nan,
            seconds=time.perf_counter() - t0,
            finite=True,
        )
    err = np.asarray(hist.error_initial, dtype=float)[0]
    done = int(hist.completed[0])
    return run(
        completed=done,
        error=hist.stop_reason[0],
        ratio_error=float(err[done] / err[0]) if err[0] > 0 else math.nan,
        seconds=time.perf_counter() - t0,
        finite=bool(np.all(np.isfinite(err[: done + 1]))),
    )
