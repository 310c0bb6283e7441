"""Units of physical_time scenes: learning concurrent with the dynamics against the ratio
of learning rate to relaxation rate, per size, task draw, rule and medium.

Phase 0, one unit per size and task draw (``physical_time/n<n>/d<d>/task``): the ``n x n``
triangular lattice (k = 1) with a Stern-scale task (sources and targets frozen, bulk
learning, strains against the initial rest lengths; draw ``d`` from the generator seeded
``(seed, n)`` for ``d = 0`` and ``(seed, n, d)`` after), and for each medium its
relaxation time ``tau`` after the source step, the time for the target strains (what
learning reads) to come within 1 % of their total change of their new equilibrium
(:func:`~continuum_vs_network.learning.physical_time.network_relaxation_time`, the body's
:func:`~continuum_vs_network.continuum.damped_states.body_relaxation_time`; the older
net-force time ``tau_force`` beside it), and the modes behind it
(:mod:`.units_time_task`). Computed once, read by every rule's unit.

Phase 1, one unit per size, draw, rule and medium
(``physical_time/n<n>/d<d>/<rule>[/continuum]``): for every ratio ``rho = alpha k tau`` of
``[physical_time] ratios``

* the rule in physical time (:func:`~continuum_vs_network.learning.physical_time.learn_in_time`)
  for ``max(learning_times / (alpha k), relaxation_times tau)``, and
* its quasi-static limit (every physical step an equilibrium) over the same window with
  the same steps (one run per learning step in units of ``1 / (alpha k)``, over the longest
  window of any ratio, shared),

with ``dt = min(tau / steps_per_tau, 1 / (steps_per_rate alpha k))`` for both (physical
and learning step equal; ``gcl_phases`` learns once per cycle of two phases of
``min(phase tau, 1 / (2 steps_per_rate alpha k))``, so its learning step is no longer).

Measured per ratio (errors relative to the initial one): the time to make all but
``fraction`` of the quasi-static error drop, in both runs (``T`` and ``T_qs``) and their
ratio (the slowdown; ``T_qs`` within the first ``learning_times``), the final errors, and
the oscillation: the largest factor by which the error climbs back above its running
minimum (floored at ``FLOOR``) at a time when it is above the quasi-static run's error
(:func:`rebound`; a rebound the quasi-static run shares is the learning step's). The
critical ratio is a bracket (:func:`critical_bracket`), narrowed by bisection inside the
grid's bracket. The coupling of every run's final learned state (source share and verdict,
the unit's verdict from the smallest share: :mod:`.units_time_coupling`); the final state
of each grid ratio is stored (``r<i>/rest_length``, ``r<i>/stiffness``; a body: its
eigenstrain and modulus fields).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .results.physical_time import TimeRunResult
from .schema import Scene
from .units import Unit, UnitContext

__all__ = [
    "OSCILLATION",
    "SLOWDOWN",
    "critical_bracket",
    "crossing_time",
    "draws_per_size",
    "plan_time",
    "rebound",
]

#: A run is past the quasi-static regime when it learns this many times slower than its
#: quasi-static limit ...
SLOWDOWN = 2.0
#: ... or when its error climbs back to this many times its running minimum (oscillation).
OSCILLATION = 2.0
#: Errors below this fraction of the initial one are at the solver's floor: no rebound.
FLOOR = 1e-6


def draws_per_size(scene: Scene) -> list[int]:
    """Task draws per size: ``[physical_time] draws`` (one number for every size or one
    per size)."""
    sizes, draws = scene.network.sizes, scene.physical_time.draws
    return list(draws) * len(sizes) if len(draws) == 1 else list(draws)


def plan_time(scene: Scene) -> list[Unit]:
    """Phase 0: one task unit per size and draw; phase 1: one unit per size, draw, rule
    and medium, the largest sizes first (the longest units start first)."""
    from .units_time_coupling import coupling_rule
    from .units_time_task import task_unit

    if scene.physical_time.dof == "stiffness" and "gpc" in scene.physical_time.rules:
        _rule("gpc", None, scene.physical_time.eta, "stiffness")  # raises: GPC cannot learn k
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "physical_time") if k in d}
    sizes = [int(n) for n in scene.network.sizes]
    draws = draws_per_size(scene)
    series = scene.export is not None and scene.export.series
    tasks = [
        Unit(key=f"physical_time/n{n}/d{j}/task", func=task_unit, params={"n": n, "draw": j},
             depends=depends)
        for n, m in zip(sizes, draws)
        for j in range(m)
    ]  # fmt: skip
    runs = [
        Unit(
            key=f"physical_time/n{n}/d{j}/{rule}" + ("" if medium == "network" else f"/{medium}"),
            func=time_unit,
            params={
                "n": n,
                "draw": j,
                "rule": rule,
                "medium": medium,
                "series": bool(series and n == sizes[-1] and j == 0),
            },
            depends={**depends, "coupling": coupling_rule()},
            phase=1,
        )
        for n, m in sorted(zip(sizes, draws), reverse=True)
        for j in range(m)
        for medium in scene.physical_time.media
        for rule in scene.physical_time.rules
    ]
    return tasks + runs


def crossing_time(times: np.ndarray, values: np.ndarray, level: float) -> float:
    """First time ``values`` reach ``level`` or below (linear between frames); inf if never."""
    below = np.flatnonzero(values <= level)
    if below.size == 0:
        return math.inf
    i = int(below[0])
    if i == 0:
        return float(times[0])
    v0, v1 = values[i - 1], values[i]
    return float(times[i - 1] + (times[i] - times[i - 1]) * (v0 - level) / (v0 - v1))


def rebound(values: np.ndarray, reference: np.ndarray | None = None, floor: float = FLOOR) -> float:
    """Largest ``v[j] / max(min(v[:j+1]), floor)``: how far the error climbs back above its
    running minimum, the minimum floored at ``floor`` (errors below it are at the solver's
    floor; 1 for a monotone decrease). With ``reference`` (the quasi-static run's error at
    the same times, same shape), only the ``j`` where ``v[j] > reference[j]`` count: a
    rebound the quasi-static run shares is the discrete learning step's, not the dynamics'.
    """
    v = np.asarray(values, float)
    ratio = v / np.maximum(np.minimum.accumulate(v), floor)
    if reference is not None:
        ref = np.asarray(reference, float)
        if ref.shape != v.shape:
            raise ValueError(f"reference must have the shape of values {v.shape}, got {ref.shape}")
        ratio = ratio[v > ref]
    return float(max(1.0, ratio.max(initial=1.0)))


def critical_bracket(ratios, past) -> tuple[float, float, int]:
    """The critical ratio as a bracket ``(lo, hi]`` from the ratios run and whether each
    is past the quasi-static regime (the criterion need not be monotone in the ratio).

    ``lo``: the largest ratio not past (0 when every ratio is past); ``hi``: the smallest
    ratio run above it (inf when there is none), so ``hi`` and every ratio above it are
    past. Also returns the number of ratios below ``lo`` that are past (the criterion's
    non-monotone points, which the bracket does not count). Bisecting between ``lo`` and
    ``hi`` and applying the rule again to all ratios run narrows the bracket.
    """
    r = np.asarray(ratios, float)
    p = np.asarray(past, bool)
    if r.size == 0 or r.shape != p.shape:
        raise ValueError("ratios and past must be non-empty and of one length")
    order = np.argsort(r)
    r, p = r[order], p[order]
    calm = np.flatnonzero(~p)
    if calm.size == 0:
        return 0.0, float(r[0]), 0
    i = int(calm[-1])
    hi = float(r[i + 1]) if i + 1 < r.size else math.inf
    return float(r[i]), hi, int(np.count_nonzero(p[:i]))


def _rule(name: str, alpha: float | None, eta: float, dof: str = "rest_length"):
    """The rule object: raw rate ``alpha`` (rest lengths), or GCL's default adaptive rate
    (``alpha`` None, stiffnesses)."""
    from ..learning.rules import CoupledLearning, ProspectiveConfiguration

    kw = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}
    if dof == "stiffness":
        if name == "gpc":
            raise ValueError(
                "[physical_time] rules: gpc does not learn stiffnesses (its line -(r^C - L)^2 "
                "/ 2 is <= 0 for every spring); use gcl and gcl_phases with dof = 'stiffness'"
            )
        return CoupledLearning(None, eta, dof="stiffness", **kw)
    if name == "gpc":
        return ProspectiveConfiguration(alpha, **kw)
    return CoupledLearning(alpha, eta, **kw)


def _lattice_task(scene: Scene, n: int, draw: int = 0):
    """The lattice and task draw ``draw`` (generator ``(seed, n)`` for draw 0, ``(seed, n,
    draw)`` after)."""
    from ..learning.allostery import allostery_task
    from ..learning.tasks import stern_task
    from .units_physics import lattice

    t, spec = scene.task, scene.physical_time
    net = lattice(scene, n)
    rng = np.random.default_rng([scene.seed, n] + ([draw] if draw else []))
    for _ in range(200):  # sources and targets share no node (a clamp="nodes" run holds both)
        if spec.dof == "stiffness":
            task = allostery_task(
                net, rng, n_sources=t.n_sources, n_targets=t.n_targets,
                ratio=spec.response_ratio * (-1.0 if draw % 2 else 1.0),
                source_strain=spec.source_strain, distance=spec.distance,
            )  # fmt: skip
        else:
            task = stern_task(
                net, t.n_sources, t.n_targets, rng, source_std=t.source_std,
                target_std=t.target_std,
            )  # fmt: skip
        ends = net.springs[np.concatenate([task.sources, task.targets])].ravel()
        if np.unique(ends).size == ends.size:
            return net, task
    raise ValueError(
        f"no task of {t.n_sources} sources and {t.n_targets} targets without shared nodes "
        f"found on the {n} x {n} lattice in 200 draws; use fewer springs or a larger lattice"
    )


def _viscosity(scene: Scene):
    from ..network.viscous import Viscosity

    spec = scene.physical_time
    return Viscosity(
        drag=spec.drag,
        dashpot=spec.dashpot,
        arm_stiffness=spec.arm_stiffness,
        arm_dashpot=spec.arm_dashpot,
    )


def _body(net, task):
    """The lattice's continuum (P1 on its triangles, lattice Lamé parameters) and the same
    task's material springs."""
    from ..continuum.learnable import learnable_body
    from ..continuum.material_task import MaterialTask
    from ..continuum.materials import lattice_lame
    from ..continuum.mesh import network_mesh

    body = learnable_body(network_mesh(net), lattice_lame(float(np.mean(net.stiffness))))
    return body, MaterialTask.from_network(net, task, body)


