"""Units of physical_time scenes: learning concurrent with the dynamics, one unit per size
and rule (``physical_time/n<n>/<rule>``).

For an ``n x n`` triangular lattice (k = 1) with a Stern-scale task (sources and targets
frozen, bulk learning, strains against the initial rest lengths), the unit measures the
relaxation time ``tau`` after the source step, the time for the target strains (what
learning reads) to come within 1 % of their total change of their new equilibrium
(:func:`~continuum_vs_network.learning.physical_time.network_relaxation_time`, the body's
:func:`~continuum_vs_network.continuum.damped_states.body_relaxation_time`; the older
net-force time ``tau_force`` is kept in the meta for comparison), then for
every ratio ``rho = alpha k tau`` of ``[physical_time] ratios`` runs

* the rule in physical time (:func:`~continuum_vs_network.learning.physical_time.learn_in_time`)
  for ``max(learning_times / (alpha k), relaxation_times tau)``, and
* its quasi-static limit (every physical step an equilibrium) for ``learning_times /
  (alpha k)`` with the same steps,

with ``dt = min(tau / steps_per_tau, 1 / (steps_per_rate alpha k))`` for both (physical
and learning step equal; ``gcl_phases`` learns once per cycle of two phases of
``min(phase tau, 1 / (2 steps_per_rate alpha k))``, so its learning step is no longer).

Measured per ratio (errors relative to the initial one): the time to make all but
``fraction`` of the quasi-static error drop, in both runs (``T`` and ``T_qs``) and their
ratio (the slowdown), the final errors, and the oscillation: the largest factor by which
the error climbs back above its running minimum (:func:`rebound`).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from .schema import Scene
from .units import Unit, UnitContext

__all__ = ["OSCILLATION", "SLOWDOWN", "critical_ratio", "crossing_time", "plan_time", "rebound"]

#: A run is past the quasi-static regime when it learns this many times slower than its
#: quasi-static limit ...
SLOWDOWN = 2.0
#: ... or when its error climbs back to this many times its running minimum (oscillation).
OSCILLATION = 2.0
#: Errors below this fraction of the initial one are at the solver's floor: no rebound.
FLOOR = 1e-6


def plan_time(scene: Scene) -> list[Unit]:
    """One unit per size and rule."""
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "physical_time") if k in d}
    sizes = scene.network.sizes
    rules = scene.physical_time.rules
    series = scene.export is not None and scene.export.series
    return [
        Unit(
            key=f"physical_time/n{n}/{rule}" + ("" if medium == "network" else f"/{medium}"),
            func=time_unit,
            params={
                "n": int(n),
                "rule": rule,
                "medium": medium,
                "series": bool(series and n == sizes[-1]),
            },
            depends=depends,
        )
        for medium in scene.physical_time.media
        for n in sizes
        for rule in rules
    ]


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


def rebound(values: np.ndarray, floor: float = FLOOR) -> float:
    """Largest ``v[j] / min(v[:j+1])`` over the ``v[j] >= floor``: how far the error climbs
    back above its running minimum (1 for a monotone decrease; an overshoot through zero
    and back gives a large value)."""
    v = np.asarray(values, float)
    running = np.minimum.accumulate(v)
    ok = v >= floor
    if not ok.any():
        return 1.0
    return float(np.max(v[ok] / np.maximum(running[ok], floor * 1e-6)))


def critical_ratio(ratios, slowdown, rebounds) -> tuple[float, str]:
    """The smallest ratio past the quasi-static regime, and which criterion it met.

    A ratio is past when ``slowdown >= SLOWDOWN`` (learning time over its quasi-static
    value; inf when the level is never reached) or ``rebound >= OSCILLATION``. Between the
    last ratio before and the first one past, the crossing of the criterion is
    interpolated in log-log (geometric mean when a value is inf or 0). Returns
    ``(ratios[0], ...)`` when the first ratio is already past and ``(inf, "none")`` when
    none is.
    """
    r = np.asarray(ratios, float)
    s = np.asarray(slowdown, float)
    q = np.asarray(rebounds, float)
    past = (s >= SLOWDOWN) | (q >= OSCILLATION)
    if not past.any():
        return math.inf, "none"
    i = int(np.argmax(past))
    which = "slowdown" if s[i] >= SLOWDOWN else "oscillation"
    if i == 0:
        return float(r[0]), which
    values, level = (s, SLOWDOWN) if which == "slowdown" else (q, OSCILLATION)
    v0, v1 = values[i - 1], values[i]
    if not (np.isfinite(v1) and v0 > 0 and v1 > v0):
        return float(math.sqrt(r[i - 1] * r[i])), which
    f = math.log(level / v0) / math.log(v1 / v0)
    return float(r[i - 1] * (r[i] / r[i - 1]) ** min(max(f, 0.0), 1.0)), which


def _rule(name: str, alpha: float, eta: float):
    from ..learning.rules import CoupledLearning, ProspectiveConfiguration

    kw = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}
    if name == "gpc":
        return ProspectiveConfiguration(alpha, **kw)
    return CoupledLearning(alpha, eta, **kw)


def _lattice_task(scene: Scene, n: int):
    from ..learning.tasks import stern_task
    from .units_physics import lattice

    t = scene.task
    net = lattice(scene, n)
    rng = np.random.default_rng([scene.seed, n])
    for _ in range(200):  # clamps are held end nodes: sources and targets share no node
        task = stern_task(
            net, t.n_sources, t.n_targets, rng, source_std=t.source_std, target_std=t.target_std
        )
        ends = net.springs[np.concatenate([task.sources, task.targets])].ravel()
        if np.unique(ends).size == ends.size:
            return net, task
    raise ValueError(
        f"no task of {t.n_sources} sources and {t.n_targets} targets without shared nodes "
        f"found on the {n} x {n} lattice in 200 draws; use fewer springs or a larger lattice"
    )


def _medium(scene: Scene, n: int, medium: str, vis):
    """``(learner, task, tau, tau_force, n_nodes)``: the lattice, or its continuum (P1 on
    the lattice's triangles, lattice Lamé parameters, the same task's material springs);
    ``tau`` by the target strains, ``tau_force`` by the net force."""
    from ..learning.physical_time import network_relaxation_time

    net, task = _lattice_task(scene, n)
    if medium == "network":
        times = [network_relaxation_time(net, task, vis, measure=m) for m in ("target", "force")]
        return net, task, *times, net.n_nodes
    from ..continuum.damped_states import body_relaxation_time
    from ..continuum.learnable import learnable_body
    from ..continuum.material_task import MaterialTask
    from ..continuum.materials import lattice_lame
    from ..continuum.mesh import network_mesh
    from ..continuum.viscoelastic import lattice_damping

    body = learnable_body(network_mesh(net), lattice_lame(float(np.mean(net.stiffness))))
    mtask = MaterialTask.from_network(net, task, body)
    damping = lattice_damping(vis)
    times = [body_relaxation_time(body, mtask, damping, measure=m) for m in ("target", "force")]
    return body, mtask, *times, net.n_nodes


def _past(row: dict) -> bool:
    return row["slowdown"] >= SLOWDOWN or row["rebound"] >= OSCILLATION


def time_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Learning in physical time against the ratio, for one size, rule and medium."""
    from ..learning.physical_time import learn_in_time
    from ..learning.rules import LearningError
    from ..network.viscous import Viscosity

    spec = scene.physical_time
    n, name, medium = params["n"], params["rule"], params.get("medium", "network")
    vis = Viscosity(
        drag=spec.drag,
        dashpot=spec.dashpot,
        arm_stiffness=spec.arm_stiffness,
        arm_dashpot=spec.arm_dashpot,
    )
    net, task, tau, tau_force, n_nodes = _medium(scene, n, medium, vis)
    k = 1.0  # the lattice's spring stiffness: rho = alpha k tau in both media
    qs_cache: dict[tuple, tuple] = {}

    def one(ratio: float) -> tuple[dict, dict]:
        alpha = ratio / (k * tau)
        rule = _rule(name, alpha, spec.eta)
        dt = min(tau / spec.steps_per_tau, 1.0 / (spec.steps_per_rate * alpha * k))
        opts: dict[str, Any] = {"form": "twin"} if name == "gcl" else {}
        if name == "gcl_phases":
            phase = min(spec.phase * tau, 0.5 / (spec.steps_per_rate * alpha * k))
            dt = min(dt, phase)
            opts = {"form": "phases", "phase": phase}
        t_learn = spec.learning_times / (alpha * k)
        duration = max(t_learn, spec.relaxation_times * tau)
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
        # one run per learning step in those units, rescaled
        key = (round(alpha * k * dt, 12), round(alpha * k * opts.get("phase", 0.0), 12))
        if key not in qs_cache:
            try:
                qs = learn_in_time(
                    net, task, rule, viscosity=vis, duration=t_learn, dt=dt, n_outputs=60,
                    quasistatic=True, **opts,
                )  # fmt: skip
            except (LearningError, RuntimeError) as err:
                raise ValueError(
                    f"the quasi-static run diverged at ratio {ratio:g} ({err}): its learning "
                    "step is too long; raise [physical_time] steps_per_rate"
                ) from err
            qs_cache[key] = (
                qs.times * alpha * k, qs.error / qs.error[0], qs.dt_learn * alpha * k,
                float(qs.seconds[-1]), float(qs.error[0]),
            )  # fmt: skip
        times_qs, e_qs, dt_learn_qs, seconds_qs, error0 = qs_cache[key]
        times_qs = times_qs / (alpha * k)
        level = e_qs[-1] + spec.fraction * (1.0 - e_qs[-1])
        T_qs = crossing_time(times_qs, e_qs, level)
        row = {
            "ratio": ratio,
            "alpha": alpha,
            "dt": dt,
            "dt_learn": dt_learn_qs / (alpha * k),
            "duration": duration,
            "T_qs": T_qs,
            "error_qs_end": float(e_qs[-1]),
            "seconds": seconds,
            "seconds_qs": seconds_qs,
            "diverged": run is None,
            "error0": error0,
        }
        if run is None:  # diverged: never learned, unbounded oscillation
            row.update(
                {
                    "T": math.inf,
                    "slowdown": math.inf,
                    "error_final": None,
                    "error_at_qs_end": None,
                    "rebound": math.inf,
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
                    "rebound": rebound(e),
                }
            )
        return row, {"times": times, "error": e, "times_qs": times_qs, "error_qs": e_qs, "run": run}

    arrays: dict[str, Any] = {}
    rows = []
    series_ratio = float(min(spec.ratios, key=lambda r: abs(math.log(r))))
    for i, ratio in enumerate(spec.ratios):
        row, out = one(ratio)
        rows.append(row)
        for name_ in ("times", "error", "times_qs", "error_qs"):
            arrays[f"r{i}/{name_}"] = out[name_]
        run = out["run"]
        if params["series"] and ratio == series_ratio and run is not None:
            idx = np.unique(np.linspace(0, run.times.size - 1, spec.frames).round().astype(int))
            arrays.update(_series_arrays(net, task, run, idx, medium))
    # bisection of the critical ratio in log scale between the bracketing grid ratios
    extra: list[dict] = []
    past = [_past(r) for r in rows]
    if any(past) and past.index(True) > 0:
        j = past.index(True)
        lo, hi = rows[j - 1], rows[j]
        for _ in range(spec.bisections):
            row, _ = one(math.sqrt(lo["ratio"] * hi["ratio"]))
            extra.append(row)
            lo, hi = (lo, row) if _past(row) else (row, hi)
    every = sorted(rows + extra, key=lambda r: r["ratio"])
    crit, which = critical_ratio(
        [r["ratio"] for r in every], [r["slowdown"] for r in every], [r["rebound"] for r in every]
    )
    first = [r for r in every if _past(r)]
    if first and first[0]["diverged"]:
        which = "divergence"
    meta = {
        "critical_ratio": crit,
        "critical_by": which,
        "n": n,
        "n_nodes": n_nodes,
        "rule": name,
        "medium": medium,
        "tau": tau,
        "tau_force": tau_force,
        "error0": rows[0]["error0"],
        "series_ratio": series_ratio if params["series"] else None,
        "runs": rows,
        "bisection": extra,
    }
    return arrays, meta


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
