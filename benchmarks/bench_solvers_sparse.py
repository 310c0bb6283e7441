"""Sparse positive-definite solvers on spring-network Hessians, side by side in one run.

The matrix: the Hessian of a noisy triangular lattice of ~N nodes with rest lengths
0.9-1.1x the noisy lengths (prestressed), relaxed to equilibrium with the default pins, its
free coordinates in the package's nested-dissection order (``pattern_for``). Positive
definite (a stable equilibrium), the case Newton's last iterations and the learning tracker
factorise. For each solver: factorisation (or set-up) seconds, seconds per solve of one
right-hand side, memory of the factor, and the ratio to the package's path (SuperLU,
diagonal pivots in symmetric mode, natural order on the nested-dissection rows).

Solvers (each one must also say whether the matrix is positive definite: Newton needs it):

* ``superlu-nd``: the package's path (``kkt.factor_spd(W, ordered=True,
  sparse_solver="superlu")``): the positive
  ``U`` diagonal with symmetric pivots proves ``W > 0``.
* ``superlu-<spec>``: SuperLU on the unordered rows with its own ``permc_spec``.
* ``pardiso-chol``: MKL PARDISO through ``pypardiso``, ``mtype=2`` (Cholesky: fails unless
  ``W > 0``), METIS ordering, analysis and factorisation; optional.
* ``pardiso-kept``: the package's PARDISO path (``linalg/pardiso.py``): the analysis of the
  structure is kept, so a refactorisation (Newton iterations, learning steps) is numerical
  only; the first factorisation's time is printed above the table.
* ``cholmod-kept``: CHOLMOD's supernodal Cholesky through ``scikit-sparse`` (fails unless
  ``W > 0``; its simplicial mode is an LDL^T that does not), ordering by its default (AMD
  or METIS, the better), the analysis kept: a refactorisation is numerical only; the first
  factorisation's time is printed above the table; optional (it needs SuiteSparse's
  CHOLMOD; scikit-sparse 0.5 needs SuiteSparse 7, 0.4.16 builds on SuiteSparse 5). Its
  supernodal speed depends on the BLAS that CHOLMOD links (reference BLAS is slow).
* ``amg-cg``: pyamg smoothed aggregation (rigid modes as near-null space) preconditioning
  CG to a relative residual ``--rtol``; optional. Set-up is its "factorisation", the CG
  solve its solve. No positive-definiteness proof (CG only detects negative curvature it
  happens to meet).

Optional packages come from ``--side DIR`` folders (``pip install --target DIR pypardiso``;
MKL's shared libraries need ``PYPARDISO_MKL_RT`` or ``LD_LIBRARY_PATH``):

    OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 python benchmarks/bench_solvers_sparse.py \\
        --sizes 1000,10000,100000 --side /work/side/pardiso --side /work/side/pyamg
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", default="1000,10000,100000")
    p.add_argument("--side", action="append", default=[], help="folder with optional packages")
    p.add_argument("--rtol", type=float, default=1e-10, help="CG tolerance for amg-cg")
    p.add_argument("--specs", default="MMD_AT_PLUS_A,COLAMD", help="SuperLU permc_spec to try")
    p.add_argument("--seed", type=int, default=0)
    return p.parse_args()


def main() -> None:
    args = _parse()
    for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    sys.path.extend(args.side)
    import numpy as np
    import scipy.sparse as sp

    import continuum_vs_network as cvn
    from continuum_vs_network.linalg.kkt import factor_spd, sparse_lu
    from continuum_vs_network.network.builders import triangular_lattice
    from continuum_vs_network.network.constraints import Problem
    from continuum_vs_network.network.energy import spring_hessian_blocks
    from continuum_vs_network.network.lagrangian import pattern_for

    try:
        import pypardiso

        from continuum_vs_network.linalg import pardiso
    except (ImportError, OSError) as err:
        pypardiso = None
        print(f"# pypardiso not importable ({err}): skipped")
    try:
        from sksparse import cholmod
    except ImportError:
        cholmod = None
        print("# scikit-sparse (CHOLMOD) not importable: skipped")
    try:
        import pyamg
    except ImportError:
        pyamg = None
        print("# pyamg not importable: skipped")

    def best(fn, repeat: int):
        out, seconds = None, np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = fn()
            seconds = min(seconds, time.perf_counter() - t0)
        return out, seconds

    print(
        f"# bench_solvers_sparse: {' '.join(sys.argv[1:]) or '(defaults)'}; "
        f"threads OPENBLAS={os.environ['OPENBLAS_NUM_THREADS']} "
        f"MKL={os.environ['MKL_NUM_THREADS']}"
    )
    print(
        f"{'N':>7} {'rows':>7} {'solver':>18} {'factor s':>9} {'solve s':>9} {'factor MB':>10} "
        f"{'PD':>4} {'err':>8} {'factor/ref':>10} {'solve/ref':>9}"
    )

    def run_size(n_nodes: int) -> None:
        rng = np.random.default_rng(args.seed)
        side = round(float(np.sqrt(n_nodes)))
        net = triangular_lattice(side, side, noise=0.1, rng=rng)
        net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
        x = cvn.relax(net).positions
        problem = Problem.build(net)
        pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
        W = pattern.assemble(spring_hessian_blocks(x, net.springs, net.stiffness, net.rest_length))
        W = sp.csr_matrix(W)
        n = W.shape[0]
        b = rng.standard_normal(n)
        repeat = 3 if n < 50_000 else 1
        rows: list[tuple] = []

        def err_of(sol) -> float:
            return float(np.linalg.norm(W @ sol - b) / np.linalg.norm(b))

        f, tf = best(lambda: factor_spd(W, ordered=True, sparse_solver="superlu"), repeat)
        lu = sparse_lu(W, ordering="NATURAL")
        mb = (lu.L.nnz + lu.U.nnz) * 12 / 1e6
        sol, ts = best(lambda: f.solve(b), repeat)
        rows.append(("superlu-nd", tf, ts, mb, f is not None, err_of(sol)))
        for spec in [s for s in args.specs.split(",") if s]:
            Wc = sp.csc_matrix(W)
            lu, tf = best(lambda spec=spec, Wc=Wc: sparse_lu(Wc, ordering=spec), repeat)
            pd = bool(np.array_equal(lu.perm_r, lu.perm_c) and np.all(lu.U.diagonal() > 0))
            sol, ts = best(lambda lu=lu, b=b: lu.solve(b), repeat)
            mb = (lu.L.nnz + lu.U.nnz) * 12 / 1e6
            rows.append((f"superlu-{spec}", tf, ts, mb, pd, err_of(sol)))
        if pypardiso is not None:
            upper = sp.triu(W, format="csr")
            upper.sort_indices()

            def pardiso_factor():
                solver = pypardiso.PyPardisoSolver(mtype=2)
                solver.set_iparm(1, 1)  # no defaults: iparm(2)=2 METIS, iparm(24)=0
                solver.set_iparm(2, 2)
                solver.set_iparm(8, 0)  # no iterative refinement steps
                solver.set_iparm(10, 8)  # pivot perturbation 1e-8 (ignored for mtype 2)
                solver.factorize(upper)
                return solver

            solver, tf = best(pardiso_factor, repeat)
            sol, ts = best(lambda: solver.solve(upper, b), repeat)
            mb = (solver.get_iparm(17) + solver.get_iparm(16)) / 1e3  # kB: factor + permanent
            # mtype 2 raises PyPardisoError(-4) when a pivot is not positive: here it factorised
            rows.append(("pardiso-chol", tf, ts, mb, True, err_of(sol)))
            solver.free_memory(everything=True)
            # the package's path: METIS analysis kept per structure, refactorisations numeric
            pardiso.forget()
            f, t_first = best(
                lambda: (pardiso.forget(), factor_spd(W, sparse_solver="pardiso"))[1], 1
            )
            f, tf = best(lambda: factor_spd(W, sparse_solver="pardiso"), repeat)
            sol, ts = best(lambda: f.solve(b), repeat)
            rows.append(("pardiso-kept", tf, ts, float("nan"), f is not None, err_of(sol)))
            print(
                f"# N={net.n_nodes}: package PARDISO first factorisation (with analysis) "
                f"{t_first:.4f} s, refactorisation {tf:.4f} s"
            )
        if cholmod is not None:
            Wc = sp.csc_matrix(W)
            f, t_first = best(lambda: cholmod.cholesky(Wc, mode="supernodal"), 1)
            analysis = cholmod.analyze(Wc, mode="supernodal")
            f, tf = best(lambda: analysis.cholesky(Wc), repeat)
            sol, ts = best(lambda: f(b), repeat)
            mb = f.L().nnz * 12 / 1e6
            rows.append(("cholmod-kept", tf, ts, mb, True, err_of(sol)))
            print(
                f"# N={net.n_nodes}: CHOLMOD first factorisation (with analysis) "
                f"{t_first:.4f} s, refactorisation {tf:.4f} s"
            )
        if pyamg is not None:
            coords = pattern.coords
            xs = x.ravel()[coords]
            B = np.zeros((n, 3))
            is_x = coords % 2 == 0
            B[is_x, 0] = 1.0
            B[~is_x, 1] = 1.0
            y_of = x.ravel()[coords + np.where(is_x, 1, -1)]
            B[is_x, 2] = -y_of[is_x]
            B[~is_x, 2] = y_of[~is_x]
            del xs
            ml, tf = best(lambda: pyamg.smoothed_aggregation_solver(W, B=B), repeat)
            iters: list[float] = []

            def amg_solve():
                res: list[float] = []
                out = ml.solve(b, tol=args.rtol, accel="cg", residuals=res, maxiter=500)
                iters.append(len(res) - 1)
                return out

            sol, ts = best(amg_solve, repeat)
            mb = (
                sum(
                    (lv.A.nnz * 12 + (lv.P.nnz * 12 if hasattr(lv, "P") else 0)) for lv in ml.levels
                )
                / 1e6
            )
            rows.append((f"amg-cg({iters[-1]} it)", tf, ts, mb, None, err_of(sol)))
        ref_f, ref_s = rows[0][1], rows[0][2]
        for name, tf, ts, mb, pd, err in rows:
            pd_s = "-" if pd is None else ("yes" if pd else "NO")
            print(
                f"{net.n_nodes:>7} {n:>7} {name:>18} {tf:>9.4f} {ts:>9.5f} {mb:>10.1f} "
                f"{pd_s:>4} {err:>8.1e} {tf / ref_f:>10.2f} {ts / ref_s:>9.2f}",
                flush=True,
            )

    for n_nodes in [int(s) for s in args.sizes.split(",") if s]:
        run_size(n_nodes)


if __name__ == "__main__":
    main()
