"""Work-precision of the finite-element continuum, and the cost of a 1e5-DOF static solve.

Run: ``python benchmarks/bench_continuum.py [--quick]``. Prints three tables:

1. mesh refinement on Lamé's thick cylinder (pressure inside, clamped outside), P1 and
   isoparametric P2: L2 error against wall-clock time (mesh + basis, assembly,
   factorisation, solve);
2. time-step refinement, on the lowest mode of a clamped block (exact solution known):
   backward Euler and Newmark, overdamped (substrate drag) and inertial, error against
   run time;
3. a static solve with about 1e5 DOFs (P1 and P2 on structured rectangles and on ring
   meshes of an annulus), timed step by step, with SuperLU's ``MMD_AT_PLUS_A`` ordering
   against SciPy's default ``COLAMD``, in symmetric mode and with partial pivoting,
   measured side by side on the same matrix (best of ``repeat`` runs; CPU time next to
   wall time). On the structured 158 x 79 P2 grid minimum degree happened to be slower
   than COLAMD (ties in a perfectly regular grid); one more column of squares reversed it.

Timings depend on the machine and its load; compare the ratios within one run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.sparse.linalg import eigsh

from continuum_vs_network.continuum.body import (
    elastic_body,
    mass_matrix,
    pressure_load,
    stiffness_matrix,
)
from continuum_vs_network.continuum.materials import Material
from continuum_vs_network.continuum.mesh import annulus_mesh, rectangle_mesh
from continuum_vs_network.continuum.static import factorise, fix
from continuum_vs_network.continuum.viscoelastic import Damping, simulate_body
from continuum_vs_network.linalg.spd import fixed_vector


def _best(fn, repeat: int):
    """Best wall-clock time of ``repeat`` runs (the CPU time of the same run is kept in
    ``_best.cpu``: on a shared machine it is the steadier figure)."""
    best, cpu, out = np.inf, np.inf, None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall = time.perf_counter() - t
        if wall < best:
            best, cpu = wall, time.process_time() - c
    _best.cpu = cpu
    return best, out


def mesh_refinement(quick: bool) -> None:
    mat = Material.from_young(1.0, 0.3)
    a, b, p = 1.0, 2.0, 1.0
    lam, mu = mat.lam, mat.mu
    A = -p / (2 * (lam + mu) + 2 * mu * b**2 / a**2)
    B = -A * b**2
    print("1. mesh refinement, thick cylinder (L2 error relative)")
    print("order      h     dofs   error      mesh+basis  assembly  factor   solve    total s")
    hs = (0.2, 0.1, 0.05, 0.025) if quick else (0.2, 0.1, 0.05, 0.025, 0.0125)
    for order in (1, 2):
        for h in hs:
            if order == 2 and h < 0.02:
                continue
            t0 = time.perf_counter()
            body = elastic_body(annulus_mesh(a, b, h=h, curved=order == 2), mat, order=order)
            t1 = time.perf_counter()
            K = stiffness_matrix(body)
            f = pressure_load(body, p, where=lambda x, y: np.hypot(x, y) < 1.5)
            t2 = time.perf_counter()
            fixed = fix(body, lambda x, y: np.hypot(x, y) > 1.5, boundary=True)
            free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
            lu = factorise(K[free][:, free])
            t3 = time.perf_counter()
            u = np.zeros(body.n_dofs)
            u[free] = lu.solve(f[free])
            t4 = time.perf_counter()
            uh = np.asarray(body.basis.interpolate(u))
            X = np.asarray(body.basis.global_coordinates())
            r = np.hypot(X[0], X[1])
            ur = A * r + B / r
            ux, uy = ur * X[0] / r, ur * X[1] / r
            dx = body.basis.dx
            err = np.sqrt(
                np.sum(((uh[0] - ux) ** 2 + (uh[1] - uy) ** 2) * dx) / np.sum((ux**2 + uy**2) * dx)
            )
            print(
                f"P{order}  {h:8.4f} {body.n_dofs:8d}  {err:9.3e}  {t1 - t0:9.3f}  "
                f"{t2 - t1:8.3f}  {t3 - t2:6.3f}  {t4 - t3:6.3f}  {t4 - t0:8.3f}"
            )
    print()


def time_refinement(quick: bool) -> None:
    body = elastic_body(rectangle_mesh(2.0, 1.0, h=0.125), Material(1.0, 1.0), order=2)
    fixed = fix(body, lambda x, y: x < 1e-9)
    K, M = stiffness_matrix(body), mass_matrix(body, 1.0)
    free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
    K_free, M_free = K[free][:, free].tocsc(), M[free][:, free].tocsc()
    w2, phi = eigsh(K_free, k=1, M=M_free, sigma=0, v0=fixed_vector(free.size))
    w2 = float(w2[0])
    mode = np.zeros(body.n_dofs)
    mode[free] = phi[:, 0] / np.abs(phi[:, 0]).max()
    print(f"2. time-step refinement, lowest mode of a clamped block ({body.n_dofs} DOFs)")
    print("problem      scheme           steps  error      seconds  (factorisation s)")
    ns = (10, 20, 40, 80) if quick else (10, 20, 40, 80, 160, 320)
    eta = 1.0
    tau = eta / w2
    period = 2 * np.pi / np.sqrt(w2)
    for problem, kw, t_end, exact in (
        ("overdamped", dict(damping=Damping(drag=eta)), tau, np.exp(-1.0)),
        ("inertial", dict(density=1.0), 0.3 * period, np.cos(0.3 * 2 * np.pi)),
    ):
        for scheme in ("backward_euler", "newmark"):
            for n in ns:
                tr = simulate_body(
                    body, fixed=fixed, dt=t_end / n, t_end=t_end, scheme=scheme, u0=mode, **kw
                )
                err = np.abs(tr.u - exact * mode).max()
                print(
                    f"{problem:12s} {scheme:15s} {n:6d}  {err:9.3e}  {tr.seconds:7.3f}  "
                    f"({tr.seconds_factorisation:.4f})"
                )
    print()


def big_static(repeat: int, pivoting: bool) -> None:
    print("3. static solve with about 1e5 DOFs (rectangles: left clamped, right pulled;")
    print("   annuli: outside clamped, inside expanded)")
    print("   factorisation seconds by SuperLU ordering; 'sym' = symmetric mode (diagonal")
    print("   pivots, the package default), 'piv' = SuperLU's default partial pivoting")
    mat = Material(1.0, 1.0)
    cases = (
        ("rectangle 316x158", 1, lambda: rectangle_mesh(2.0, 1.0, h=1 / 158)),
        ("rectangle 158x79", 2, lambda: rectangle_mesh(2.0, 1.0, h=1 / 79)),
        ("rectangle 159x80", 2, lambda: rectangle_mesh(2.0, 1.0, h=0.012658)),
        ("annulus h=0.0125", 1, lambda: annulus_mesh(1.0, 2.0, h=0.0125)),
        ("annulus h=0.025", 2, lambda: annulus_mesh(1.0, 2.0, h=0.025, curved=True)),
    )
    for name, order, make in cases:
        t0 = time.perf_counter()
        body = elastic_body(make(), mat, order=order)
        t_basis = time.perf_counter() - t0
        t_asm, K = _best(lambda body=body: stiffness_matrix(body), repeat)
        if name.startswith("rectangle"):
            fixed = fix(body, lambda x, y: x < 1e-9) + fix(
                body, lambda x, y: x > 2 - 1e-9, displacement=(1e-3, 0.0)
            )
        else:
            fixed = fix(body, lambda x, y: np.hypot(x, y) > 1.5, boundary=True) + fix(
                body,
                lambda x, y: np.hypot(x, y) < 1.5,
                boundary=True,
                displacement=lambda x, y: (1e-3 * x, 1e-3 * y),
            )
        free = np.setdiff1d(np.arange(body.n_dofs), fixed.dofs)
        Kff = K[free][:, free].tocsc()
        rhs = -K[free][:, fixed.dofs] @ fixed.values
        times = {}
        runs = [("MMD_AT_PLUS_A", True), ("COLAMD", True)]
        if pivoting or (order == 1 and name.startswith("rectangle")):
            runs += [("MMD_AT_PLUS_A", False), ("COLAMD", False)]
        for ordering, sym in runs:
            t, lu = _best(
                lambda o=ordering, s=sym, A=Kff: factorise(A, ordering=o, symmetric=s),
                repeat if sym else 1,
            )
            times[ordering, sym] = (t, _best.cpu, lu.fill)
        lu = factorise(Kff)
        t_sol, u = _best(lambda lu=lu, rhs=rhs: lu.solve(rhs), repeat)
        res = np.linalg.norm(Kff @ u - rhs) / np.linalg.norm(rhs)
        t_mmd, c_mmd = times["MMD_AT_PLUS_A", True][:2]
        total = t_basis + t_asm + t_mmd + t_sol
        print(
            f"P{order} {name}: {body.n_dofs} DOFs; mesh+basis {t_basis:.3f} s, assembly "
            f"{t_asm:.3f} s, solve {t_sol:.3f} s (residual {res:.1e}); total with MMD sym "
            f"{total:.3f} s"
        )
        for (ordering, sym), (t, c, fill) in times.items():
            print(
                f"   factor {ordering:14s} {'sym' if sym else 'piv'}  wall {t:7.3f} s  "
                f"cpu {c:7.3f} s  fill {fill / 1e6:6.2f} M  cpu x{c / c_mmd:5.2f} of MMD sym"
            )
        if order == 2 and not pivoting:
            print("   (partial pivoting skipped for P2: minutes at this size; --pivoting runs it)")
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer refinements")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many timings")
    parser.add_argument(
        "--pivoting", action="store_true", help="also factorise P2 with partial pivoting (slow)"
    )
    args = parser.parse_args()
    mesh_refinement(args.quick)
    time_refinement(args.quick)
    big_static(args.repeat, args.pivoting)


if __name__ == "__main__":
    main()
