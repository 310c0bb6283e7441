"""Units of an ``allostery`` scene: jammed networks learning allosteric tasks.

Draw ``i`` of a network size ``N`` (``[allostery] n_nodes``) is one jammed packing
(:func:`~continuum_vs_network.network.jammed.jammed_network`, ``phi``, ``dz`` when set,
k = 1/L) built from ``default_rng([seed, N, i])`` and, per task, one allosteric task
(:func:`~continuum_vs_network.learning.allostery.allostery_task`) from
``default_rng([seed, N, i, n_sources])``, trained with its rest example
(:func:`~continuum_vs_network.learning.examples.anchored`). The response ratio is
``+ratio`` for even draws and ``-ratio`` for odd ones. Every rule of a draw trains the
same network on the same task.

* ``allostery/train/n<N>/<task>/<dof>/draw<i>/<rule>``: one rule (the package's default
  rule object of :data:`RULES`, ``dof``), ``steps`` steps (``clamped_steps`` for gpc and
  aging). Arrays: ``error`` (steps + 1,) summed C per step, ``seconds`` (steps + 1,)
  cumulative wall clock, ``rule_seconds`` (the same less the free states measured for the
  record only), ``sweep`` (n_scales, n_targets) target strains of the trained network at
  source scales ``scales``, the network (``positions`` (n, 2), ``springs`` (m, 2),
  ``k0``, ``k``, ``L0``, ``L`` (m,)) and ``sources``, ``targets``. Meta: final C/C0, steps
  to C/C0 <= 1e-2 and 1e-3, coupling (share, verdict), outcome, contrast.
* ``allostery/opt/n<N>/<task>/<dof>/draw<i>``: the bounded optimum of the same draw
  (:func:`optimum`): C/C0, evaluations, seconds, contrast, feasibility (C/C0 <= FEASIBLE);
  and the untrained network's source sweep ``sweep0`` (n_scales, n_targets) with the
  desired strains ``desired`` and rest strains ``rest`` (n_targets,).
* ``allostery/map/n<N>/<task>/draw<j>``: the feasibility map, optimum only, for the first
  dof: one network from ``default_rng([seed, N, 1, j])`` and, for every map distance and
  ratio, one task (sign alternating with ``j``). Arrays (n_distances, n_ratios): ``ratio``
  (optimum C/C0), ``feasible``, ``contrast``.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..learning.metrics import first_below
from .results.allostery import (
    AllosteryOptimumResult,
    AllosteryTrainResult,
    FeasibilityMapResult,
)
from .schema import Scene
from .units import Unit, UnitContext

__all__ = [
    "FEASIBLE",
    "LEVELS",
    "RULES",
    "SCALES",
    "TASKS",
    "Run",
    "optimum",
    "plan_allostery",
    "runs",
]

#: A draw is feasible when the bounded optimum reaches C/C0 <= FEASIBLE.
FEASIBLE = 1e-3
#: C/C0 levels whose first step is recorded (``steps_to``, by :func:`first_below`).
LEVELS = (1e-2, 1e-3)
#: Source scales lambda of the sweeps.
SCALES = (0.0, 0.5, 1.0, 1.5, 2.0)
#: (n_sources, n_targets) of each task.
TASKS = {"1to1": (1, 1), "10to3": (10, 3)}
#: Rules clamped-only (no free state needed: ``clamped_steps``).
CLAMPED = ("gpc", "aging")
#: Rules a scene's raw rate ``alpha`` applies to (the clamped-only ones keep their scaled
#: rate: their lines have one sign, a raw rate sized for GCL drives them to the range's floor).
RAW = ("gcl", "exact")


def _rule(
    name: str,
    dof: str,
    *,
    eta: float | None = None,
    step: float | None = None,
    alpha: float | None = None,
):
    """The package's default rule object ``name`` learning ``dof``: nothing tuned unless the
    scene sets GCL's nudge ``eta``, the default rate's ``step`` or the raw rate ``alpha`` (GCL
    and the exact gradient only, :data:`RAW`)."""
    from dataclasses import replace

    from ..learning import CoupledLearning, DirectedAging, ExactGradient, ProspectiveConfiguration

    cls = {
        "gcl": CoupledLearning,
        "exact": ExactGradient,
        "gpc": ProspectiveConfiguration,
        "aging": DirectedAging,
    }[name]
    kw: dict[str, Any] = {"dof": dof}
    if eta is not None:
        kw["eta"] = eta
    if step is not None:
        kw["rate"] = replace(cls.default_rate, step=step)
    if alpha is not None and name in RAW:
        kw["alpha"] = alpha
    return cls(**kw)


@dataclass(frozen=True)
class Run:
    """One training run of a draw: ``rule`` at nudge ``eta`` (GCL; None: its default) and
    read-out noise ``noise``; ``name`` labels its units (``rule``, ``_eta<eta>`` when the
    scene lists nudges, ``_noise<noise>`` when it lists noise levels other than 0)."""

    name: str
    rule: str
    eta: float | None
    noise: float


def runs(scene: Scene) -> list[Run]:
    """Every run of a draw, rules outermost, then nudges, then noise levels."""
    a = scene.allostery
    noisy = a.noise != (0.0,)
    out = []
    for rule in a.rules:
        etas = a.etas if (rule == "gcl" and a.etas) else (None,)
        for eta in etas:
            for sigma in a.noise:
                name = rule + ("" if eta is None else f"_eta{eta:g}")
                name += f"_noise{sigma:g}" if noisy else ""
                out.append(Run(name, rule, eta, float(sigma)))
    return out


#: The rule classes by scene name (for the text).
RULES = {
    "gcl": "CoupledLearning",
    "exact": "ExactGradient",
    "gpc": "ProspectiveConfiguration",
    "aging": "DirectedAging",
}


def optimum(net, tasks, dof: str):
    """The least error learning ``dof`` can reach within the physical range
    (:func:`~continuum_vs_network.learning.optimum.exact_optimum`, its defaults)."""
    from ..learning.optimum import exact_optimum

    return exact_optimum(net, tasks, dof=dof)


@functools.lru_cache(maxsize=4)
def _network(n: int, phi: float, dz: float | None, seed: tuple[int, ...]):
    from ..network.jammed import jammed_network

    kw = {} if dz is None else {"dz": dz}
    return jammed_network(n, np.random.default_rng(list(seed)), phi=phi, **kw)


def draw(
    scene: Scene,
    n: int,
    task: str,
    i: int,
    *,
    distance: float | None = None,
    ratio: float | None = None,
    stream: tuple[int, ...] = (),
):
    """Network, task and anchored task set of draw ``i`` (see the module).

    ``stream`` separates the map's draws from the trained ones; ``distance`` and ``ratio``
    default to the scene's (the sign of ``ratio`` alternates with ``i`` either way).
    """
    from ..learning import anchored
    from ..learning.allostery import allostery_task

    a = scene.allostery
    net = _network(n, a.phi, a.dz, (scene.seed, n, *stream, i))
    n_src, n_tgt = TASKS[task]
    size = abs(a.ratio if ratio is None else ratio)
    t = allostery_task(
        net,
        np.random.default_rng([scene.seed, n, *stream, i, n_src]),
        n_sources=n_src,
        n_targets=n_tgt,
        ratio=size if i % 2 == 0 else -size,
        source_strain=a.source_strain,
        distance=a.distance if distance is None else distance,
    )
    return net, t, anchored(t, net)


def plan_allostery(scene: Scene) -> list[Unit]:
    a = scene.allostery
    common = {"seed": scene.seed, "phi": a.phi, "dz": a.dz, "source_strain": a.source_strain}
    map_depends = {**common, "distances": a.map_distances, "ratios": a.map_ratios, "dof": a.dofs[0]}
    depends = {**common, "ratio": a.ratio, "distance": a.distance}
    units: list[Unit] = []
    for n in a.n_nodes:
        for task in a.tasks:
            for j in range(a.map_draws if a.map_distances and a.map_ratios else 0):
                units.append(
                    Unit(
                        f"allostery/map/n{n}/{task}/draw{j}",
                        map_unit,
                        {"n": n, "task": task, "draw": j},
                        map_depends,
                    )
                )
            for dof in a.dofs:
                for i in range(a.draws):
                    p = {"n": n, "task": task, "dof": dof, "draw": i}
                    base = f"n{n}/{task}/{dof}/draw{i}"
                    if a.optimum:
                        units.append(Unit(f"allostery/opt/{base}", optimum_unit, p, depends))
                    for run in runs(scene):
                        steps = steps_of(scene, run.rule)
                        units.append(
                            Unit(
                                f"allostery/train/{base}/{run.name}",
                                train_unit,
                                {
                                    **p,
                                    "rule": run.rule,
                                    "eta": run.eta,
                                    "noise": run.noise,
                                    "steps": steps,
                                },
                                {**depends, "step": a.step, "alpha": a.alpha},
                                weight=steps * (1 + (run.noise > 0)),
                            )
                        )
    return units


def steps_of(scene: Scene, rule: str) -> int:
    """Learning steps of ``rule`` (``clamped_steps`` for the clamped-only rules)."""
    a = scene.allostery
    return a.clamped_steps if rule in CLAMPED and a.clamped_steps is not None else a.steps


def contrast(k0, k, mask) -> float:
    """``max(k/k0) / min(k/k0)`` over the springs of ``mask``."""
    r = np.asarray(k, dtype=float)[mask] / np.asarray(k0, dtype=float)[mask]
    return float(np.max(r) / np.min(r)) if r.size else 1.0


def train_unit(scene: Scene, params: dict, ctx: UnitContext) -> AllosteryTrainResult:
    """One rule on one draw (see the module)."""
    from ..learning import measure_coupling, train
    from ..learning.coupling import outcome
    from ..network.equilibrium import EquilibriumError

    net, task, tasks = draw(scene, params["n"], params["task"], params["draw"])
    rule = _rule(
        params["rule"],
        params["dof"],
        eta=params.get("eta"),
        step=scene.allostery.step,
        alpha=scene.allostery.alpha,
    )
    steps = steps_of(scene, params["rule"])
    noise = float(params.get("noise", 0.0))
    cb = None if ctx.on_step is None else (lambda trial, step, net: ctx.on_step())
    h = train(net, tasks, rule, steps, noise=noise, progress=False, callback=cb)
    e = np.asarray(h.error_initial[0], dtype=float)
    r = e / e[0]
    done = int(h.completed[0]) == steps
    final = h.final[0]
    sweep = np.full((len(SCALES), task.n_targets), np.nan)
    share, verdict = float("nan"), "not measured"
    if done:
        try:
            c = measure_coupling(net, final, task, scales=SCALES)
            sweep, share, verdict = c.sweep, float(c.share), c.verdict
        except EquilibriumError:
            pass
    ratio = float(r[-1]) if done else float("nan")
    mask = rule.learning_mask(net, task)
    seconds = np.asarray(h.seconds[0], dtype=float)
    measured = np.asarray(h.data["measure_seconds"][0], dtype=float)
    return AllosteryTrainResult(
        error=e,
        seconds_trace=seconds,
        rule_seconds_trace=seconds - measured,
        sweep=sweep,
        positions=net.positions,
        springs=net.springs,
        k0=net.stiffness,
        k=final.stiffness,
        L0=net.rest_length,
        L=final.rest_length,
        sources=task.sources,
        targets=task.targets,
        ratio=ratio,
        floor=_floor(r, done),
        noise=noise,
        eta=getattr(rule, "eta", float("nan")),
        steps=steps,
        completed=int(h.completed[0]),
        stop_reason=h.stop_reason[0],
        steps_to={f"{lv:g}": first_below(r, lv) for lv in LEVELS},
        share=share,
        coupling=verdict,
        outcome=outcome(ratio, None if verdict == "not measured" else verdict),
        contrast=contrast(net.stiffness, final.stiffness, mask),
        seconds=float(np.nanmax(seconds)),
        rule_seconds=float(np.nanmax(seconds - measured)),
        n_nodes=int(net.n_nodes),
        n_springs=int(net.n_springs),
        task_ratio=float(task.target_strain[0] / task.source_strain[0]),
    )


def _floor(r: np.ndarray, done: bool, fraction: float = 0.25) -> float:
    """Median C/C0 over the last ``fraction`` of the steps (the level a noisy run settles
    at, robust to a run still descending); NaN for a run that stopped early."""
    from ..learning.noise import noise_floor

    completed = np.array([r.size - 1 if done else 0])
    return float(noise_floor(r[None, :], completed, fraction=fraction, statistic=np.median)[0])


def optimum_unit(scene: Scene, params: dict, ctx: UnitContext) -> AllosteryOptimumResult:
    """The bounded optimum of one draw and the untrained network's sweep."""
    from ..learning import measure_coupling
    from ..network.equilibrium import EquilibriumError

    net, task, tasks = draw(scene, params["n"], params["task"], params["draw"])
    c0 = measure_coupling(net, net, task, scales=SCALES)
    t0 = time.perf_counter()
    opt = optimum(net, tasks, params["dof"])
    seconds = time.perf_counter() - t0
    try:
        share = float(measure_coupling(net, opt.net, task, scales=SCALES).share)
    except EquilibriumError:
        share = float("nan")
    return AllosteryOptimumResult(
        sweep0=c0.sweep,
        desired=c0.desired,
        rest=c0.initial_off,
        example_ratio=opt.example_ratio,
        ratio=float(opt.ratio),
        feasible=bool(opt.ratio <= FEASIBLE),
        evaluations=int(opt.evaluations),
        iterations=int(opt.iterations),
        converged=bool(opt.converged),
        seconds=seconds,
        contrast=float(opt.contrast),
        share=share,
        n_nodes=int(net.n_nodes),
        n_springs=int(net.n_springs),
    )


def map_unit(scene: Scene, params: dict, ctx: UnitContext) -> FeasibilityMapResult:
    """The feasibility map of one map draw: the optimum at every distance and ratio."""
    from ..learning.allostery import spring_distances

    a = scene.allostery
    shape = (len(a.map_distances), len(a.map_ratios))
    out = {k: np.full(shape, np.nan) for k in ("ratio", "contrast", "distance")}
    for di, d in enumerate(a.map_distances):
        for ri, q in enumerate(a.map_ratios):
            net, task, tasks = draw(
                scene, params["n"], params["task"], params["draw"], distance=d, ratio=q, stream=(1,)
            )
            opt = optimum(net, tasks, a.dofs[0])
            out["ratio"][di, ri] = opt.ratio
            out["contrast"][di, ri] = opt.contrast
            near = spring_distances(net, task.sources)[task.targets]
            out["distance"][di, ri] = float(np.min(near))
    return FeasibilityMapResult(
        **out, feasible=out["ratio"] <= FEASIBLE, dof=a.dofs[0], n_nodes=int(net.n_nodes)
    )
