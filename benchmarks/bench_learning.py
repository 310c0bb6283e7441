"""Seconds per learning step against one Hessian assembly + factorisation, same run.

Run: ``python benchmarks/bench_learning.py [--full]``. For noisy triangular lattices of
about 1024 and 10^4 nodes with a Stern task (10 sources, 3 targets, strains against the
initial rest lengths) it prints

* ``H+factor``: one assembly of the Lagrangian Hessian plus its sparse factorisation, the
  way ``relax`` builds them (median of repeats),
* the median wall-clock seconds of one learning step for coupled learning with reused
  factorisations (``GCL``), with every state found by ``relax`` (``GCL relax``), for
  prospective configuration (``GPC``) and the exact gradient (``exact``), after warm-up
  steps, and each one's ratio to ``H+factor``,
* the time of 10^4 GCL steps at N = 1024, extrapolated from the measured mean step
  (measured in full with ``--full``).

Timings depend on the machine and its load (other processes on a shared machine slow
both columns); the ratios, measured side by side, are what to compare.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    ProspectiveConfiguration,
    Solver,
    Tracker,
    stern_task,
)
from continuum_vs_network.network.constraints import Problem
from continuum_vs_network.network.lagrangian import Frame, lagrangian_hessian
from continuum_vs_network.scenes.stern import stern_network


def _hessian_factor(net, task, x, repeat: int) -> float:
    problem = Problem.build(net, pinned=task.pinned, clamped=task.source_clamps(net, "initial"))
    frame = Frame(net, problem.free)
    mu = np.zeros(problem.n_clamps)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        W = lagrangian_hessian(problem, x, mu, frame=frame)
        factor = frame.factor(W)
        times.append(time.perf_counter() - t)
        assert factor is not None
    return float(np.median(times))


def _steps(net, task, rule, warmup: int, steps: int) -> tuple[float, float, object]:
    tracker = Tracker(rule.solver)
    step = rule.update(net, task, tracker=tracker)
    for _ in range(warmup):
        net = step.apply(net)
        step = rule.update(net, task, warm=step.warm, tracker=tracker)
    times = []
    for _ in range(steps):
        net = step.apply(net)
        t = time.perf_counter()
        step = rule.update(net, task, warm=step.warm, tracker=tracker)
        times.append(time.perf_counter() - t)
    return float(np.median(times)), float(np.mean(times)), tracker.stats


def main() -> None:
    full = "--full" in sys.argv
    common = {"strain_reference": "initial", "min_rest_length": 1e-3}
    rules = {
        "GCL": CoupledLearning(0.05, 0.1, **common),
        "GCL relax": CoupledLearning(0.05, 0.1, solver=Solver(reuse=False), **common),
        "GPC": ProspectiveConfiguration(0.05, **common),
        "exact": ExactGradient(0.05, cost="length", **common),
    }
    print("    N  springs  H+factor s  rule        s/step    ratio  factorisations/step")
    gcl_mean_1024 = None
    for n, warmup, steps, repeat in ((1024, 10, 40, 9), (10_000, 3, 8, 3)):
        rng = np.random.default_rng(0)
        net = stern_network(n, rng)
        task = stern_task(net, 10, 3, rng, candidates=np.ones(net.n_springs, dtype=bool))
        ref = _hessian_factor(net, task, net.positions, repeat)
        for name, rule in rules.items():
            if name == "GCL relax" and n > 2000:
                steps_here = 3
            else:
                steps_here = steps
            median, mean, stats = _steps(net, task, rule, warmup, steps_here)
            fact = stats.factorisations / (warmup + steps_here + 1)
            print(
                f"{net.n_nodes:5d}  {net.n_springs:7d}  {ref:10.4f}  {name:10s} "
                f"{median:8.4f}  {median / ref:7.2f}  {fact:10.2f}"
            )
            if name == "GCL" and n == 1024:
                gcl_mean_1024 = mean
    print()
    print(f"10^4 GCL steps at N=1024, extrapolated from the mean step: {1e4 * gcl_mean_1024:.0f} s")
    if full:
        rng = np.random.default_rng(0)
        net = stern_network(1024, rng)
        task = stern_task(net, 10, 3, rng, candidates=np.ones(net.n_springs, dtype=bool))
        rule = rules["GCL"]
        tracker = Tracker(rule.solver)
        t = time.perf_counter()
        step = rule.update(net, task, tracker=tracker)
        for _ in range(9_999):
            net = step.apply(net)
            step = rule.update(net, task, warm=step.warm, tracker=tracker)
        print(
            f"10^4 GCL steps at N=1024, measured: {time.perf_counter() - t:.0f} s "
            f"({tracker.stats.factorisations} factorisations)"
        )


if __name__ == "__main__":
    main()
