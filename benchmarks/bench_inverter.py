"""Cross-check of the package's SIMP force inverter against an independent textbook code.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_inverter.py [--nelx 60] [--iterations 200]``.

Reference (the textbook force inverter: Sigmund 1997; Bendsøe & Sigmund 2003, sec. 2.6
and the 99-line code's mechanism modification, in the 88-line code's form of Andreassen
et al. 2011), written here from scratch on numpy/scipy in :func:`textbook_inverter`,
importing nothing of the package:

* Q4 bilinear plane-stress elements (``E = 1``, ``nu = 0.3``, unit thickness) on a
  ``nelx x nely`` grid of unit squares, ``nely = nelx / 2``: the upper half of the
  symmetric inverter, the symmetry line at the top (``u_y = 0`` there);
* the two lowest nodes of the left edge fixed (both components);
* input force ``f_in = 1`` in ``+x`` at the top-left node, input spring ``k_in = 0.1`` there,
  output spring ``k_out = 0.1`` on ``u_x`` of the top-right node;
* objective: minimise ``u_out`` (the output should move in ``-x``, against the input),
  adjoint ``K lambda = e_out``;
* SIMP ``E(x) = E_min + x^3 (1 - E_min)``, ``E_min = 1e-9`` (the textbook's ``x_min = 1e-3``
  cubed), volume fraction 0.3, density filter with cone weights ``rmin - dist`` (radius
  ``rmin = 1.5`` elements), OC with damping 0.3, move 0.1 and the floor
  ``max(1e-10, -dc)`` of the textbook's mechanism variant.

These are the settings of the textbook case as implemented in public code, e.g.
stefanhiemer/topoptlab ``topoptlab/example_bc/lin_elast.py::forceinverter_2d`` ("Force
inverter as example case for compliant mechanisms. Example case taken from the standard TO
textbook by Sigmund and Bendsoe page 269"): symmetry on the top row's ``u_y``, the bottom
two nodes of the left edge fixed, ``f[0] = 1`` at the top-left ``u_x``, springs
``[0, 2*nelx*(nely+1)]`` of stiffness ``[0.1, 0.1]``; its driver
(``examples/topology_optimization/compliant_mechanisms/force_inverter2d.py``) runs
``nelx = 120, nely = 60, volfrac = 0.3, penal = 3``, ``E_min = 1e-9``, a density filter,
OC, 200 iterations. pyMOTO's spring example (aatmdelissen/pyMOTO,
``examples/topology_optimization/ex_compliant_mechanism_springs.py``, after Bendsøe &
Sigmund 2003) uses ``volfrac 0.3``, ``filter_radius 2``, MMA, and warns that the spring
formulation converges with difficulty ("the inverter requires the displacement (initially
positive) to pass trough zero in order to become negative"). Neither quotes a number for
``u_out``; the published behaviour is qualitative: the uniform plate's output moves with
the input (``u_out > 0``), the optimised one's against it (``u_out < 0 < u_in``). The
magnitude of the geometric advantage ``-u_out / u_in`` depends on the springs (with
``k_in = k_out = 0.1`` the input spring is soft and ``u_in`` large, so the advantage is well
below one), the volume and the mesh; no reference value is hand-written here: this script
computes the textbook code's value in the same run as the package's and prints the ratio.

The package (:func:`package_inverter`) runs
:func:`continuum_vs_network.continuum.topology.simp_inverter` on the same half model at
the closest settings it allows: the ``2 x 1`` rectangle meshed by structured P1 triangles of
size ``h = 2 / nelx`` (two triangles per textbook square), symmetry at the top, one
corner node fixed (the textbook fixes two), the same force, springs, ``E_min``, volume
fraction, penalty and OC (damping 0.3, move 0.1), filter radius ``rmin * h`` in length
units, the same iteration count. In 2D plane stress the stiffness matrix of a mesh is
invariant under a uniform scaling of lengths (``K ~ E t``, no length), so the package's
``2 x 1`` body and the textbook's ``nelx x nely`` grid of unit squares have the same
force/displacement units and their ``u_in``, ``u_out`` compare directly. Differences that
remain: P1 triangles (stiffer in bending than Q4) and one fixed node instead of two.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

# the reference's settings (the textbook inverter)
VOLFRAC = 0.3
PENAL = 3.0
RMIN = 1.5  # elements
K_IN = 0.1
K_OUT = 0.1
F_IN = 1.0
E_MIN = 1e-9
NU = 0.3


def _q4_stiffness(nu: float = NU) -> np.ndarray:
    """Element stiffness (8, 8) of a unit-square Q4, plane stress, ``E = 1``, unit thickness;
    DOFs ``(x, y)`` of the nodes counter-clockwise from the lower left."""
    # 2 x 2 Gauss quadrature of B^T D B on the reference square [-1, 1]^2 (Jacobian 1/2)
    D = np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1.0 - nu) / 2]]) / (1 - nu**2)
    xi_n = np.array([-1.0, 1.0, 1.0, -1.0])
    eta_n = np.array([-1.0, -1.0, 1.0, 1.0])
    KE = np.zeros((8, 8))
    g = 1.0 / np.sqrt(3.0)
    for xi in (-g, g):
        for eta in (-g, g):
            dN_dxi = 0.25 * xi_n * (1 + eta * eta_n)
            dN_deta = 0.25 * eta_n * (1 + xi * xi_n)
            dN_dx, dN_dy = 2.0 * dN_dxi, 2.0 * dN_deta  # element side 1: d/dx = 2 d/dxi
            B = np.zeros((3, 8))
            B[0, 0::2] = dN_dx
            B[1, 1::2] = dN_dy
            B[2, 0::2] = dN_dy
            B[2, 1::2] = dN_dx
            KE += B.T @ D @ B * 0.25  # det J = 1/4, weights 1
    return KE


def textbook_inverter(
    nelx: int = 60, nely: int | None = None, *, volfrac: float = VOLFRAC,
    penal: float = PENAL, rmin: float = RMIN, k_in: float = K_IN, k_out: float = K_OUT,
    f_in: float = F_IN, e_min: float = E_MIN, iterations: int = 200, move: float = 0.1,
    damping: float = 0.3,
) -> dict:  # fmt: skip
    """The textbook inverter of the module (independent of the package).

    Returns a dict: ``u_in``, ``u_out``, ``ratio`` (``u_out / u_in``), ``u_out_initial``,
    ``u_in_initial`` (uniform density), ``history`` (u_out per iteration), ``volume``,
    ``density`` (nely, nelx; row 0 at the bottom), ``seconds``.
    """
    nely = nelx // 2 if nely is None else nely
    nx, ny = nelx + 1, nely + 1
    node = np.arange(nx * ny).reshape(ny, nx)  # node[j, i] at (i, j), j = 0 the bottom
    ll = node[:-1, :-1].ravel()  # element e = j * nelx + i, lower-left node
    corners = np.stack([ll, ll + 1, ll + 1 + nx, ll + nx], axis=1)  # counter-clockwise
    edof = np.empty((nelx * nely, 8), dtype=np.int64)
    edof[:, 0::2] = 2 * corners
    edof[:, 1::2] = 2 * corners + 1
    ndof = 2 * nx * ny
    KE = _q4_stiffness()
    iK = np.repeat(edof, 8, axis=1).ravel()
    jK = np.tile(edof, (1, 8)).ravel()

    top = node[-1, :]
    din, dout = 2 * node[-1, 0], 2 * node[-1, -1]
    fixed = np.union1d(2 * top + 1, np.concatenate([2 * node[:2, 0], 2 * node[:2, 0] + 1]))
    free = np.setdiff1d(np.arange(ndof), fixed)
    springs = sp.coo_matrix(([k_in, k_out], ([din, dout], [din, dout])), shape=(ndof, ndof))
    f = np.zeros(ndof)
    f[din] = f_in
    lvec = np.zeros(ndof)
    lvec[dout] = 1.0

    # density filter: cone weights rmin - distance between element centres (top88, ft = 2)
    cx, cy = np.meshgrid(np.arange(nelx) + 0.5, np.arange(nely) + 0.5)
    c = np.stack([cx.ravel(), cy.ravel()], axis=1)
    r = int(np.ceil(rmin))
    rows, cols, vals = [], [], []
    for di in range(-r, r + 1):
        for dj in range(-r, r + 1):
            w = rmin - np.hypot(di, dj)
            if w <= 0:
                continue
            i2, j2 = cx.ravel() - 0.5 + di, cy.ravel() - 0.5 + dj
            ok = (i2 >= 0) & (i2 < nelx) & (j2 >= 0) & (j2 < nely)
            e1 = np.flatnonzero(ok)
            rows.append(e1)
            cols.append((j2[ok] * nelx + i2[ok]).astype(np.int64))
            vals.append(np.full(e1.size, w))
    H = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(c.shape[0], c.shape[0]),
    )
    Hs = np.asarray(H.sum(axis=1)).ravel()

    def solve(xphys: np.ndarray, adjoint: bool):
        E = e_min + xphys**penal * (1.0 - e_min)
        K = sp.coo_matrix((np.outer(E, KE.ravel()).ravel(), (iK, jK)), shape=(ndof, ndof))
        K = (K + springs).tocsc()
        lu = splu(K[free][:, free].tocsc())
        u = np.zeros(ndof)
        u[free] = lu.solve(f[free])
        if not adjoint:
            return u, None
        lam = np.zeros(ndof)
        lam[free] = lu.solve(lvec[free])
        return u, lam

    x = np.full(nelx * nely, float(volfrac))
    t0 = time.perf_counter()
    history = []
    u_in0 = None
    for it in range(iterations + 1):
        xphys = (H @ x) / Hs
        last = it == iterations
        u, lam = solve(xphys, adjoint=not last)
        history.append(float(u[dout]))
        if u_in0 is None:
            u_in0 = float(u[din])
        if last:
            break
        ce = np.einsum("ei,ij,ej->e", lam[edof], KE, u[edof])
        dc = -penal * (1.0 - e_min) * xphys ** (penal - 1.0) * ce  # d u_out / d xphys
        dc = H.T @ (dc / Hs)  # through the density filter
        dv = H.T @ (np.ones_like(x) / Hs)
        lo, hi = 0.0, 1e9
        ratio = np.maximum(1e-10, -dc) / dv
        while (hi - lo) / (hi + lo) > 1e-6:
            mid = 0.5 * (lo + hi)
            xnew = np.clip(x * (ratio / mid) ** damping, np.maximum(0.0, x - move),
                           np.minimum(1.0, x + move))  # fmt: skip
            if ((H @ xnew) / Hs).sum() > volfrac * x.size:
                lo = mid
            else:
                hi = mid
        x = xnew
    xphys = (H @ x) / Hs
    return {
        "u_in": float(u[din]), "u_out": float(u[dout]), "ratio": float(u[dout] / u[din]),
        "u_in_initial": u_in0, "u_out_initial": history[0], "history": np.array(history),
        "volume": float(xphys.mean()), "density": xphys.reshape(nely, nelx),
        "seconds": time.perf_counter() - t0,
    }  # fmt: skip


def package_inverter(
    nelx: int = 60, *, volfrac: float = VOLFRAC, rmin: float = RMIN, k_in: float = K_IN,
    k_out: float = K_OUT, f_in: float = F_IN, e_min: float = E_MIN, iterations: int = 200,
) -> dict:  # fmt: skip
    """The package's :func:`~continuum_vs_network.continuum.topology.simp_inverter` at the
    closest settings (see the module): the same keys as :func:`textbook_inverter`."""
    from continuum_vs_network.continuum.learnable import learnable_body
    from continuum_vs_network.continuum.materials import Material
    from continuum_vs_network.continuum.mechanism import inverter_layout, mechanism_mesh
    from continuum_vs_network.continuum.topology import inverter_response, simp_inverter

    h = 2.0 / nelx
    body = learnable_body(mechanism_mesh(2.0, 1.0, h), Material.from_young(1.0, NU, plane="stress"))
    layout = inverter_layout(body, force=f_in, k_in=k_in, k_out=k_out)
    t0 = time.perf_counter()
    res, u_in = simp_inverter(
        body, layout, volfrac=volfrac, radius=rmin * h, iterations=iterations, e_min=e_min
    )
    u_in0 = inverter_response(
        body,
        layout,
        np.full(body.n_elements, e_min + volfrac**PENAL * (1 - e_min)),
        adjoint=False,
    )[0]
    return {
        "u_in": float(u_in), "u_out": float(res.objective[-1]),
        "ratio": float(res.objective[-1] / u_in), "u_in_initial": float(u_in0),
        "u_out_initial": float(res.objective[0]), "history": res.objective,
        "volume": res.volume, "density": res.density, "seconds": time.perf_counter() - t0,
        "n_elements": int(body.n_elements),
    }  # fmt: skip


def compare(nelx: int = 60, iterations: int = 200, **kw) -> tuple[dict, dict]:
    """Both implementations at the same settings: ``(textbook, package)``."""
    return (
        textbook_inverter(nelx, iterations=iterations, **kw),
        package_inverter(nelx, iterations=iterations, **kw),
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--nelx", type=int, default=60)
    p.add_argument("--iterations", type=int, default=200)
    p.add_argument("--rmin", type=float, default=RMIN)
    a = p.parse_args()
    ref, pkg = compare(a.nelx, a.iterations, rmin=a.rmin)
    print(
        f"force inverter, half model {a.nelx} x {a.nelx // 2} (textbook Q4; package "
        f"{pkg['n_elements']} P1 on 2 x 1), volfrac {VOLFRAC}, p {PENAL:g}, rmin {a.rmin:g} "
        f"elements, k_in {K_IN:g}, k_out {K_OUT:g}, f_in {F_IN:g}, {a.iterations} OC iterations"
    )
    rows = [
        ("u_in (uniform start)", "u_in_initial"),
        ("u_out (uniform start)", "u_out_initial"),
        ("u_in", "u_in"),
        ("u_out", "u_out"),
        ("u_out / u_in", "ratio"),
        ("volume fraction", "volume"),
        ("seconds", "seconds"),
    ]
    print(f"{'':24s}{'textbook':>14s}{'package':>14s}{'package/textbook':>18s}")
    for label, key in rows:
        r, q = ref[key], pkg[key]
        print(f"{label:24s}{r:14.5g}{q:14.5g}{q / r:18.4g}")
    for name, d in (("textbook", ref), ("package", pkg)):
        work = F_IN * d["u_in"]  # input compliance f_in u_in
        out = K_OUT * abs(d["u_out"])  # force on the output spring
        print(
            f"{name:9s} input compliance f_in u_in = {work:.5g}, output force "
            f"k_out |u_out| = {out:.5g}, mechanical advantage {out / F_IN:.4g}, "
            f"geometric advantage -u_out/u_in = {-d['ratio']:.4g}"
        )
    same_sign = ref["ratio"] < 0 and pkg["ratio"] < 0
    factor = max(pkg["ratio"] / ref["ratio"], ref["ratio"] / pkg["ratio"]) if same_sign else np.inf
    print(
        f"same sign (output against input): {same_sign}; |u_out/u_in| package/textbook = "
        f"{pkg['ratio'] / ref['ratio']:.4g} (within a factor {factor:.3g})"
    )


if __name__ == "__main__":
    main()
