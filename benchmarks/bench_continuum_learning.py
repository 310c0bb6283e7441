"""Cost of learning in the continuum: one step against one assembly + factorisation.

Run: ``python benchmarks/bench_continuum_learning.py [--quick]``. Prints two tables:

1. for P1 and P2 bodies on a triangular lattice's triangles (refined), the wall time of one
   assembly of the stiffness plus one factorisation of its KKT system (``t_af``: the
   stiffness with the fixed DOFs removed, sparse LU, plus the solves for the
   source/target functionals that the Schur complement needs), and of one learning step
   of coupled learning (eigenstrain, modulus) and of the exact gradient, each as a ratio
   ``step / t_af`` (the issue's budget: <= 2). Eigenstrain learning never changes the
   stiffness, so its steps reuse one factorisation for the whole run; modulus learning
   refactorises once per step and reuses it for the free and the nudged state.
2. a continuum of about 1e5 DOFs trained by coupled learning (eigenstrain) to
   ``C / C0 <= 1e-3`` on a Stern-scale task (10 sources, 3 targets, bulk learning): steps,
   wall time, final ``C / C0``.

Timings depend on the machine and its load; compare the ratios within one run (best of
``repeat`` runs each).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import continuum_vs_network as cvn
from continuum_vs_network.continuum.learnable import learnable_body
from continuum_vs_network.continuum.learning_states import _System
from continuum_vs_network.continuum.material_task import MaterialTask
from continuum_vs_network.continuum.materials import lattice_lame
from continuum_vs_network.continuum.mesh import network_mesh


def _setup(n: int, refine: int, order: int, seed: int = 0):
    net = cvn.triangular_lattice(n, n)
    rng = np.random.default_rng(seed)
    # springs between interior (6-fold) nodes: all strain-tunable in a full lattice, and
    # naming them skips the network's dense rigidity analysis (minutes at 3000 nodes)
    degree = np.bincount(net.springs.ravel(), minlength=net.n_nodes)
    inner = np.flatnonzero(np.all(degree[net.springs] == 6, axis=1))
    task = cvn.stern_task(net, 10, 3, rng, candidates=inner, source_std=0.01, target_std=0.01)
    body = learnable_body(network_mesh(net, refine=refine), lattice_lame(1.0), order=order)
    return body, MaterialTask.from_network(net, task, body)


def _best(fn, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def step_costs(n: int, refine: int, order: int, repeat: int) -> dict[str, float]:
    body, task = _setup(n, refine, order)

    def assemble_factorise():
        body.stiffness()
        _System(body, task, None)

    t_af = _best(assemble_factorise, repeat)
    out = {"dofs": body.n_dofs, "t_af": t_af}
    rules = {
        "gcl eigenstrain": cvn.CoupledLearning(0.5, 0.1, dof="eigenstrain"),
        "gcl modulus": cvn.CoupledLearning(0.5, 0.1, dof="modulus"),
        "exact eigenstrain": cvn.ExactGradient(0.5, dof="eigenstrain"),
    }
    for name, rule in rules.items():
        cur = body.with_eigenstrain(0.0)  # fresh cache
        step = rule.update(cur, task)  # first step: factorises
        cur = step.apply(cur)

        def one_step(rule=rule):
            nonlocal cur
            cur = rule.update(cur, task).apply(cur)

        out[name] = _best(one_step, repeat)
    return out


def train_large(n: int, refine: int, steps: int) -> dict[str, float]:
    """Build (mesh, element operators, task) and train; seconds of each part."""
    t0 = time.perf_counter()
    body, task = _setup(n, refine, 1)
    build = time.perf_counter() - t0
    rule = cvn.CoupledLearning(0.5, 0.1)
    t0 = time.perf_counter()
    h = cvn.train(body, task, rule, steps, progress=False)
    seconds = time.perf_counter() - t0
    ratio = h.error_initial[0] / h.error_initial[0, 0]
    hit = np.flatnonzero(ratio <= 1e-3)
    k = int(hit[0]) if hit.size else -1
    return {
        "dofs": body.n_dofs,
        "build": build,
        "seconds": seconds,
        "final": float(ratio[-1]),
        "steps_to": k,
        "seconds_to": float(h.seconds[0, k]) if k >= 0 else float("nan"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller bodies, one repeat")
    args = parser.parse_args()
    repeat = 1 if args.quick else 3
    cases = [(16, 1, 1), (16, 0, 2)] if args.quick else [(24, 2, 1), (32, 3, 1), (32, 2, 2)]
    print("1. one learning step against one assembly + KKT factorisation (t_af)")
    print("order   dofs     t_af s    gcl eigenstrain  gcl modulus  exact eigenstrain  (ratios)")
    for n, refine, order in cases:
        c = step_costs(n, refine, order, repeat)
        print(
            f"P{order}  {c['dofs']:7d}  {c['t_af']:8.4f}   "
            f"{c['gcl eigenstrain'] / c['t_af']:15.3f}  {c['gcl modulus'] / c['t_af']:11.3f}  "
            f"{c['exact eigenstrain'] / c['t_af']:17.3f}"
        )
    print()
    n, refine, steps = (24, 2, 25) if args.quick else (56, 2, 25)
    r = train_large(n, refine, steps)
    print(f"2. coupled learning (eigenstrain, bulk) of a P1 continuum with {r['dofs']} DOFs")
    print(
        f"   build {r['build']:.1f} s; C/C0 <= 1e-3 after {r['steps_to']} steps and "
        f"{r['seconds_to']:.1f} s of training; {steps} steps in {r['seconds']:.1f} s, final "
        f"C/C0 {r['final']:.2e}"
    )


if __name__ == "__main__":
    main()
