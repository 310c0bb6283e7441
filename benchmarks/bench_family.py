"""Newton's robustness and iteration counts on a seeded family of random networks.

The family (issue 10): noisy triangular lattices, random Delaunay meshes and the paper's
10-node patches; stiffness ``k = 10^U(-3, 3)``; rest lengths within 10 % of the geometry
or ``10^U(log 0.3, log 3)`` times it; 0-3 clamps at strains ``U(-0.9, 10)``; the default
(two far) pins. Every network is relaxed with ``cvn.relax`` at its defaults; a failure is
any ``EquilibriumError`` (or other exception). Prints failures and the median / p95 / max
iterations, overall and for the strongly prestressed half (rest lengths 0.3-3x).

    python benchmarks/bench_family.py            # 500 networks
    python benchmarks/bench_family.py --count 100 --seed 1
    python benchmarks/bench_family.py --medium --count 100  # 170-530 nodes: just above dense
    python benchmarks/bench_family.py --large --count 60   # 500-1100 nodes: the sparse Newton
    python benchmarks/bench_family.py --tol 1e-2           # a loose tolerance (no false saddles)
    python benchmarks/bench_family.py --pinned             # two far nodes pinned fully
    python benchmarks/bench_family.py --medium --displaced --count 60   # pinned nodes moved
    python benchmarks/bench_family.py --stiffness 0.5,50 --count 300   # no stiff springs

Targets: 0 failures, median <= 30, p95 <= 120 iterations. Clamp sets that no network can
meet (three clamped springs forming a triangle that violates the triangle inequality) are
counted apart: ``relax`` must refuse them with a clear reason.
"""

from __future__ import annotations

import argparse
import os
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--count", type=int, default=500)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--method", default="newton")
    p.add_argument("--verbose", action="store_true", help="print every failure's reason")
    p.add_argument("--tol", type=float, default=1e-10, help="relax's tol (default 1e-10)")
    p.add_argument(
        "--pinned",
        action="store_true",
        help="pin both nodes of the default pins fully (they then carry load) instead of "
        "relaxing under the default pins",
    )
    p.add_argument(
        "--displaced",
        action="store_true",
        help="stress-free networks (rest lengths = the geometry's), no clamps: 1-5 "
        "neighbouring nodes moved together by 0.1-10 mean rest lengths and pinned there, "
        "with the default pins (a source displaced and held)",
    )
    p.add_argument(
        "--large",
        action="store_true",
        help="lattices of 24-33 per side and Delaunay meshes of 500-1100 nodes (no paper "
        "patches): above the dense trust-region size, so the sparse Newton solves them",
    )
    p.add_argument(
        "--stiffness",
        default="",
        help="LO,HI: each network's stiffness drawn anew, uniform in [LO, HI] (the paper's "
        "0.5,50 has no spring 10x the median), after the rest of the network",
    )
    p.add_argument(
        "--medium",
        action="store_true",
        help="lattices of 13-23 per side and Delaunay meshes of 170-530 nodes (no paper "
        "patches): just above the dense trust-region size",
    )
    return p.parse_args()


def family_member(rng, *, large: bool = False, medium: bool = False):
    """One random network and its clamps: ``(kind, prestressed, net, clamped)``; ``large``
    (``medium``): the same distributions on networks of 500-1100 (170-530) nodes, lattices
    and Delaunay meshes."""
    import numpy as np
    from scipy.spatial import Delaunay

    import continuum_vs_network as cvn
    from continuum_vs_network.network.builders import paper_network, triangular_lattice

    sides, nodes = (24, 34), (500, 1100)
    if medium:
        sides, nodes = (13, 24), (170, 530)
    elif not large:
        sides, nodes = (5, 13), (20, 120)
    kind = ("lattice", "delaunay", "paper")[rng.integers(2 if large or medium else 3)]
    if kind == "lattice":
        side = int(rng.integers(*sides))
        net = triangular_lattice(side, side, noise=0.15, rng=rng)
    elif kind == "delaunay":
        n = int(rng.integers(*nodes))
        pts = rng.random((n, 2)) * np.sqrt(n)
        tri = Delaunay(pts).simplices
        edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
        edges = np.unique(edges, axis=0)
        d = np.linalg.norm(pts[edges[:, 1]] - pts[edges[:, 0]], axis=1)
        net = cvn.SpringNetwork(pts, edges, np.ones(len(edges)), d)
    else:
        net = paper_network(rng)
    s = net.n_springs
    k = 10.0 ** rng.uniform(-3, 3, s)
    prestressed = bool(rng.random() < 0.5)
    geometry = net.lengths()
    factor = 10.0 ** rng.uniform(np.log10(0.3), np.log10(3), s) if prestressed else None
    if factor is None:
        factor = rng.uniform(0.9, 1.1, s)
    net = net.with_stiffness(k).with_rest_length(geometry * factor)
    m = int(rng.integers(0, 4))
    springs = rng.choice(s, size=m, replace=False)
    strains = rng.uniform(-0.9, 10.0, m)
    clamped = {int(j): float(geometry[j] * (1 + e)) for j, e in zip(springs, strains)}
    return kind, prestressed, net, clamped


