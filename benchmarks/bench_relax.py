"""Time to equilibrium (residual <= 1e-10 F) of every relax method, side by side.

For each size and source strain: a triangular lattice with 10% position noise (stress-free,
or with random rest lengths with ``--random-rest``; stiffness 1, or uniform in ``--stiffness
LO,HI``), one clamped spring near the centre held at the strain (with ``--clamps 2`` a
second one, an eighth of the springs away in distance order, at -strain/4), default pins.
Methods: ``newton``, ``fire``, ``lbfgs`` (time to ``tol = 1e-10``; capped by
``--max-seconds``), ``paper`` (the residual it reaches in 10x Newton's time), and the
limit "one Hessian assembly + one sparse factorisation" of the same problem (float64;
the ratio in parentheses is against the ``rough`` factorisation Newton itself makes,
float32 where that is accurate; in brackets, where the limit is the banded Cholesky,
against SuperLU), measured in the same run; Newton and the limit are each the best of
``--repeat`` (default 3) runs, the others are timed once. Where the limit is the banded
Cholesky, ``floor`` is what Newton's own linear algebra costs: one more solve is run
untimed, its factorisations, Hessian assemblies and triangular solves (per column) are
counted and each is priced at the limit's best time for it, everything else taken as free.
A floor above 3x the limit says that no implementation of the same iteration (Python
overhead removed) comes within 3x: fewer factorisations, assemblies or solves would be
needed. It is an estimate: a solve of several columns is priced as that many single ones,
which can cost more than the batched call. With PARDISO (``--sparse-solvers``) the kept
symbolic analysis is dropped before the limit and before every timed run, so each pays one.

    python benchmarks/bench_relax.py                 # N ~ 10, 1e3, 1e4
    python benchmarks/bench_relax.py --sizes 10,1024
    python benchmarks/bench_relax.py --big           # adds N ~ 1e5 (316 x 316)
    python benchmarks/bench_relax.py --clamps 2 --stiffness 0.5,50 --methods newton \
        --sizes 1024,10000 --strains 0.05,0.5,1   # the issue's two-clamp case
    python benchmarks/bench_relax.py --random-rest --methods newton \
        --sparse-solvers superlu,pardiso --side /work/side/pardiso   # solvers side by side

``--sparse-solvers``: the sparse factorisations (``sparse_solver``,
:data:`~continuum_vs_network.linalg.kkt.SPARSE_SOLVERS`) to time Newton and the limit with,
each against its own limit; the other methods run with the first. ``relax`` takes no
``sparse_solver`` argument yet, so for SuperLU this benchmark hides pypardiso from
``"auto"`` (its ``use``). ``--side DIR`` appends a folder holding optional
packages (pypardiso) to ``sys.path``.

BLAS is pinned to one thread (``--blas-threads``) before numpy is imported: on a shared
2-core machine multithreaded OpenBLAS made scipy's L-BFGS-B 10-30x slower.
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument(
        "--sizes",
        default="10,1024,10000",
        help="node counts, comma separated (10 -> 10-node patch, else ~n x n lattice)",
    )
    p.add_argument("--big", action="store_true", help="add N ~ 1e5 (316 x 316)")
    p.add_argument("--strains", default="0.05,5", help="source strains, comma separated")
    p.add_argument("--methods", default="newton,fire,lbfgs,paper")
    p.add_argument(
        "--max-seconds", type=float, default=120.0, help="time cap for fire and lbfgs (per run)"
    )
    p.add_argument(
        "--random-rest",
        action="store_true",
        help="rest lengths uniform in 0.9-1.1 x the noisy lengths (prestressed)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--clamps", type=int, choices=(1, 2), default=1, help="clamped springs")
    p.add_argument("--stiffness", default="", help="LO,HI: stiffness uniform in [LO, HI]")
    p.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="Newton is timed best of this many runs, as the limit (others once)",
    )
    p.add_argument("--sparse-solvers", default="auto", help="e.g. superlu,pardiso")
    p.add_argument("--side", action="append", default=[], help="folder with optional packages")
    p.add_argument("--blas-threads", default="1")
    return p.parse_args()


def main() -> None:
    args = _parse()
    os.environ.setdefault("OPENBLAS_NUM_THREADS", args.blas_threads)
    os.environ.setdefault("OMP_NUM_THREADS", args.blas_threads)
    os.environ.setdefault("MKL_NUM_THREADS", args.blas_threads)
    sys.path.extend(args.side)

    import numpy as np
    import scipy.linalg as sla

    import continuum_vs_network as cvn
    from continuum_vs_network.linalg import spd
    from continuum_vs_network.linalg.kkt import sparse_backend
    from continuum_vs_network.linalg.spd import factor_spd, sparse_lu
    from continuum_vs_network.network.builders import paper_network, triangular_lattice
    from continuum_vs_network.network.constraints import Problem
    from continuum_vs_network.network.energy import HessianPattern, spring_hessian_blocks
    from continuum_vs_network.network.lagrangian import pattern_for

    sizes = [int(s) for s in args.sizes.split(",") if s]
    if args.big and 100_000 not in sizes:
        sizes.append(100_000)
    strains = [float(s) for s in args.strains.split(",") if s]
    solvers = [s for s in args.sparse_solvers.split(",") if s]
    methods = [m for m in args.methods.split(",") if m]
    have_torch = False
    if "paper" in methods:
        try:
            import torch  # noqa: F401  (imported here so its import time is not timed)

            have_torch = True
        except ImportError:
            print("torch not installed: skipping 'paper'")
            methods.remove("paper")

    def build(n_nodes: int, rng: np.random.Generator) -> cvn.SpringNetwork:
        if n_nodes <= 10:
            net = paper_network(rng, noise=0.1, spacing=1.0)  # the 4-3-2-1 patch
            net = net.with_stiffness(np.ones(net.n_springs)).with_rest_length(net.lengths())
        else:
            side = round(float(np.sqrt(n_nodes)))
            net = triangular_lattice(side, side, noise=0.1, rng=rng)
        if args.stiffness:
            lo, hi = (float(v) for v in args.stiffness.split(","))
            net = net.with_stiffness(rng.uniform(lo, hi, net.n_springs))
        if args.random_rest:
            net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
        return net

    def use(solver: str) -> None:
        """Make ``sparse_solver="auto"`` (relax's, everywhere) mean ``solver``: SuperLU by
        hiding pypardiso; PARDISO only where it imports (else ImportError)."""
        spd._PARDISO.clear()
        if solver == "superlu":
            spd._PARDISO["module"] = False
        elif sparse_backend(solver) != sparse_backend():
            raise ImportError(f"sparse solver {solver!r} is not what 'auto' chooses here")

    def forget() -> None:
        """Drop PARDISO's kept analyses: the limit and each timed run pay their own."""
        if sparse_backend() == "pardiso":
            from continuum_vs_network.linalg import pardiso

            pardiso.forget()

    def limit(net: cvn.SpringNetwork, clamp: dict) -> tuple[dict[str, float], str]:
        """Best of --repeat seconds: ``assembly``, ``factor`` (the limit's factorisation,
        float64), ``rough`` (the factorisation Newton itself makes: float32 where accurate,
        :func:`~continuum_vs_network.linalg.spd.factor_spd`) and, where the limit is the
        banded Cholesky, ``superlu`` (SuperLU in nested-dissection order, the package's
        factorisation above the band sizes and the issue's limit when it was written);
        and the name of the factorisation used.

        The Hessian of the start (clamped springs set to their lengths); when that is
        indefinite, the network's own positions': a failed Cholesky stops at its first
        negative pivot and would make the limit cheaper than one factorisation.
        """
        problem = Problem.build(net, clamped=clamp)
        pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
        ordered = pattern.ordered
        # band-ordered rows (lagrangian.pattern_for) mean kkt's banded Cholesky is used
        rows = pattern.nested_rows()

        def hessian(x):
            return pattern.assemble(
                spring_hessian_blocks(x, net.springs, net.stiffness, net.rest_length)
            )

        x, where = problem.start(net.positions), "start"
        if factor_spd(hessian(x), ordered=ordered) is None:
            x, where = net.positions, "indefinite start: at the positions"
        best: dict[str, float] = {}

        def timed(name: str, work) -> object:
            forget()
            t0 = time.perf_counter()
            out = work()
            best[name] = min(best.get(name, np.inf), time.perf_counter() - t0)
            return out

        b = np.ones(pattern.size)  # a right-hand side for the timed triangular solves
        for _ in range(args.repeat):
            W = timed("assembly", lambda: hessian(x))
            f = timed("factor", lambda W=W: factor_spd(W, ordered=ordered))
            timed("rough", lambda W=W: factor_spd(W, ordered=ordered, rough=True))
            if rows is not None:
                nested = W[rows][:, rows]
                timed("superlu", lambda M=nested: sparse_lu(M, ordering="NATURAL"))
            if rows is not None and sparse_backend() != "pardiso":  # banded: the floor's parts
                f.precondition(b)  # its float32 copy is made at the first use, not timed
                timed("dpbtrs", lambda f=f: f.solve(b))
                timed("spbtrs", lambda f=f: f.precondition(b))
        used = ("banded Cholesky" if rows is not None else sparse_backend()) + ", " + where
        return best, used

    def floor(net, clamp: dict, best: dict[str, float]) -> tuple[float, str]:
        """Newton's floor: the seconds of one more (untimed) solve's banded factorisations,
        Hessian assemblies and triangular solves, each counted (solves per column) and
        priced at the limit's best time for it, all else taken as free; and the counts.

        The solve with which each completed float32 factorisation is probed for accuracy
        (spd._accurate) is not counted again: the ``rough`` price includes it."""
        names = ("spbtrf", "cholesky_banded", "assemble", "spbtrs", "dpbtrs")
        owner = {"cholesky_banded": sla, "assemble": HessianPattern}
        owner = {name: owner.get(name, sla.lapack) for name in names}
        saved = {name: getattr(owner[name], name) for name in names}
        counts = dict.fromkeys(names, 0)
        probes = [0]  # completed spbtrf (info 0): each is probed by one spbtrs

        def counting(name: str):
            def call(*a, **k):
                rhs = a[1] if name.endswith("trs") else None
                counts[name] += rhs.shape[1] if rhs is not None and rhs.ndim == 2 else 1
                out = saved[name](*a, **k)
                probes[0] += name == "spbtrf" and out[1] == 0
                return out

            return call

        try:
            for name in names:
                setattr(owner[name], name, counting(name))
            cvn.relax(net, clamped=clamp, method="newton", tol=1e-10)
        finally:
            for name in names:
                setattr(owner[name], name, saved[name])
        counts["spbtrs"] -= probes[0]
        price = {"spbtrf": "rough", "cholesky_banded": "factor", "assemble": "assembly"}
        seconds = sum(counts[name] * best[price.get(name, name)] for name in names)
        factorisations = counts["spbtrf"] + counts["cholesky_banded"]
        solves = counts["spbtrs"] + counts["dpbtrs"]
        return seconds, (
            f"{factorisations} factorisations + {counts['assemble']} assemblies + {solves} solves"
        )

    def run(net, clamp: dict, strain: float, todo: list[str], tag: str, times: dict) -> None:
        for method in todo:
            try:  # warm-up (pattern and ordering caches, lazy imports), not timed
                cvn.relax(net, clamped=clamp, method=method, max_iter=2)
            except cvn.EquilibriumError:
                pass
            kw: dict = {}
            if method == "paper":
                kw = {"max_seconds": 10 * times.get("newton" + tag, 1.0), "max_iter": 10**9}
            elif method != "newton":
                kw = {"max_seconds": args.max_seconds, "max_iter": 10**9}
            name = method + (tag if method == "newton" else "")
            seconds = np.inf
            for _ in range(args.repeat if method == "newton" else 1):
                forget()
                t0 = time.perf_counter()
                try:
                    eq = cvn.relax(net, clamped=clamp, method=method, tol=1e-10, **kw)
                    note = "converged"
                except cvn.EquilibriumError as err:
                    eq = err.state
                    note = f"not converged in {time.perf_counter() - t0:.3g} s"
                    if eq is None:
                        print(f"{net.n_nodes:>7} {strain:>5g} {name:>16} failed: {err}")
                        break
                except ValueError as err:
                    print(f"{net.n_nodes:>7} {strain:>5g} {name:>16} refused: {err}")
                    eq = None
                    break
                seconds = min(seconds, time.perf_counter() - t0)
            if eq is None:
                continue
            if eq.converged:
                times[name] = seconds
            print(
                f"{net.n_nodes:>7} {strain:>5g} {name:>16} {seconds:>9.4f} "
                f"{eq.iterations:>7} {eq.relative_residual:>11.2e}  {note}"
                + (f", clamp error {eq.clamp_error:.1e}" if not eq.converged else "")
            )

    print(
        f"# bench_relax: {' '.join(sys.argv[1:]) or '(defaults)'}; cores={os.cpu_count()}, "
        f"BLAS threads={os.environ['OPENBLAS_NUM_THREADS']}, torch={have_torch}"
    )
    print(
        "# target: relative residual 1e-10 (each net force against its node's sum k L); "
        f"fire/lbfgs capped at {args.max_seconds:g} s; paper given 10x newton's time"
    )
    header = (
        f"{'N':>7} {'S':>5} {'method':>16} {'seconds':>9} {'iters':>7} {'rel. resid':>11}  note"
    )
    print(header)
    summary = []
    tags = [f"@{s}" if len(solvers) > 1 else "" for s in solvers]
    for n_nodes in sizes:
        rng = np.random.default_rng(args.seed)
        net = build(n_nodes, rng)
        mid = net.positions[net.springs].mean(axis=1)
        order = np.argsort(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1))
        centre, second = int(order[0]), int(order[len(order) // 8])
        for strain in strains:
            clamp = {centre: float(net.clamp_length(centre, strain))}
            if args.clamps == 2:
                clamp[second] = float(net.clamp_length(second, -strain / 4))
            times: dict[str, float] = {}
            for which, (solver, tag) in enumerate(zip(solvers, tags, strict=True)):
                use(solver)
                best, factorisation = limit(net, clamp)
                for name in ("factor", "rough", "superlu"):
                    if name in best:
                        key = "limit" if name == "factor" else name
                        times[key + tag] = best["assembly"] + best[name]
                superlu = f"; SuperLU {best['superlu']:.4f} s" if "superlu" in best else ""
                print(
                    f"{net.n_nodes:>7} {strain:>5g} {'limit' + tag:>16} "
                    f"{times['limit' + tag]:>9.4f} {'':>7} {'':>11}  assembly "
                    f"{best['assembly']:.4f} s + factorisation {best['factor']:.4f} s "
                    f"({factorisation}; rough {best['rough']:.4f} s{superlu})"
                )
                todo = [m for m in methods if m == "newton" or not which]
                run(net, clamp, strain, todo, tag, times)
                if "newton" + tag in times and "dpbtrs" in best:
                    times["floor" + tag], parts = floor(net, clamp, best)
                    print(
                        f"{net.n_nodes:>7} {strain:>5g} {'floor' + tag:>16} "
                        f"{times['floor' + tag]:>9.4f} {'':>7} {'':>11}  {parts}, each at "
                        "the limit's time"
                    )
            use(solvers[0])
            summary.append((net.n_nodes, strain, times))

    print(
        "\n# ratios (same run): newton/limit per sparse solver (against the rough limit; "
        "[against SuperLU where the limit is banded]; floor/limit where it is banded), "
        "fire/newton, lbfgs/newton"
    )
    for n_nodes, strain, times in summary:

        def ratio(a: str, b: str, times=times) -> str:
            return f"{times[a] / times[b]:8.1f}" if a in times and b in times else f"{'-':>8}"

        def against(t: str, times=times) -> str:
            out = f"{ratio('newton' + t, 'limit' + t)} ({ratio('newton' + t, 'rough' + t).strip()})"
            if "superlu" + t in times:
                out += f" [{ratio('newton' + t, 'superlu' + t).strip()}]"
            if "floor" + t in times:
                out += f" floor {ratio('floor' + t, 'limit' + t).strip()}"
            return out

        per_solver = " ".join(against(t) for t in tags)
        print(
            f"{n_nodes:>7} {strain:>5g} {per_solver} {ratio('fire', 'newton' + tags[0])} "
            f"{ratio('lbfgs', 'newton' + tags[0])}"
        )


if __name__ == "__main__":
    main()