def _medium(scene: Scene, params: dict, ctx: UnitContext):
    """``(learner, task, times, n_nodes)`` from the task unit of this size and draw: the
    lattice, or its continuum, and the medium's stored times (``tau``, ``tau_force`` and,
    learning stiffnesses, the reference's ``steps_qs`` and ``learned``)."""
    from ..learning.tasks import AllosteryTask
    from .results import from_stored
    from .results.physical_time import TimeTaskResult
    from .units_physics import lattice

    stored = ctx.read_unit(f"physical_time/n{params['n']}/d{params['draw']}/task")
    t = from_stored(stored, TimeTaskResult)
    times = t.medium_times(params["medium"])
    net = lattice(scene, params["n"])
    task = AllosteryTask.create(
        net, t.sources, t.source_strain, t.targets, t.target_strain, pinned=t.pinned
    )
    learner, learn_task = (net, task) if params["medium"] == "network" else _body(net, task)
    return learner, learn_task, times, net.n_nodes


def _past(row: dict) -> bool:
    return row["slowdown"] >= SLOWDOWN or row["rebound"] >= OSCILLATION


def time_unit(scene: Scene, params: dict, ctx: UnitContext) -> TimeRunResult:
    """Learning in physical time against the ratio, for one size, draw, rule and medium."""
    from ..learning.physical_time import learn_in_time
    from ..learning.rules import LearningError
    from .units_time_coupling import final_coupling, final_state, unit_coupling

    spec = scene.physical_time
    n, name, medium = params["n"], params["rule"], params.get("medium", "network")
    vis = _viscosity(scene)
    net, task, times_meta, n_nodes = _medium(scene, params, ctx)
    tau, tau_force = times_meta["tau"], times_meta["tau_force"]
    adaptive = spec.dof == "stiffness"
    if adaptive and not times_meta.get("learned", False):
        from .units_time_reference import not_learned_result

        return not_learned_result(params, n_nodes, name, medium, times_meta)
    # the learning time unit: 1 / (alpha k) (raw rate, k = 1: rho = alpha k tau = tau /
    # unit) or the time of one adaptive step, whose largest relative change of k is
    # ``step`` (rho = step tau / unit: tau over the time in which a stiffness may change
    # by its own size); c: the quasi-static run's learning window unit (1 for the raw
    # rate, steps_qs adaptive steps), so the runs last learning_times quasi-static times
    from ..learning.rates import Adaptive

    s_rate = Adaptive().step if adaptive else 1.0
    c = float(times_meta["steps_qs"]) if adaptive else 1.0
    k = 1.0
    qs_cache: dict[tuple, tuple] = {}

    def one(ratio: float) -> tuple[dict, dict]:
        unit = s_rate * tau / ratio
        alpha = None if adaptive else 1.0 / (k * unit)
        rule = _rule(name, alpha, spec.eta, spec.dof)
        dt = min(tau / spec.steps_per_tau, unit / spec.steps_per_rate)
        opts: dict[str, Any] = {"form": "twin"} if name == "gcl" else {}
        if name == "gcl_phases":
            phase = min(spec.phase * tau, 0.5 * unit / spec.steps_per_rate)
            dt = min(dt, phase)
            opts = {"form": "phases", "phase": phase}
        if adaptive:
            opts["step_time"] = unit
        t_learn = spec.learning_times * c * unit
        duration = max(t_learn, spec.relaxation_times * tau)
        longest = max(c * spec.learning_times, spec.relaxation_times * max(spec.ratios) / s_rate)
        outputs = min(300, max(20, round(60 * duration / t_learn)))
        t0 = time.perf_counter()
        try:
            run = learn_in_time(
                net, task, rule, viscosity=vis, duration=duration, dt=dt, n_outputs=outputs, **opts
            )
        except (LearningError, RuntimeError, FloatingPointError):  # diverged: a failed step
            run = None
        seconds = time.perf_counter() - t0
        # the quasi-static run depends on alpha only through the time unit 1 / (alpha k):
        # one run per learning step in those units, over the longest window any ratio needs
        # (learning units), every step recorded, rescaled and cut to each run's window
        key = (round(dt / unit, 12), round(opts.get("phase", 0.0) / unit, 12))
        if key not in qs_cache:
            steps = math.ceil(longest * unit / dt - 1e-9)
            try:
                qs = learn_in_time(
                    net, task, rule, viscosity=vis, duration=longest * unit, dt=dt,
                    n_outputs=steps, quasistatic=True, **opts,
                )  # fmt: skip
            except (LearningError, RuntimeError) as err:
                raise ValueError(
                    f"the quasi-static run diverged at ratio {ratio:g} ({err}): its learning "
                    "step is too long; raise [physical_time] steps_per_rate"
                ) from err
            qs_cache[key] = (
                qs.times / unit, qs.error / qs.error[0], qs.dt_learn / unit,
                qs.seconds, float(qs.error[0]),
            )  # fmt: skip
        times_l, e_all, dt_learn_qs, secs_all, error0 = qs_cache[key]
        window = times_l <= duration / unit * (1 + 1e-9)
        times_qs, e_qs = times_l[window] * unit, e_all[window]
        first = times_l <= spec.learning_times * c * (1 + 1e-9)  # the quasi-static window
        e_first = e_all[first]
        seconds_qs = float(secs_all[window][-1])
        level = e_first[-1] + spec.fraction * (1.0 - e_first[-1])
        T_qs = crossing_time(times_qs[first[window]], e_first, level)
        row = {
            "ratio": ratio,
            "alpha": alpha if alpha is not None else math.nan,
            "step_time": unit if adaptive else math.nan,
            "unit": unit,
            "dt": dt,
            "dt_learn": dt_learn_qs * unit,
            "duration": duration,
            "T_qs": T_qs,
            "error_qs_end": float(e_first[-1]),
            "error_qs_window_end": float(e_qs[-1]),
            "rebound_qs": rebound(e_qs),
            "seconds": seconds,
            "seconds_qs": seconds_qs,
            "diverged": run is None,
            "error0": error0,
        }
        row.update(final_coupling(net, task, run, medium))
        if run is None:  # diverged: never learned, unbounded oscillation
            row.update(
                {
                    "T": math.inf,
                    "slowdown": math.inf,
                    "error_final": None,
                    "error_at_qs_end": None,
                    "rebound": math.inf,
                    "rebound_raw": math.inf,
                }
            )
            e, times = np.empty(0), np.empty(0)
        else:
            e, times = run.error / run.error[0], run.times
            T = crossing_time(times, e, level)
            row.update(
                {
                    "T": T,
                    "slowdown": T / T_qs if T_qs > 0 else math.inf,
                    "error_final": float(e[-1]),
                    "error_at_qs_end": float(np.interp(t_learn, times, e)),
                    "rebound": rebound(e, np.interp(times, times_qs, e_qs)),
                    "rebound_raw": rebound(e),
                }
            )
        return row, {"times": times, "error": e, "times_qs": times_qs, "error_qs": e_qs, "run": run}

    arrays: dict[str, np.ndarray] = {}
    rows = []
    series_ratio = float(min(spec.ratios, key=lambda r: abs(math.log(r))))
    for i, ratio in enumerate(spec.ratios):
        row, out = one(ratio)
        rows.append(row)
        for name_ in ("times", "error", "times_qs", "error_qs"):
            arrays[f"r{i}/{name_}"] = out[name_]
        run = out["run"]
        if run is not None:  # the final learned state, whose coupling the row carries
            arrays[f"r{i}/rest_length"], arrays[f"r{i}/stiffness"] = final_state(run)
        if params["series"] and ratio == series_ratio and run is not None:
            idx = np.unique(np.linspace(0, run.times.size - 1, spec.frames).round().astype(int))
            arrays.update(_series_arrays(net, task, run, idx, medium))
    # the grid's bracket, narrowed by bisection in log scale (critical_bracket over every
    # ratio run: a bisection point past narrows from above, one not past from below)
    extra: list[dict] = []
    lo, hi, _ = critical_bracket([r["ratio"] for r in rows], [_past(r) for r in rows])
    if lo > 0 and math.isfinite(hi):
        for _ in range(spec.bisections):
            row, _ = one(math.sqrt(lo * hi))
            extra.append(row)
            lo, hi = (lo, row["ratio"]) if _past(row) else (row["ratio"], hi)
    every = sorted(rows + extra, key=lambda r: r["ratio"])
    lo, hi, exceptions = critical_bracket([r["ratio"] for r in every], [_past(r) for r in every])
    first = next((r for r in every if r["ratio"] == hi), None)
    if first is None:
        which = "none"
    elif first["diverged"]:
        which = "divergence"
    else:
        slow, osc = first["slowdown"] >= SLOWDOWN, first["rebound"] >= OSCILLATION
        which = "both" if slow and osc else ("slowdown" if slow else "oscillation")
    return TimeRunResult(
        critical_low=lo,
        critical_high=hi,
        critical_ratio=math.sqrt(lo * hi)
        if lo > 0 and math.isfinite(hi)
        else (math.inf if lo > 0 else hi),
        critical_by=which,
        non_monotone=exceptions,
        n=n,
        draw=params.get("draw", 0),
        n_nodes=n_nodes,
        rule=name,
        medium=medium,
        tau=tau,
        tau_force=tau_force,
        dof=spec.dof,
        steps_qs=times_meta.get("steps_qs"),
        learned_qs=times_meta.get("learned", True),
        reference_coupling=times_meta.get("coupling"),
        error0=rows[0]["error0"],
        series_ratio=series_ratio if params["series"] else None,
        runs=rows,
        bisection=extra,
        **unit_coupling(rows + extra),
        fields=arrays,
    )


def _series_arrays(net, task, run, idx, medium: str) -> dict[str, Any]:
    """What the PVD export of a run needs (the network, or the body's mesh, and the frames)."""
    if medium != "network":
        mesh = {"body/points": net.body.mesh.p.T, "body/triangles": net.body.mesh.t.T}
    else:
        mesh = {
            "net/positions": net.positions,
            "net/springs": net.springs,
            "net/stiffness": net.stiffness,
            "net/rest_length": net.rest_length,
            "net/sources": task.sources,
            "net/targets": task.targets,
        }
    return {
        **mesh,
        "series/times": run.times[idx],
        "series/x": run.positions[idx],
        "series/rest_length": run.rest_length[idx],
        "series/stiffness": run.stiffness[idx],
    }
