"""Coupled learning at scale: time, peak memory and C/C0 per step.

A noisy triangular lattice of ``--nodes`` nodes (default 1e6), 10 sources and 3 targets
(``stern_task``), bulk learning (sources and targets frozen: ``stern_rules``), coupled
learning (GCL) with the package's default solver (the tracker reusing factorisations).
Prints after every step the wall time, the process's peak resident memory and, at the
end, C/C0 per step from the history.

    python benchmarks/bench_million.py --nodes 10000 --steps 20
    python benchmarks/bench_million.py                    # 1e6 nodes (target: C/C0 <=
                                                          # 1e-3 in <= 15 min, <= 12 GB)
    python benchmarks/bench_million.py --side /work/side/pardiso   # pypardiso from a folder
                            # (MKL's library from PYPARDISO_MKL_RT=<path>/libmkl_rt.so.3
                            # when MKL is not pip-installed in the environment)

``--sparse-solver``: the factorisation (:func:`~continuum_vs_network.network.kkt.
set_sparse_solver`); ``auto`` is PARDISO when ``pypardiso`` imports.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--nodes", type=int, default=1_000_000)
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--alpha", type=float, default=0.5)
    p.add_argument("--eta", type=float, default=0.1)
    p.add_argument("--sparse-solver", default="auto", help="auto, pardiso or superlu")
    p.add_argument("--side", action="append", default=[], help="folder with optional packages")
    return p.parse_args()


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024**2  # kB on Linux


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "2")
    os.environ.setdefault("MKL_NUM_THREADS", "2")
    sys.path.extend(args.side)
    import numpy as np

    from continuum_vs_network.learning.stern import stern_network, stern_rules
    from continuum_vs_network.learning.tasks import stern_task
    from continuum_vs_network.learning.train import train
    from continuum_vs_network.network.kkt import set_sparse_solver, sparse_solver

    set_sparse_solver(args.sparse_solver)

    t0 = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    net = stern_network(args.nodes, rng)
    task = stern_task(net, 10, 3, rng, candidates=np.ones(net.n_springs, dtype=bool))
    rule = stern_rules(alpha=args.alpha, eta=args.eta)["GCL"]
    print(
        f"# {net.n_nodes} nodes, {net.n_springs} springs; built in "
        f"{time.perf_counter() - t0:.1f} s, peak {_peak_gb():.2f} GB; sparse solver "
        f"{sparse_solver()}"
    )
    start = time.perf_counter()

    def report(trial: int, step: int, _net) -> None:
        print(
            f"step {step:4d}  {time.perf_counter() - start:8.1f} s  peak {_peak_gb():6.2f} GB",
            flush=True,
        )

    history = train(
        net, task, rule, args.steps, seeds=(args.seed,), progress=False, callback=report
    )
    err = np.asarray(history.error_initial).reshape(-1)
    print("# C/C0 per step (strains against the initial rest lengths)")
    for t, e in enumerate(err):
        print(f"step {t:4d}  C/C0 {e / err[0]:.3e}")
    below = np.flatnonzero(err / err[0] <= 1e-3)
    reached = f"step {below[0]}" if below.size else "not reached"
    print(
        f"# total {time.perf_counter() - start:.1f} s, peak {_peak_gb():.2f} GB, "
        f"C/C0 <= 1e-3: {reached}"
    )


if __name__ == "__main__":
    main()
