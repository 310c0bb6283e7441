"""The first relax of a new network (orderings, caches and band layouts built cold) against
a second relax of the same network, and optionally against another checkout, one run.

Problems, on a triangular lattice of ~N nodes with 10 % position noise, stress-free, k = 1:

* ``pins``: the spring nearest the centre strained to ``S`` by moving its two nodes apart
  and pinning them (``bench_jaxmd.py``'s problem);
* ``clamp``: the spring in the middle of the list clamped at 1.05 of its rest length,
  default pins;
* ``prestressed``: as ``clamp``, but the noise moves the nodes after the rest lengths are
  set (a prestressed network: ~8 Newton iterations where the others take 3-5).

Every size draws ``--seeds`` networks; each is relaxed once new ("first") and once more
("again"). Printed: the minimum and median over the seeds, in ms. ``--against DIR`` runs the
same script with ``PYTHONPATH=DIR`` (an older checkout's package folder's parent) in
alternating rounds, so that the shared machine's load falls alike on both.

    python benchmarks/bench_first_relax.py --sizes 256,1024,4096
    python benchmarks/bench_first_relax.py --against /tmp/old_8d1dbfb
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", default="256,1024,4096")
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--rounds", type=int, default=3, help="alternating rounds with --against")
    p.add_argument("--against", default="", help="folder holding another continuum_vs_network")
    p.add_argument("--json", action="store_true", help=argparse.SUPPRESS)
    return p.parse_args()


def measure(sizes: list[int], seeds: int) -> dict[str, list[float]]:
    """``{"problem N": [first min, first median, again min, again median]}`` in ms."""
    import numpy as np

    import continuum_vs_network as cvn

    sys.path.insert(0, str(pathlib.Path(__file__).parents[1] / "tests"))
    from pulled_lattices import pulled_apart  # bench_jaxmd's problem

    def pins(n_nodes: int, seed: int, strain: float = 0.05):
        side = round(float(np.sqrt(n_nodes)))
        net, pinned, x0 = pulled_apart(side, strain, seed)
        return net, {"pinned": pinned, "x0": x0}

    def clamp(n_nodes: int, seed: int):
        side = round(float(np.sqrt(n_nodes)))
        net = cvn.triangular_lattice(side, side, noise=0.1, rng=np.random.default_rng(seed))
        mid = net.n_springs // 2
        return net, {"clamped": {mid: 1.05 * float(net.rest_length[mid])}}

    def prestressed(n_nodes: int, seed: int):
        side = round(float(np.sqrt(n_nodes)))
        net = cvn.triangular_lattice(side, side)
        noise = np.random.default_rng(seed).normal(size=net.positions.shape)
        net = net.with_positions(net.positions + 0.1 * np.mean(net.rest_length) * noise)
        mid = net.n_springs // 2
        return net, {"clamped": {mid: 1.05 * float(net.rest_length[mid])}}

    out = {}
    for name, make in (("pins", pins), ("clamp", clamp), ("prestressed", prestressed)):
        for n in sizes:
            net, kw = make(n, 10_000)
            cvn.relax(net, **kw)  # imports and process-wide caches warm
            first, again = [], []
            for seed in range(seeds):
                net, kw = make(n, seed)
                t0 = time.perf_counter()
                cvn.relax(net, **kw)
                first.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                cvn.relax(net, **kw)
                again.append(time.perf_counter() - t0)
            ms = [1e3 * float(f(v)) for v in (first, again) for f in (np.min, np.median)]
            out[f"{name} {n}"] = ms
    return out


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.json:
        print(json.dumps(measure(sizes, args.seeds)))
        return
    here, there = [], []
    for _ in range(args.rounds if args.against else 1):
        here.append(measure(sizes, args.seeds))
        if args.against:
            env = dict(os.environ, PYTHONPATH=os.path.abspath(args.against))
            cmd = [sys.executable, __file__, "--json", "--sizes", args.sizes]
            cmd += ["--seeds", str(args.seeds)]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            there.append(json.loads(out.stdout.splitlines()[-1]))
    print(f"first relax of a new network and again, ms (min / median over {args.seeds} seeds; "
          f"best round of {len(here)})")  # fmt: skip
    head = f"{'problem N':>16} {'first':>14} {'again':>14}"
    print(head + (f" {'first there':>14} {'again there':>14}" if there else ""))
    for key in here[0]:
        best = min((r[key] for r in here), key=lambda v: v[0])
        row = f"{key:>16} {best[0]:6.1f} /{best[1]:6.1f} {best[2]:6.1f} /{best[3]:6.1f}"
        if there:
            b = min((r[key] for r in there), key=lambda v: v[0])
            row += f" {b[0]:6.1f} /{b[1]:6.1f} {b[2]:6.1f} /{b[3]:6.1f}"
        print(row)


if __name__ == "__main__":
    main()
