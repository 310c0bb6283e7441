"""Build times of the network builders, and dense against sparse rigidity tests.

Run: ``python benchmarks/bench_builders.py``. Prints wall-clock seconds (best of three) and,
for the rigidity test, the ratio dense / sparse measured side by side on the same network.
Timings depend on the machine and its load; the ratios are what to compare.
"""

from __future__ import annotations

import time

import numpy as np

from continuum_vs_network.network.builders import diluted_lattice, triangular_lattice
from continuum_vs_network.network.jammed import jammed_network
from continuum_vs_network.network.rigidity import is_rigid


def _best(fn, repeat: int = 3) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main() -> None:
    print("builder                       nodes  springs  seconds")
    for n in (512, 1024):
        t, net = _best(lambda n=n: jammed_network(n, np.random.default_rng(0)))
        print(f"jammed_network({n:5d})        {net.n_nodes:5d}  {net.n_springs:7d}  {t:7.3f}")
    for side in (23, 32, 45):
        t, net = _best(lambda s=side: diluted_lattice(s, s, 0.25, np.random.default_rng(0)))
        name = f"diluted_lattice({side}x{side}, 0.25)"
        print(f"{name:29s} {net.n_nodes:5d}  {net.n_springs:7d}  {t:7.3f}")
    print()
    print("is_rigid          coords  dense s  sparse s  dense/sparse")
    for side in (16, 23, 32):
        net = triangular_lattice(side, side)
        td, rd = _best(lambda net=net: is_rigid(net, method="dense"), repeat=1)
        ts, rs = _best(lambda net=net: is_rigid(net, method="sparse"))
        assert rd == rs
        name = f"lattice {side}x{side}"
        print(f"{name:17s} {2 * net.n_nodes:6d}  {td:7.3f}  {ts:8.4f}  {td / ts:12.1f}")


if __name__ == "__main__":
    main()