def displaced(net, rng):
    """``net`` made stress-free (rest lengths = its lengths) with 1-5 neighbouring nodes
    moved together by ``10^U(-1, 1)`` mean rest lengths in a random direction and pinned
    there, with the default pins: ``(net, pins (n_nodes, 2) bool, x0)``."""
    import numpy as np

    import continuum_vs_network as cvn

    net = net.with_rest_length(net.lengths(net.positions))
    count = int(rng.integers(1, 6))
    centre = int(rng.integers(net.n_nodes))
    movers = np.argsort(np.linalg.norm(net.positions - net.positions[centre], axis=1))[:count]
    amplitude = 10 ** rng.uniform(-1, 1) * float(np.mean(net.rest_length))
    direction = rng.standard_normal(2)
    x0 = net.positions.copy()
    x0[movers] += amplitude * direction / np.linalg.norm(direction)
    pins = cvn.default_pins(net)
    pins[movers] = True
    return net, pins, x0


def incompatible(net, clamped) -> bool:
    """True when three clamped springs form a triangle that violates the triangle
    inequality: no network meets those clamps, and ``relax`` must say so."""
    if len(clamped) < 3:
        return False
    pairs = {frozenset(map(int, net.springs[j])): v for j, v in clamped.items()}
    nodes = sorted(set().union(*pairs))
    for a in nodes:
        for b in nodes:
            for c in nodes:
                if a < b < c:
                    sides = [pairs.get(frozenset(p)) for p in ((a, b), (b, c), (a, c))]
                    if None not in sides and 2 * max(sides) >= sum(sides):
                        return True
    return False


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    import numpy as np

    import continuum_vs_network as cvn
    from continuum_vs_network.network.constraints import default_pins

    rng = np.random.default_rng(args.seed)
    rows = []
    t0 = time.perf_counter()
    for i in range(args.count):
        kind, prestressed, net, clamped = family_member(rng, large=args.large, medium=args.medium)
        if args.stiffness:
            low, high = (float(v) for v in args.stiffness.split(","))
            net = net.with_stiffness(rng.uniform(low, high, net.n_springs))
        pinned = x0 = None
        if args.displaced:
            (net, pinned, x0), clamped = displaced(net, rng), {}
        if incompatible(net, clamped):
            kind = "incompatible"
        if args.pinned:
            pins = default_pins(net, list(clamped))
            pinned = np.flatnonzero(pins.any(axis=1)).tolist()
        try:
            eq = cvn.relax(net, pinned, clamped, x0=x0, method=args.method, tol=args.tol)
            rows.append((kind, prestressed, eq.iterations, True, ""))
        except Exception as err:  # every failure counts, whatever it is
            its = getattr(getattr(err, "state", None), "iterations", -1)
            rows.append((kind, prestressed, its, False, f"{type(err).__name__}: {err}"))
            if args.verbose:
                print(f"#{i} {kind} prestressed={prestressed} clamps={len(clamped)}: {err}")
        if args.verbose and (i + 1) % 50 == 0:
            done = np.array([r[2] for r in rows if r[3]])
            print(
                f"# {i + 1} done, {sum(not r[3] for r in rows)} failures, median "
                f"{np.median(done):.0f}, {time.perf_counter() - t0:.0f} s",
                flush=True,
            )
    seconds = time.perf_counter() - t0

    def line(name, sel):
        its = np.array([r[2] for r in sel if r[3]])
        fails = sum(not r[3] for r in sel)
        if not its.size:
            return f"{name:24s} n={len(sel):4d} failures={fails}"
        return (
            f"{name:24s} n={len(sel):4d} failures={fails:3d}  iterations median="
            f"{np.median(its):5.1f} p95={np.percentile(its, 95):6.1f} max={its.max():5d}"
        )

    pins = "two far nodes pinned" if args.pinned else "default pins"
    pins += ", 1-5 nodes displaced and pinned (stress-free)" if args.displaced else ""
    pins += f", k uniform in [{args.stiffness}]" if args.stiffness else ""
    print(
        f"family of {args.count} networks, seed {args.seed}, method {args.method}, "
        f"tol {args.tol:g}, {pins}"
    )
    print(line("all", rows))
    feasible = [r for r in rows if r[0] != "incompatible"]
    print(line("all with compatible clamps", feasible))
    print(line("incompatible clamps", [r for r in rows if r[0] == "incompatible"]))
    if not args.displaced:  # displaced networks are made stress-free
        print(line("prestressed (0.3-3x)", [r for r in feasible if r[1]]))
        print(line("near geometry (0.9-1.1x)", [r for r in feasible if not r[1]]))
    for kind in ("lattice", "delaunay", "paper"):
        print(line(kind, [r for r in rows if r[0] == kind]))
    print(f"total {seconds:.1f} s")
    reasons: dict[str, int] = {}
    for r in rows:
        if not r[3]:
            key = r[4].split(" (")[0][:100]
            reasons[key] = reasons.get(key, 0) + 1
    for reason, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
        print(f"  {count:4d} x {reason}")


if __name__ == "__main__":
    main()
