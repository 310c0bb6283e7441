"""Learning at scale on a task that is learned genuinely: time, steps, peak memory, reach.

Two measurements:

1. ``--nodes N`` (default 1e5): a jammed packing of N discs (``jammed_network``, k = 1/L,
   stress-free) learns Rocks' 1 -> 1 allosteric task (``allostery_task``: one source
   strained 0.05, one target ``--distance`` box sizes away asked for +0.3 of it) with its
   rest example (``anchored``) by coupled learning of the stiffnesses
   (``CoupledLearning(dof="stiffness")``, the adaptive rate with step ``--step``), until
   ``C/C0 <= --stop`` or ``--steps`` steps. Learning k cannot prestress a stress-free
   network, so a met task is a coupled one; the source share of the trained network
   (``measure_coupling``) is printed to show it. Printed per step: wall time, C/C0 (the
   free states the rule solves anyway, before each update) and the process's peak resident
   memory; at the end the learned response's reach: the distances from the source within
   which half, 90 % and 99 % of the summed change of the springs' strain response to the
   source (trained against untrained) lie, against the target's distance.
2. ``--lattice-nodes M`` (e.g. 1e6; 0 skips it): the per-step cost of the same rule on a
   triangular lattice of M nodes (k = 1, stress-free) with a 1 -> 1 task, ``--lattice-steps``
   steps: seconds per step and peak memory (a jammed packing of 1e6 discs is not built
   here: its minimisation alone would take hours on 2 cores).

    python benchmarks/bench_million.py                          # 1e5 nodes
    python benchmarks/bench_million.py --nodes 10000 --steps 200
    python benchmarks/bench_million.py --nodes 0 --lattice-nodes 1000000 --lattice-steps 3

Timings depend on the machine and its load; peak memory is the process's (``ru_maxrss``).
"""

from __future__ import annotations

import argparse
import os
import resource
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--nodes", type=int, default=100_000, help="discs of the packing (0: skip)")
    p.add_argument("--steps", type=int, default=300, help="most learning steps (300)")
    p.add_argument("--stop", type=float, default=1e-3, help="stop at C/C0 <= this (1e-3)")
    p.add_argument("--step", type=float, default=0.3, help="adaptive rate's step (0.3)")
    p.add_argument("--distance", type=float, default=0.1, help="source-target distance (0.1)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--lattice-nodes", type=int, default=0, help="lattice for the step cost")
    p.add_argument("--lattice-steps", type=int, default=3)
    return p.parse_args()


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # kB on Linux


def _learn(net, tasks, rule, steps: int, stop: float, log: bool = True):
    """Bare learning loop: the final network, C/C0 and cumulative seconds per step, and the
    first example's free positions before the first and after the last step."""
    import numpy as np

    from continuum_vs_network.learning import Tracker

    tracker = Tracker(rule.solver)
    cur, warm, ratios, seconds, states = net, None, [], [], []
    c0 = None
    t0 = time.perf_counter()
    for t in range(steps + 1):
        step = rule.update(cur, tasks, warm=warm, tracker=tracker)
        c = tasks.error(cur, [e.free.positions for e in step.examples])
        c0 = c if c0 is None else c0
        ratios.append(c / c0)
        if t == 0:
            states.append(step.examples[0].free.positions)
        seconds.append(time.perf_counter() - t0)
        if log:
            print(
                f"step {t:4d}  {seconds[-1]:8.1f} s  C/C0 {ratios[-1]:.3e}  "
                f"peak {_peak_gb():6.2f} GB",
                flush=True,
            )
        if ratios[-1] <= stop or t == steps:
            states.append(step.examples[0].free.positions)
            break
        cur = step.apply(cur)
        warm = step.warm
    return cur, np.array(ratios), np.array(seconds), states


