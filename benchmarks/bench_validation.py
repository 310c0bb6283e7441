"""Cost of the argument checks at the entry of ``relax`` against the solve they guard.

Run: ``python benchmarks/bench_validation.py``. Prints, for the paper's network (N = 10)
and a 100 x 100 lattice, the best-of-five time of the checks ``relax`` runs before it
solves (scalar options, the network, pins and clamps, lone nodes) and of a whole ``relax``
call, measured side by side, and their ratio.
"""

from __future__ import annotations

import time

import numpy as np

import continuum_vs_network as cvn
from continuum_vs_network.network.arguments import (
    clamp_arrays,
    lone_nodes,
    pin_mask_or_indices,
    relax_arguments,
)
from continuum_vs_network.network.equilibrium import METHODS


def _best(fn, repeat: int, number: int) -> float:
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(number):
            fn()
        best = min(best, (time.perf_counter() - t) / number)
    return best


def main() -> None:
    cases = {
        "paper N=10": cvn.paper_network(np.random.default_rng(0)),
        "lattice 100x100": cvn.triangular_lattice(
            100, 100, noise=0.1, rng=np.random.default_rng(1)
        ),
    }
    print(f"{'network':16} {'checks (us)':>12} {'relax (ms)':>11} {'checks/relax':>13}")
    for label, net in cases.items():
        j = net.n_springs // 2
        clamped = {j: float(net.rest_length[j]) * 1.2}
        pinned = [0, net.n_nodes - 1]
        mask = np.zeros((net.n_nodes, 2), bool)
        mask[pinned] = True

        def checks(net=net, clamped=clamped, pinned=pinned, mask=mask) -> None:
            relax_arguments(net, methods=tuple(METHODS), method="newton", tol=1e-10,
                            clamp="exact", rod_stiffness=1e10, ramp=1, max_iter=None,
                            max_seconds=600.0)  # fmt: skip
            pin_mask_or_indices(net, pinned)
            clamp_arrays(net, clamped)
            lone_nodes(net, ~mask)

        def solve(net=net, clamped=clamped, pinned=pinned) -> None:
            cvn.relax(net, pinned=pinned, clamped=clamped)

        number = 20 if net.n_nodes > 1000 else 200
        t_check = _best(checks, 5, 200)
        t_relax = _best(solve, 5, number)
        print(f"{label:16} {t_check * 1e6:12.1f} {t_relax * 1e3:11.3f} {t_check / t_relax:13.4f}")


if __name__ == "__main__":
    main()
