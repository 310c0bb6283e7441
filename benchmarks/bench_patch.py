"""Time to relax the paper's prestressed N = 10 patch (issue 10 target: <= 1 ms).

``cvn.relax`` at its defaults on ``paper_network(rng)`` (rest lengths U(0.5, 20), stiffness
U(0.5, 50): strongly prestressed) for ``--count`` seeds; each timed as the best of
``--repeats`` runs after a warm-up (caches, lazy imports). Prints the median time, the
median iterations and the time per iteration, and the same with explicit default pins
(the pinned problem solved directly, rigid motion not removed by the solver), side by side;
``fresh network`` times default pins on a new network object with slightly other stiffness
each run, so that nothing ``relax`` keeps per network (setup, checks) is reused; ``new
network`` builds the network anew each run (new arrays of the same topology: what is kept
per topology, such as the rank check, is shared by content), a user's first ``relax`` of
another patch; ``new topology`` relabels its nodes by a new random permutation each run,
so nothing kept per topology is reused either.

    python benchmarks/bench_patch.py
    python benchmarks/bench_patch.py --count 50 --repeats 20
    python benchmarks/bench_patch.py --against /path/to/other/checkout   # old vs new

``--against DIR`` also times the package found in ``DIR`` (another checkout, e.g. the
commit before a change) in a subprocess of the same run, in ``--rounds`` rounds
alternating with this one (a burst of load on the shared host then falls on both), and
prints each row's best time on either side and the median of the rounds' time ratios.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--count", type=int, default=20)
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--against", default=None, help="another checkout to time side by side")
    p.add_argument(
        "--rounds", type=int, default=3, help="with --against: alternating rounds (default 3)"
    )
    return p.parse_args()


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import numpy as np

    import continuum_vs_network as cvn
    from continuum_vs_network.network.builders import paper_network

    nets = [paper_network(np.random.default_rng(seed)) for seed in range(args.count)]

    def relabelled(net: cvn.SpringNetwork, rng: np.random.Generator) -> cvn.SpringNetwork:
        """The same patch, node ``j`` renamed ``p[j]`` for a random permutation ``p``."""
        p = rng.permutation(net.n_nodes)
        positions = np.empty_like(net.positions)
        positions[p] = net.positions
        return cvn.SpringNetwork(positions, p[net.springs], net.stiffness, net.rest_length)

    def measure(
        pinned: bool, fresh: bool = False, new: bool = False, relabel: bool = False
    ) -> tuple[float, float, float]:
        shuffle = np.random.default_rng(12345)
        times, iterations = [], []
        for seed, net in enumerate(nets):
            pins = cvn.default_pins(net) if pinned else None
            eq = cvn.relax(net, pinned=pins)  # warm-up
            best = np.inf
            for i in range(args.repeats):
                # fresh: a new network object with other stiffness bytes (k (1 + 1e-12 i)) each
                # run, so nothing kept per network or per stiffness is reused; new: the network
                # built anew (new arrays: nothing kept per topology either), a user's first relax
                one = net.with_stiffness(net.stiffness * (1 + 1e-12 * (i + 1))) if fresh else net
                if new:
                    one = paper_network(np.random.default_rng(seed))
                if relabel:
                    one = relabelled(net, shuffle)
                t0 = time.perf_counter()
                eq = cvn.relax(one, pinned=pins)
                best = min(best, time.perf_counter() - t0)
            times.append(best)
            iterations.append(eq.iterations)
        t, i = np.array(times), np.array(iterations)
        return 1e3 * float(np.median(t)), float(np.median(i)), 1e3 * float(np.median(t / i))

    cases = {  # each row's arguments of measure
        "default pins": {"pinned": False},
        "explicit pins": {"pinned": True},
        "fresh network": {"pinned": False, "fresh": True},
        "new network": {"pinned": False, "new": True},
        "new topology": {"pinned": False, "relabel": True},
    }
    names = tuple(cases)

    def measure_all() -> dict[str, tuple[float, float, float]]:
        return {name: measure(**kw) for name, kw in cases.items()}

    def there() -> dict[str, float]:
        """The rows' median ms of the package in ``--against`` (one round, a subprocess)."""
        env = dict(os.environ, PYTHONPATH=os.path.abspath(args.against))
        cmd = [sys.executable, __file__, "--count", str(args.count), "--repeats", str(args.repeats)]
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
        other = {}
        for line in out.splitlines():
            for name in names:
                if line.startswith(name):
                    other[name] = float(line.split("median")[1].split("ms")[0])
        return other

    rounds = args.rounds if args.against else 1
    here_rounds, there_rounds = [], []
    for _ in range(rounds):  # alternating: a burst of load on the shared host hits both
        here_rounds.append(measure_all())
        if args.against:
            there_rounds.append(there())
    # each row from the round in which it ran fastest here
    rows = {name: min((r[name] for r in here_rounds), key=lambda v: v[0]) for name in names}
    print(
        f"paper patch N = 10, {args.count} seeds, best of {args.repeats} runs each"
        + (f", best of {rounds} rounds" if rounds > 1 else "")
    )
    for name, (ms, its, per) in rows.items():
        print(f"{name:14s} median {ms:6.2f} ms  iterations {its:5.1f}  {per:6.3f} ms/iteration")
    ratio = rows["explicit pins"][0] / rows["default pins"][0]
    print(f"explicit / default pins time: {ratio:.2f}; target <= 1 ms")
    if args.against:
        print(f"--against {args.against} ({rounds} alternating rounds; ratio: their median):")
        for name in names:
            pairs = [(t[name], h[name][0]) for h, t in zip(here_rounds, there_rounds) if name in t]
            if not pairs:  # an older checkout's script without that row
                continue
            there_ms = min(p[0] for p in pairs)
            ratios = [t / h for t, h in pairs]
            print(f"{name:14s} {there_ms:6.2f} ms there, {rows[name][0]:6.2f} ms here: "
                  f"{float(np.median(ratios)):.2f}x faster here "
                  f"(rounds {', '.join(f'{r:.2f}' for r in ratios)})")  # fmt: skip


if __name__ == "__main__":
    main()
