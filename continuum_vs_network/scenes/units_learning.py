"""Units of a learning scene: training trials, then sweeps, gradient comparison and fields.

* ``train/<solver>/<rule>/noise<i>/trial<k>``: one trial (seed ``scene.seed + k``) of one
  rule with one equilibrium solver at one read-out noise level; a one-trial
  :class:`~continuum_vs_network.learning.History`, checkpointed inside the trial.
* ``sweeps/<solver>/<rule>`` (``[learning] sweeps``): source sweeps of the trained networks
  (Fig. 5 and the appendix), noise level 0 (the first listed).
* ``gradient/<rule>`` (``[learning] compare_gradient``): cosine between each rule's step and
  the exact gradient's, at every trial's initial and final network;
* ``coupling/<solver>/<rule>/noise<i>`` (every run, unless ``measure = false`` asks for the
  rules' own work only): target strains of every trained network
  with the sources on, off and over a source sweep, and of the initial network with the
  sources off (:mod:`~continuum_vs_network.learning.coupling`), so that every learning
  result states whether the sources cause the target strains;
* ``fields/<solver>/<rule>`` (only with ``[export]`` or ``[report] images``): free states of
  the exported trials' initial and final networks and, with ``[export] series``, of the
  trajectory frames.

Nothing else is solved: a prospective-configuration run with ``measure = false`` (which
also skips the coupling measurement) and neither sweeps, gradient comparison, export nor
images solves no free state at all.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ..io.atomic import atomic_path
from .schema import Scene
from .units import Unit, UnitContext

__all__ = [
    "build_rules",
    "experiments",
    "frames_file",
    "group_key",
    "plan_learning",
    "run_names",
]

_STERN_KIND = {"triangular": "lattice", "diluted": "diluted", "jammed": "jammed"}


def group_key(solver: str, rule: str, noise_index: int) -> str:
    """Key of a learning run: ``"<solver>/<rule>/noise<i>"``."""
    return f"{solver}/{rule}/noise{noise_index}"


def run_names(scene: Scene) -> tuple[str, ...]:
    """The scene's learning runs: its rules, a GCL rule once per nudge when ``etas`` lists
    nudges (``<rule>_eta<value>``)."""
    L = scene.learning
    out = []
    for rule in L.rules:
        if rule.startswith("gcl") and L.etas:
            out += [f"{rule}_eta{eta:g}" for eta in L.etas]
        else:
            out.append(rule)
    return tuple(out)


def _solvers(scene: Scene) -> tuple[str, ...]:
    return scene.solver.methods if scene.solver is not None else ("newton",)


def _training_depends(scene: Scene) -> dict[str, Any]:
    d = scene.to_dict()
    learning = {
        k: v
        for k, v in d["learning"].items()
        if k
        not in (
            "rules",
            "trials",
            "noise",
            "sweeps",
            "sweep_span",
            "sweep_points",
            "compare_gradient",
        )
    }
    solver = d.get("solver", {})
    return {
        "seed": scene.seed,
        "network": d["network"],
        "task": d["task"],
        "learning": learning,
        "paper_iterations": solver.get("paper_iterations", 300),
    }


def plan_learning(scene: Scene) -> list[Unit]:
    """Training trials (phase 0) and the units that read their histories (phase 1)."""
    L = scene.learning
    assert L is not None
    dep = _training_depends(scene)
    export = scene.export
    series_trials = set(export.trials) if export is not None and export.series else set()
    units: list[Unit] = []
    for solver in _solvers(scene):
        for rule in run_names(scene):
            for i, noise in enumerate(L.noise):
                for k in range(L.trials):
                    series = export.every if (k in series_trials and i == 0) else 0
                    units.append(
                        Unit(
                            key=f"train/{group_key(solver, rule, i)}/trial{k}",
                            func=train_unit,
                            params={
                                "solver": solver,
                                "rule": rule,
                                "noise": noise,
                                "seed": scene.seed + k,
                                "series_every": series,
                            },
                            depends=dep,
                            weight=L.steps,
                        )
                    )
    first = {"sweep_span": L.sweep_span, "sweep_points": L.sweep_points}
    for solver in _solvers(scene):
        for rule in run_names(scene):
            for i, noise in enumerate(L.noise if L.measure else ()):
                units.append(
                    Unit(
                        key=f"coupling/{group_key(solver, rule, i)}",
                        func=coupling_unit,
                        params={"group": group_key(solver, rule, i)},
                        depends={**dep, "trials": L.trials, "noise": noise},
                        phase=1,
                    )
                )
            deps = {**dep, "trials": L.trials, "noise": L.noise[0]}
            if L.sweeps:
                units.append(
                    Unit(
                        key=f"sweeps/{solver}/{rule}",
                        func=sweeps_unit,
                        params={"group": group_key(solver, rule, 0), **first},
                        depends=deps,
                        phase=1,
                    )
                )
            if scene.export is not None or scene.report.images:
                trials = list(export.trials) if export is not None else [0]
                units.append(
                    Unit(
                        key=f"fields/{solver}/{rule}",
                        func=fields_unit,
                        params={
                            "group": group_key(solver, rule, 0),
                            "trials": trials,
                            "series": bool(series_trials),
                        },
                        depends=deps,
                        phase=1,
                    )
                )
    if L.compare_gradient:
        solver = "newton" if "newton" in _solvers(scene) else _solvers(scene)[0]
        for rule in run_names(scene):
            if rule == "exact":
                continue
            units.append(
                Unit(
                    key=f"gradient/{rule}",
                    func=gradient_unit,
                    params={"group": group_key(solver, rule, 0), "rule": rule},
                    depends={**dep, "trials": L.trials, "noise": L.noise[0]},
                    phase=1,
                )
            )
    return units


# -- building networks, tasks and rules ----------------------------------------------------
def _paper_network(rng: np.random.Generator, *, noise: float):
    from ..network.builders import paper_network

    return paper_network(rng, noise=noise)


def _stern_network(rng: np.random.Generator, *, n_nodes: int, kind: str, noise: float):
    from ..learning.stern import stern_network

    return stern_network(n_nodes, rng, kind=kind, noise=noise)


def _stern_task(
    net,
    rng: np.random.Generator,
    *,
    n_sources: int,
    n_targets: int,
    source_std: float,
    target_std: float,
    anchored: bool = False,
    strain_reference: str = "initial",
):
    from ..learning.examples import anchored as with_rest
    from ..learning.tasks import stern_task

    task = stern_task(
        net,
        n_sources,
        n_targets,
        rng,
        candidates=np.ones(net.n_springs, bool),
        source_std=source_std,
        target_std=target_std,
    )
    return with_rest(task, net, strain_reference=strain_reference) if anchored else task


def task_example(task):
    """The task example of a trained task: ``task`` itself, or a task set's first example
    (an anchored task's rest example is not the task; coupling and fields read the task)."""
    from ..learning.examples import TaskSet

    return task.tasks[0] if isinstance(task, TaskSet) else task


def builders(scene: Scene):
    """``(network, task)`` callables of a trial generator, as :func:`~.learning.train` takes."""
    from ..learning.tasks import paper_task

    net, task = scene.network, scene.task
    noise = 0.1 if net.noise is None else net.noise
    if net.builder == "paper":
        return functools.partial(_paper_network, noise=noise), paper_task
    return (
        functools.partial(
            _stern_network, n_nodes=net.n_nodes, kind=_STERN_KIND[net.builder], noise=noise
        ),
        functools.partial(
            _stern_task,
            n_sources=task.n_sources,
            n_targets=task.n_targets,
            source_std=task.source_std,
            target_std=task.target_std,
            anchored=task.anchored,
            strain_reference=scene.learning.strain_reference,
        ),
    )


def _solver(scene: Scene, name: str):
    from ..learning.replication import exact_solver, paper_solver

    if name == "newton":
        return exact_solver()
    iterations = scene.solver.paper_iterations if scene.solver is not None else 300
    return paper_solver(iterations)


def build_rules(scene: Scene, solver: str = "newton") -> dict[str, Any]:
    """The learning rules the scene names, with the equilibrium solver ``solver``.

    The paper task uses :func:`~continuum_vs_network.learning.replication.paper_experiments`
    (every spring learns in ``gcl``, ``gpc`` and ``exact``, as in the paper); Stern-scale
    tasks :func:`~continuum_vs_network.learning.stern.stern_rules`: ``gcl``, ``gpc`` and
    ``exact`` learn in the bulk (sources and targets frozen; the exact gradient uses
    ``alpha_gcl`` on the length cost, as ``stern_rules`` matches the step sizes),
    ``gcl_all`` and ``gpc_all`` let every spring learn, ``aging`` and ``aging_k`` are
    directed aging of rest lengths and stiffnesses (in the bulk, :func:`aging_rules`),
    ``gcl_both`` GCL of rest lengths and stiffnesses together (``dof="both"``).
    Keys are :func:`run_names`.
    """
    import dataclasses

    L = scene.learning
    eq_solver = _solver(scene, solver)
    if scene.task.kind == "paper":
        from ..learning.replication import paper_experiments

        exps = paper_experiments(
            strain_reference=L.strain_reference,
            solver=eq_solver,
            alpha_gcl=L.alpha_gcl,
            eta=L.eta,
            alpha_gpc=L.alpha_gpc,
            alpha_exact=L.alpha_exact,
            floor=L.floor,
        )
        table = {e.name: e.rule for e in exps}
    else:
        from ..learning.stern import stern_rules

        kw = {"alpha": L.alpha_gcl, "eta": L.eta, "alpha_gpc": L.alpha_gpc, "solver": eq_solver}
        bulk = stern_rules(**kw)
        every = stern_rules(**kw, learn_sources=True, learn_targets=True)
        table = {
            "gcl": bulk["GCL"],
            "gpc": bulk["GPC"],
            "exact": bulk["exact"],
            "gcl_all": every["GCL"],
            "gpc_all": every["GPC"],
        }
        table.update(aging_rules(L.alpha_aging, bulk["GPC"]))
        table["gcl_both"] = dataclasses.replace(bulk["GCL"], dof="both", min_stiffness=1e-3)
    out = {}
    for rule in L.rules:
        if rule.startswith("gcl") and L.etas:
            for eta in L.etas:
                out[f"{rule}_eta{eta:g}"] = dataclasses.replace(table[rule], eta=eta)
        else:
            out[rule] = table[rule]
    return out


def aging_rules(alpha: float, like) -> dict[str, Any]:
    """Directed aging of rest lengths (``aging``) and stiffnesses (``aging_k``) with the
    options of the rule ``like`` (bulk learning, strain reference, solver, floor)."""
    from ..learning.aging import DirectedAging

    common = {
        "learn_sources": like.learn_sources,
        "learn_targets": like.learn_targets,
        "strain_reference": like.strain_reference,
        "solver": like.solver,
    }
    floor = like.min_rest_length
    return {
        "aging": DirectedAging(alpha, min_rest_length=floor, **common),
        "aging_k": DirectedAging(alpha, dof="stiffness", min_stiffness=1e-3, **common),
    }


def experiments(scene: Scene, solver: str = "newton"):
    """The paper's :class:`~.learning.replication.Experiment` objects the scene names."""
    from ..learning.replication import paper_experiments

    L = scene.learning
    exps = paper_experiments(
        strain_reference=L.strain_reference,
        solver=_solver(scene, solver),
        alpha_gcl=L.alpha_gcl,
        eta=L.eta,
        alpha_gpc=L.alpha_gpc,
        alpha_exact=L.alpha_exact,
        floor=L.floor,
    )
    return tuple(e for e in exps if e.name in L.rules)


# -- units ---------------------------------------------------------------------------------
def train_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One training trial; returns its (one-trial) History."""
    from ..learning.train import train

    L = scene.learning
    rule = build_rules(scene, params["solver"])[params["rule"]]
    net, task = builders(scene)
    every = int(params["series_every"])
    frames_path = ctx.checkpoint.with_name(ctx.checkpoint.stem + ".frames.npz")
    frames = _load_frames(frames_path) if every else {}

    def callback(trial: int, step: int, cur) -> None:
        if every and (step % every == 0 or step == L.steps):
            frames[step] = (np.array(cur.rest_length), np.array(cur.stiffness))
            _save_frames(frames_path, frames)
        if ctx.on_step is not None:
            ctx.on_step()

    history = train(
        net,
        task,
        rule,
        L.steps,
        seeds=(int(params["seed"]),),
        noise=float(params["noise"]),
        measure=L.measure,
        progress=False,
        checkpoint=ctx.checkpoint,
        checkpoint_every=L.checkpoint_every,
        callback=callback,
    )
    if every:
        _save_frames(frames_file(ctx.directory, ctx.key), frames)
    frames_path.unlink(missing_ok=True)
    return history


def frames_file(directory, key: str):
    """Where the trajectory frames (rest lengths, stiffnesses) of a training unit are kept."""
    return directory / "frames" / (key.replace("/", "__") + ".npz")


def _load_frames(path) -> dict[int, tuple]:
    if not path.exists():
        return {}
    with np.load(path) as z:
        steps = z["steps"]
        return {int(s): (z["rest_length"][i], z["stiffness"][i]) for i, s in enumerate(steps)}


def _save_frames(path, frames: dict[int, tuple]) -> None:
    steps = sorted(frames)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(
            fh,
            steps=np.array(steps, dtype=np.int64),
            rest_length=np.array([frames[s][0] for s in steps]),
            stiffness=np.array([frames[s][1] for s in steps]),
        )


def coupling_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Coupling of every trial's trained network (sources on / off, a source sweep)."""
    from ..learning.coupling import SCALES, measure_coupling
    from ..learning.replication import exact_solver
    from ..network.equilibrium import EquilibriumError

    history = ctx.history(params["group"])
    tasks = [task_example(t) for t in history.tasks]
    n, nt = history.trials, tasks[0].n_targets
    sweep = np.full((n, len(SCALES), nt), np.nan)
    initial_off = np.full((n, nt), np.nan)
    initial_on = np.full((n, nt), np.nan)
    desired = np.full((n, nt), np.nan)
    share = np.full(n, np.nan)
    verdicts, failed = [], []
    for i in range(n):
        desired[i] = tasks[i].target_strain
        try:
            c = measure_coupling(
                history.initial[i],
                history.final[i],
                tasks[i],
                strain_reference=history.strain_reference,
                solver=exact_solver(),
            )
        except EquilibriumError as err:
            verdicts.append("not measured")
            failed.append(f"trial {i}: {err.reason}")
            continue
        sweep[i], initial_off[i], initial_on[i] = c.sweep, c.initial_off, c.initial_on
        share[i] = c.share
        verdicts.append(c.verdict)
    arrays = {
        "scales": np.array(SCALES),
        "sweep": sweep,
        "initial_off": initial_off,
        "initial_on": initial_on,
        "desired": desired,
        "share": share,
    }
    return arrays, {"verdicts": verdicts, "failed": failed}


def sweeps_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Source sweeps of every trial's final network (exact equilibria)."""
    from ..learning.replication import exact_solver, sweeps

    history = ctx.history(params["group"])
    strains, target = sweeps(
        history, span=params["sweep_span"], points=params["sweep_points"], solver=exact_solver()
    )
    desired = np.array([t.target_strain[0] for t in history.tasks])
    source = np.array([t.source_strain[0] for t in history.tasks])
    return {
        "source_strain": strains,
        "target_strain": target,
        "desired": desired,
        "task_source": source,
    }, {"failed": int(np.sum(np.isnan(target).all(axis=1)))}


def gradient_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Cosine of the rule's step with the exact gradient step (same masks, exact states)."""
    from ..learning.metrics import cosine
    from ..learning.rules import ExactGradient, LearningError
    from ..learning.states import Solver
    from ..network.equilibrium import EquilibriumError

    history = ctx.history(params["group"])
    rule = build_rules(scene, "newton")[params["rule"]]
    cost = "strain" if scene.task.kind == "paper" else "length"
    exact = ExactGradient(
        1.0,
        cost=cost,
        strain_reference=rule.strain_reference,
        learn_sources=rule.learn_sources,
        learn_targets=rule.learn_targets,
        dof=rule.dof,
        solver=Solver(),
    )
    out = np.full((history.trials, 2), np.nan)
    for i in range(history.trials):
        for j, net in enumerate((history.initial[i], history.final[i])):
            try:
                a = rule.update(net, history.tasks[i]).delta
                b = exact.update(net, history.tasks[i]).delta
            except (EquilibriumError, LearningError):
                continue
            if np.linalg.norm(a) > 0 and np.linalg.norm(b) > 0:
                out[i, j] = cosine(a, b)
    return {"cosine": out}, {"rule": params["rule"], "cost": cost}


def _free_state(net, task, strain_reference: str, x0=None):
    from ..network.equilibrium import relax

    return relax(
        net,
        pinned=task.pinned,
        clamped=task.source_clamps(net, strain_reference),
        x0=x0,
        ramp=1 if x0 is not None else 4,
    )


def fields_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Free states (positions) of the exported trials, and of their trajectory frames."""
    from ..network.equilibrium import EquilibriumError

    history = ctx.history(params["group"])
    ref = scene.learning.strain_reference
    arrays: dict[str, np.ndarray] = {}
    meta: dict[str, Any] = {"trials": [], "failed": []}
    for k in params["trials"]:
        task = task_example(history.tasks[k])
        for stage, net in (("initial", history.initial[k]), ("final", history.final[k])):
            try:
                eq = _free_state(net, task, ref)
            except EquilibriumError as err:
                meta["failed"].append(f"trial {k} {stage}: {err.reason}")
                continue
            p = f"t{k}/{stage}/"
            arrays.update(
                {
                    p + "positions": net.positions,
                    p + "springs": net.springs,
                    p + "stiffness": net.stiffness,
                    p + "rest_length": net.rest_length,
                    p + "x": eq.positions,
                }
            )
        arrays[f"t{k}/sources"] = task.sources
        arrays[f"t{k}/targets"] = task.targets
        meta["trials"].append(k)
        path = frames_file(ctx.directory, f"train/{params['group']}/trial{k}")
        if params["series"] and path.exists():
            frames = _load_frames(path)
            frames.setdefault(0, (history.initial[k].rest_length, history.initial[k].stiffness))
            steps, xs, rest, stiff = [], [], [], []
            x0 = None
            base = history.initial[k]
            for s in sorted(frames):
                net = base.with_rest_length(frames[s][0]).with_stiffness(frames[s][1])
                try:
                    eq = _free_state(net, task, ref, x0=x0)
                except EquilibriumError as err:
                    meta["failed"].append(f"trial {k} frame {s}: {err.reason}")
                    break
                x0 = eq.positions
                steps.append(s)
                xs.append(eq.positions)
                rest.append(frames[s][0])
                stiff.append(frames[s][1])
            if steps:
                arrays[f"t{k}/series/steps"] = np.array(steps)
                arrays[f"t{k}/series/x"] = np.array(xs)
                arrays[f"t{k}/series/rest_length"] = np.array(rest)
                arrays[f"t{k}/series/stiffness"] = np.array(stiff)
    return arrays, meta