def _jammed(args) -> None:
    import numpy as np

    from continuum_vs_network.learning import CoupledLearning, anchored, measure_coupling
    from continuum_vs_network.learning.allostery import allostery_task, spring_distances
    from continuum_vs_network.learning.rates import Adaptive
    from continuum_vs_network.network.jammed import jammed_network

    t0 = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    net = jammed_network(args.nodes, rng)
    built = time.perf_counter() - t0
    task = allostery_task(net, rng, ratio=0.3, source_strain=0.05, distance=args.distance)
    tasks = anchored(task, net)
    dist = spring_distances(net, task.sources)
    print(
        f"# jammed: {net.n_nodes} nodes, {net.n_springs} springs, built in {built:.1f} s, "
        f"peak {_peak_gb():.2f} GB; target {dist[task.targets][0]:.3f} box sizes "
        f"from the source"
    )
    rule = CoupledLearning(dof="stiffness", rate=Adaptive(step=args.step))
    trained, ratios, seconds, states = _learn(net, tasks, rule, args.steps, args.stop)
    hit = np.flatnonzero(ratios <= args.stop)
    c = measure_coupling(net, trained, task)
    # the learned response: change of every spring's strain under the source, trained
    # against untrained (free states of the driven example)
    strain = [
        np.linalg.norm(np.diff(x[net.springs], axis=1)[:, 0], axis=1) / net.rest_length
        for x in states
    ]
    change = np.abs(strain[1] - strain[0])
    order = np.argsort(dist)
    share = np.cumsum(change[order]) / change.sum()
    reach = [float(dist[order][np.searchsorted(share, q)]) for q in (0.5, 0.9, 0.99)]
    changed = np.abs(np.log(trained.stiffness / net.stiffness)) > np.log(1.1)
    print(
        f"# C/C0 <= {args.stop:g}: "
        + (f"step {hit[0]} at {seconds[hit[0]]:.1f} s" if hit.size else "not reached")
        + f"; final C/C0 {ratios[-1]:.3e}; source share {c.share:.3f} ({c.verdict}); "
        f"peak {_peak_gb():.2f} GB"
    )
    print(
        f"# reach: half, 90 % and 99 % of the summed change of the springs' strain response "
        f"to the source (trained against untrained) lie within {reach[0]:.3f}, "
        f"{reach[1]:.3f} and {reach[2]:.3f} box sizes of the source; target at "
        f"{dist[task.targets][0]:.3f}; {int(changed.sum())} of {net.n_springs} springs "
        "changed k by > 10 % (the adaptive rate moves every spring with a non-zero line)"
    )


def _lattice(args) -> None:
    import numpy as np

    from continuum_vs_network.learning import CoupledLearning, anchored
    from continuum_vs_network.learning.allostery import allostery_task
    from continuum_vs_network.learning.rates import Adaptive
    from continuum_vs_network.network.builders import triangular_lattice

    side = round(args.lattice_nodes**0.5)
    t0 = time.perf_counter()
    net = triangular_lattice(side, side)
    rng = np.random.default_rng(args.seed)
    task = allostery_task(net, rng, ratio=0.3, source_strain=0.05, distance=0.1)
    tasks = anchored(task, net)
    print(
        f"# lattice: {net.n_nodes} nodes, {net.n_springs} springs, built in "
        f"{time.perf_counter() - t0:.1f} s, peak {_peak_gb():.2f} GB"
    )
    rule = CoupledLearning(dof="stiffness", rate=Adaptive(step=args.step))
    _, _, seconds, _ = _learn(net, tasks, rule, args.lattice_steps, 0.0)
    per = np.diff(seconds)
    print(
        f"# lattice: first step (cold: orderings, factorisations) {seconds[0]:.1f} s, then "
        f"{np.median(per):.1f} s per step (median of {per.size}); peak {_peak_gb():.2f} GB"
    )


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    if args.nodes:
        _jammed(args)
    if args.lattice_nodes:
        _lattice(args)


if __name__ == "__main__":
    main()
