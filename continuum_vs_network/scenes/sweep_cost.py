"""What a sweep will compute, printed before it runs: grid size, trials, learning steps,
and an estimate of the compute and wall time from a few timed steps of its first point."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .grid import GridPoint
from .schema import Scene

__all__ = ["Cost", "estimate_cost"]


@dataclass(frozen=True)
class Cost:
    """What a sweep will compute (printed before it runs).

    Attributes
    ----------
    points, todo : int
        Grid points, and those not yet stored.
    trials : int
        Training trials of the points to do (every rule x solver x noise level x trial).
    steps : int
        Learning steps of those trials.
    seconds_per_step, seconds_per_trial : float or None
        Measured on the first point to do (its runs trained for 1 and 3 steps): the cost of
        a learning step and of a trial besides its steps (building the network and task, the
        first measurement). None when nothing is to do or the measurement failed.
    """

    points: int
    todo: int
    trials: int
    steps: int
    seconds_per_step: float | None
    seconds_per_trial: float | None

    def text(self, workers: int) -> str:
        """One line: grid size, work, estimated compute and (``workers > 0``) wall time."""
        line = (
            f"{self.points} grid point(s), {self.todo} to compute: {self.trials} training "
            f"trial(s), {self.steps} learning steps"
        )
        if self.seconds_per_step is not None and self.todo:
            total = self.seconds_per_step * self.steps + self.seconds_per_trial * self.trials
            line += f"; estimated {total:.0f} s of compute"
            if workers > 0:
                wall = total / min(workers, self.todo)
                line += f", ~{wall:.0f} s on {workers} worker(s)"
        return line


def _steps(scene: Scene) -> int:
    """Learning steps of one trial (an allostery run: its rule's steps, the longest)."""
    return scene.allostery.steps if scene.kind == "allostery" else scene.learning.steps


def _runs(scene: Scene) -> int:
    if scene.kind == "allostery":
        from .units_allostery import runs

        a = scene.allostery
        return len(runs(scene)) * a.draws * len(a.n_nodes) * len(a.tasks) * len(a.dofs)
    from .units_learning import run_names

    L = scene.learning
    solvers = len(scene.solver.methods) if scene.solver is not None else 1
    return solvers * len(run_names(scene)) * len(L.noise) * L.trials


def estimate_cost(points: Sequence[GridPoint], todo: Sequence[GridPoint]) -> Cost:
    """Count the work of ``todo`` and time a few learning steps of its first point."""
    trials = sum(_runs(p.scene) for p in todo)
    steps = sum(_runs(p.scene) * _steps(p.scene) for p in todo)
    timing = _calibrate(todo[0].scene) if todo and todo[0].scene.kind == "learning" else None
    if timing is None:
        return Cost(len(points), len(todo), trials, steps, None, None)
    return Cost(len(points), len(todo), trials, steps, *timing)


def _calibrate(scene: Scene) -> tuple[float, float] | None:
    """(seconds per learning step, seconds per trial besides its steps) of ``scene``'s runs:
    trial 0 of every run trained for 1 and for 3 steps (after a warm-up), averaged over
    the runs."""
    from ..learning.train import train
    from .units_learning import build_rules, builders, run_names

    solvers = scene.solver.methods if scene.solver is not None else ("newton",)
    per_step, per_trial = [], []
    try:
        for solver in solvers:
            rules = build_rules(scene, solver)
            for name in run_names(scene):
                t = []
                for steps in (1, 1, 3):  # the first call warms up (imports, caches)
                    net, task = builders(scene)
                    t0 = time.perf_counter()
                    train(net, task, rules[name], steps, seeds=(scene.seed,), progress=False)
                    t.append(time.perf_counter() - t0)
                per_step.append(max(t[2] - t[1], 0.0) / 2)
                per_trial.append(max(t[1] - per_step[-1], 0.0))
    except Exception:  # an estimate only: the real run reports failures
        return None
    return float(np.mean(per_step)), float(np.mean(per_trial))
