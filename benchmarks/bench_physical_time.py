"""Cost of learning in physical time: the viscous step with and without a predictor.

GCL in twin form (a free and a nudged copy, ``learn_in_time``) at the ratio rho = alpha k
tau = 1e4 on the ``n x n`` lattice of the ``physical_time`` scene (first task draw, drag
c = 1, tau from ``network_relaxation_time``), run twice in one process: with the linear
predictor ``2 x - x_previous`` as each step's first Newton iterate (what the package does)
and with the previous state (the predictor switched off by a patch of the copies' step).
Prints the Newton iterations, the seconds (process CPU time: less sensitive to a shared
machine than wall time) and their ratios, and the largest difference of the recorded
errors (the converged steps are the same to the tolerance).

    python benchmarks/bench_physical_time.py            # n = 32 (N = 1024)
    python benchmarks/bench_physical_time.py --n 64     # N = 4096 (about a minute)
"""

from __future__ import annotations

import argparse
import os
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", type=int, default=32, help="lattice side (N = n^2 nodes)")
    p.add_argument("--ratio", type=float, default=1e4, help="rho = alpha k tau")
    return p.parse_args()


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import numpy as np

    from continuum_vs_network.learning import time_media
    from continuum_vs_network.learning.physical_time import (
        learn_in_time,
        network_relaxation_time,
    )
    from continuum_vs_network.learning.rules import CoupledLearning
    from continuum_vs_network.network.stepper import Stepper
    from continuum_vs_network.network.viscous import Viscosity
    from continuum_vs_network.scenes.schema.builtin import load_scene
    from continuum_vs_network.scenes.units_time import _lattice_task

    scene = load_scene("physical_time")
    net, task = _lattice_task(scene, args.n)
    vis = Viscosity(drag=1.0)
    tau = network_relaxation_time(net, task, vis)
    alpha = args.ratio / tau
    rule = CoupledLearning(
        alpha, 0.1, strain_reference="initial", learn_sources=False, learn_targets=False
    )
    dt = min(tau / 10, 1 / (5 * alpha))
    duration = max(5 / alpha, 0.05 * tau)
    count = {"iterations": 0}
    step = Stepper.step

    def counted(self, *a, **k):
        before = self.newton_iterations
        out = step(self, *a, **k)
        count["iterations"] += self.newton_iterations - before
        return out

    Stepper.step = counted
    original = time_media._Copy.step

    def no_predictor(self, net_, held, arm=None):
        self.previous = None
        return original(self, net_, held, arm)

    results = {}
    for label, patch in (("predictor", original), ("previous state", no_predictor)):
        time_media._Copy.step = patch
        count["iterations"] = 0
        t0 = time.process_time()
        h = learn_in_time(
            net, task, rule, viscosity=vis, duration=duration, dt=dt, n_outputs=300, form="twin"
        )
        results[label] = (time.process_time() - t0, count["iterations"], h.error / h.error[0])
    time_media._Copy.step = original
    Stepper.step = step
    (s1, i1, e1), (s0, i0, e0) = results["predictor"], results["previous state"]
    steps = round(duration / dt)
    print(f"N = {net.n_nodes}, rho = {args.ratio:g}, tau = {tau:.4g}, {steps} steps x 2 copies")
    print(f"first iterate = previous state: {i0} Newton iterations, {s0:.2f} s of CPU")
    print(f"first iterate = predictor:      {i1} Newton iterations, {s1:.2f} s of CPU")
    print(f"ratio previous / predictor: iterations {i0 / i1:.2f}, time {s0 / s1:.2f}")
    print(f"largest |difference| of the relative errors: {np.max(np.abs(e1 - e0)):.2e}")


if __name__ == "__main__":
    main()
