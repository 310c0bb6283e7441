"""Units that read a learning scene's trained histories: coupling, sweeps, gradient, fields.

* ``coupling/<solver>/<rule>/noise<i>``: target strains of every trained network with the
  sources on, off and over a source sweep, and of the initial network with the sources off
  (:mod:`~continuum_vs_network.learning.coupling`);
* ``sweeps/<solver>/<rule>``: source sweeps of the trained networks (Fig. 5, appendix);
* ``gradient/<rule>``: cosine between each rule's step and the exact gradient's;
* ``fields/<solver>/<rule>``: free states of the exported trials' initial and final
  networks and of their trajectory frames.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .results.learning import CouplingResult, FieldsResult, GradientResult, SweepsResult
from .schema import Scene
from .units import UnitContext
from .units_learning_build import build_rules, task_example
from .units_learning_train import _load_frames, frames_file

__all__ = ["coupling_unit", "feasibility_unit", "fields_unit", "gradient_unit", "sweeps_unit"]


def coupling_unit(scene: Scene, params: dict, ctx: UnitContext) -> CouplingResult:
    """Coupling of every trial's trained network (sources on / off, a source sweep)."""
    from ..learning.coupling import SCALES, measure_coupling
    from ..network.equilibrium import EquilibriumError
    from .replication import exact_solver

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
    return CouplingResult(
        scales=np.array(SCALES),
        sweep=sweep,
        initial_off=initial_off,
        initial_on=initial_on,
        desired=desired,
        share=share,
        verdicts=verdicts,
        failed=failed,
    )


def sweeps_unit(scene: Scene, params: dict, ctx: UnitContext) -> SweepsResult:
    """Source sweeps of every trial's final network (exact equilibria)."""
    from .replication import exact_solver, sweeps

    history = ctx.history(params["group"])
    strains, target = sweeps(
        history, span=params["sweep_span"], points=params["sweep_points"], solver=exact_solver()
    )
    desired = np.array([t.target_strain[0] for t in history.tasks])
    source = np.array([t.source_strain[0] for t in history.tasks])
    return SweepsResult(
        source_strain=strains,
        target_strain=target,
        desired=desired,
        task_source=source,
        failed=int(np.sum(np.isnan(target).all(axis=1))),
    )


def gradient_unit(scene: Scene, params: dict, ctx: UnitContext) -> GradientResult:
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
    return GradientResult(cosine=out, rule=params["rule"], cost=cost)


def _free_state(net, task, strain_reference: str, x0=None):
    from ..network.equilibrium import relax

    return relax(
        net,
        pinned=task.pinned,
        clamped=task.source_clamps(net, strain_reference),
        x0=x0,
        ramp=1 if x0 is not None else 4,
    )


def fields_unit(scene: Scene, params: dict, ctx: UnitContext) -> FieldsResult:
    """Free states (positions) of the exported trials, and of their trajectory frames."""
    from ..network.equilibrium import EquilibriumError

    history = ctx.history(params["group"])
    ref = history.strain_reference  # the run's own convention (paper_setting: per rule)
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
    return FieldsResult(trials=meta["trials"], failed=meta["failed"], fields=arrays)


def feasibility_unit(scene: Scene, params: dict, ctx: UnitContext):
    """Per draw of the paper's task (the untrained networks of run ``group``): linear
    response, nonlinearity, the exact optimum, self-stress share and collapse
    (:func:`~continuum_vs_network.scenes.paper_setting.draw_feasibility`)."""
    from .paper_setting import draw_feasibility

    history = ctx.history(params["group"])
    rows = [draw_feasibility(history.initial[i], history.tasks[i]) for i in range(history.trials)]
    keys = sorted(rows[0]) if rows else []
    return {k: np.array([r[k] for r in rows]) for k in keys}, {"keys": keys}
