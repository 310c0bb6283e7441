"""The linear modes of a physical_time medium after the source step: the slowest-mode
time, and which mode sets the target's settling time ``tau`` (why ``tau`` does not follow
the slowest mode).

``physical_time`` measures ``tau``: the time for the target strain to settle within 1 %
of its total change after a local source step. The ``relaxation`` scene reports the
slowest-mode time ``1 / lambda_min`` of ``C u' + K u = 0`` under a global step (one side
held, the other moved). Here, linear about the unstressed initial state, with the free-DOF
``K`` and ``C`` and the source clamp either holding DOFs (removed) or a constraint ``G u =
0`` on the deviation, the deviation ``d0`` from the clamped equilibrium just after the
step is expanded in the ``C``-orthonormal modes, ``d(t) = sum_i a_i phi_i exp(-lambda_i
t)``, ``a_i = phi_i^T C d0``, and the read-out ``g d(t) = sum_i c_i exp(-lambda_i t)``,
``c_i = (g phi_i) a_i`` (:func:`modal_response`):

* ``tau_mode = 1 / lambda_1``; ``displacement_share = a_1^2 / d0^T C d0``, the slowest
  mode's share of the step's (dissipation-weighted) displacement;
* weights ``w_i = |c_i| / |Delta|``, each mode's term in the read-out over the total change
  ``Delta`` the 1 % criterion scales with: ``slow_weight = w_1``; the setting mode, the one
  with the largest ``tau_i ln(w_i / 0.01)`` (when it alone would fall inside the band),
  its time ``setting_time`` and ``setting_weight``; ``cancellation = sum_i w_i`` (1 when
  every term has one sign, large when the terms nearly cancel and ``Delta`` is small);
* ``tau_modal``: the 1 % settling time of the whole modal sum (the linear prediction of
  ``tau``).

:func:`network_modes` (the lattice: free Hessian, drag ``c I`` plus the dashpots, the
source spring a chord-strain constraint as the run holds it (a rod) and as the body holds
its material spring; beside it the slowest-mode time with the source's end nodes held, and
with the body's edges, :func:`edge_weights`), :func:`body_modes` (the body: ``K_ff``,
``C_ff`` with the task's fixed DOFs, the source material spring a constraint) and
:func:`global_step_share` (the relaxation scene's drive on the same lattice, the read-out
every free coordinate) return plain dicts for the task unit's meta.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from ..network.length_jacobian import strain_jacobian

__all__ = [
    "body_modes",
    "edge_weights",
    "global_step_share",
    "modal_response",
    "network_modes",
    "slowest_mode",
]


def _constrained_solver(K: sp.spmatrix, G: sp.spmatrix | None):
    """``x -> y`` with ``K y + G^T mu = x``, ``G y = 0`` (``K`` SPD; ``G`` None: ``K^-1``)."""
    from scipy.sparse.linalg import splu

    lu = splu(sp.csc_matrix(K))
    if G is None or G.shape[0] == 0:
        return lu.solve
    Gd = np.atleast_2d(G.toarray() if sp.issparse(G) else np.asarray(G, float))
    KiGt = lu.solve(np.ascontiguousarray(Gd.T))
    S = Gd @ KiGt

    def solve(x: NDArray) -> NDArray:
        y = lu.solve(np.asarray(x, float))
        return y - KiGt @ np.linalg.solve(S, Gd @ y)

    return solve


def slowest_mode(
    K: sp.spmatrix, C: sp.spmatrix, G: sp.spmatrix | None = None
) -> tuple[float, NDArray]:
    """``(lambda_min, phi)``: the slowest mode of ``C u' + K u = 0`` on ``G u = 0`` (``K``
    positive definite on the free DOFs, ``C`` positive definite), ``phi^T C phi = 1``.

    Shift-invert Lanczos at 0 with the constrained inverse of ``K`` (:func:`_constrained_solver`):
    ``S C phi = phi / lambda``; dense ``eigh`` below 4 DOFs."""
    from scipy.sparse.linalg import LinearOperator, eigsh

    from ..linalg.spd import fixed_vector

    K, C = sp.csc_matrix(K), sp.csc_matrix(C)
    n = K.shape[0]
    solve = _constrained_solver(K, G)
    if n < 4:  # ARPACK needs k < n: the constrained inverse as a dense matrix
        from scipy.linalg import eigh

        S = np.column_stack([solve(e) for e in np.eye(n)])
        Cd = C.toarray()
        mu, vec = eigh(Cd @ S @ Cd, Cd)  # C S C v = mu C v: mu = 1 / lambda
        lam, phi = 1.0 / mu[-1], vec[:, -1]
    else:
        op = LinearOperator((n, n), matvec=solve, dtype=float)
        v0 = solve(C @ fixed_vector(n))  # in the constrained space
        mu, vec = eigsh(K, k=1, M=C, sigma=0.0, which="LM", OPinv=op, v0=v0)
        lam, phi = float(mu[0]), vec[:, 0]
    if not lam > 0:
        raise ValueError(f"the slowest mode does not decay (lambda_min = {lam:.3e}): fix more DOFs")
    phi = phi / math.sqrt(float(phi @ (C @ phi)))
    return float(lam), phi


def _basis(G, n: int) -> NDArray | None:
    """An orthonormal basis (n, n - m) of ``G u = 0`` (None without constraints)."""
    if G is None or G.shape[0] == 0:
        return None
    from scipy.linalg import null_space

    return null_space(np.atleast_2d(G.toarray() if sp.issparse(G) else np.asarray(G, float)))


def modal_response(
    K: sp.spmatrix,
    C: sp.spmatrix,
    d0: NDArray,
    g: sp.spmatrix | NDArray,
    change: NDArray,
    G: sp.spmatrix | None = None,
    *,
    fraction: float = 1e-2,
    dense_limit: int = 2500,
) -> dict[str, float]:
    """The modal expansion of a relaxation ``d(t)`` from ``d0`` (``d0`` on ``G u = 0``) and
    its read-out ``g d(t)`` against the 1 % criterion on ``change`` (module docstring).

    All modes (dense generalised ``eigh`` on the constrained space) up to ``dense_limit``
    DOFs; above it only ``tau_mode`` (:func:`slowest_mode`) and the slowest mode's shares,
    the rest NaN. Returns ``tau_mode``, ``displacement_share``, ``slow_weight``,
    ``setting_time``, ``setting_weight``, ``cancellation`` and ``tau_modal``.
    """
    from scipy.linalg import eigh

    from ..network.dynamics import settling_time

    total = float(np.linalg.norm(np.atleast_1d(change)))
    norm = float(d0 @ (C @ d0))
    nan = math.nan
    if K.shape[0] > dense_limit:
        lam, phi = slowest_mode(K, C, G)
        a = float(phi @ (C @ d0))
        return {
            "tau_mode": 1.0 / lam,
            "displacement_share": a * a / norm if norm > 0 else nan,
            "slow_weight": float(np.linalg.norm(np.atleast_1d(g @ phi))) * abs(a) / total,
            "setting_time": nan, "setting_weight": nan, "cancellation": nan, "tau_modal": nan,
        }  # fmt: skip
    Z = _basis(G, K.shape[0])
    Kd, Cd = K.toarray(), C.toarray()
    gd = g.toarray() if sp.issparse(g) else np.atleast_2d(np.asarray(g, float))
    if Z is not None:
        Kd, Cd, gd = Z.T @ Kd @ Z, Z.T @ Cd @ Z, gd @ Z
        d0 = Z.T @ d0  # d0 lies on G u = 0: its coordinates in the basis
    lam, V = eigh(Kd, Cd)  # V^T C V = I
    if not lam[0] > 0:
        raise ValueError(f"the slowest mode does not decay (lambda_min = {lam[0]:.3e})")
    a = V.T @ (Cd @ d0)
    c = (gd @ V) * a  # (n_targets, n_modes): each mode's term in the read-out at t = 0
    w = np.linalg.norm(c, axis=0) / total
    tau = 1.0 / lam
    reach = np.where(w > fraction, tau * np.log(np.maximum(w, fraction) / fraction), 0.0)
    i = int(np.argmax(reach))
    bound = tau[0] * math.log(max(w.sum(), fraction) / fraction)  # settled after this
    times = np.linspace(0.0, 1.05 * bound + 1e-12, 4001)
    dev = (c @ np.exp(-np.outer(lam, times))).T  # (T, n_targets): g d(t)
    end = np.zeros(dev.shape[1])
    tau_modal = settling_time(times, dev, end - np.atleast_1d(change), end, fraction)
    return {
        "tau_mode": float(tau[0]),
        "displacement_share": float(a[0] ** 2 / norm) if norm > 0 else nan,
        "slow_weight": float(w[0]),
        "setting_time": float(tau[i]),
        "setting_weight": float(w[i]),
        "cancellation": float(w.sum()),
        "tau_modal": float(tau_modal),
    }


def _network_matrices(net, viscosity, free: NDArray, *, stiffness=None, drag=None):
    """The free-DOF Hessian at the initial positions and the damping (drag ``c I``, or a
    drag per node, plus the dashpots), and the full ones (for the held columns)."""
    import dataclasses

    from ..network.energy import hessian
    from ..network.viscous import dashpot_matrix

    if stiffness is not None:
        net = dataclasses.replace(net, stiffness=stiffness)
    H = hessian(net.positions, net).tocsr()
    node = viscosity.drag * np.ones(net.n_nodes) if drag is None else np.asarray(drag, float)
    C = (
        dashpot_matrix(net.positions, net, viscosity.dashpot) + sp.diags(np.repeat(node, 2))
    ).tocsr()
    return H[free][:, free], C[free][:, free], H, C


def edge_weights(net) -> tuple[NDArray, NDArray]:
    """``(spring factor, node area)``: each spring's number of lattice triangles over 2 (1
    inside, 1/2 on the edge) and each node's area (a third of its triangles') over the
    lattice's area per node: the P1 body on the lattice's triangles is the network with
    ``k`` times the first and node drag ``c`` times the second (lumped)."""
    from ..continuum.mesh import network_faces

    t = network_faces(net, net.positions)
    x = net.positions
    e1, e2 = x[t[:, 1]] - x[t[:, 0]], x[t[:, 2]] - x[t[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    node = np.bincount(t.ravel(), weights=np.repeat(area / 3.0, 3), minlength=net.n_nodes)
    n = net.n_nodes
    edges = np.sort(np.vstack([t[:, [0, 1]], t[:, [1, 2]], t[:, [0, 2]]]), axis=1)
    count = np.bincount(edges[:, 0] * n + edges[:, 1], minlength=n * n)
    s = np.sort(net.springs, axis=1)
    return count[s[:, 0] * n + s[:, 1]] / 2.0, node / (math.sqrt(3.0) / 2.0)


def network_modes(
    net, task, viscosity, *, fraction: float = 1e-2, clamp: str = "strain"
) -> dict[str, float]:
    """The lattice's modes after the source step (module docstring).

    Linear about the initial positions (unstressed). ``clamp="strain"`` (default, as
    :func:`~continuum_vs_network.learning.physical_time.network_relaxation_time` runs it):
    the source springs are chord-strain constraints ``G u = S`` (the body's form of the
    clamp; the run's rods), the pins held; the ``C``-weighted jump onto the constraint
    relaxes to the constrained equilibrium, as :func:`body_modes`. ``clamp="nodes"``: the
    source springs' end nodes are held and stepped half each way along the spring to the
    clamp length (as :func:`~continuum_vs_network.network.dynamics.simulate_viscous` holds a
    clamp), the pins held; the free nodes jump by ``-C_ff^-1 C_fh u_h`` (none with drag
    only) and relax to ``-K_ff^-1 K_fh u_h``. The targets' strains are read.
    :func:`modal_response`'s keys (for ``clamp``), the slowest-mode times with the source
    springs as chord-strain constraints (``tau_mode_constraint``) and with held end nodes
    (``tau_mode_nodes``), and ``tau_mode_edges``: the constraint with the edge springs
    halved and the drag by node area as well (:func:`edge_weights`: the body's matrices,
    lumped)."""
    if clamp not in ("strain", "nodes"):
        raise ValueError(f"clamp must be 'strain' or 'nodes', got {clamp!r}")
    from scipy.sparse.linalg import splu

    from ..linalg.kkt import factor_kkt

    held = task.pinned.copy()
    u = np.zeros((net.n_nodes, 2))
    x = net.positions
    for s, length in task.source_clamps(net).items():
        a, b = net.springs[s]
        d = x[b] - x[a]
        r = float(np.hypot(*d))
        grow = (length - r) * d / r
        u[a], u[b] = -0.5 * grow, 0.5 * grow
        held[[a, b]] = True
    free = ~held.ravel()
    Kff, Cff, H, C = _network_matrices(net, viscosity, free)
    uh = u.ravel()[~free]
    u_eq = -splu(Kff.tocsc()).solve(H[free][:, ~free] @ uh)
    jump = -splu(Cff.tocsc()).solve(C[free][:, ~free] @ uh) if viscosity.dashpot > 0 else 0.0
    g = strain_jacobian(net.positions, net.springs[task.targets]).tocsc()[:, free]
    nodes = modal_response(Kff, Cff, jump - u_eq, g, g @ u_eq, fraction=fraction)
    pins = ~task.pinned.ravel()
    Gs = strain_jacobian(net.positions, net.springs[task.sources]).tocsc()[:, pins]
    Kp, Cp, _, _ = _network_matrices(net, viscosity, pins)
    if clamp == "strain":
        clamps = task.source_clamps(net)
        r = net.lengths(x, np.array(list(clamps), dtype=int))
        S = np.array(list(clamps.values())) / r - 1.0
        zero = np.zeros(Kp.shape[0])
        jump_s, _ = factor_kkt(Cp.tocsc(), Gs).solve(zero, S)
        end_s, _ = factor_kkt(Kp.tocsc(), Gs).solve(zero, S)
        gp = strain_jacobian(net.positions, net.springs[task.targets]).tocsc()[:, pins]
        out = modal_response(Kp, Cp, jump_s - end_s, gp, gp @ end_s, Gs, fraction=fraction)
        out["tau_mode_constraint"] = out["tau_mode"]
    else:
        out = nodes
        out["tau_mode_constraint"] = 1.0 / slowest_mode(Kp, Cp, Gs)[0]
    out["tau_mode_nodes"] = nodes["tau_mode"]
    factor, area = edge_weights(net)
    Ke, Ce, _, _ = _network_matrices(
        net, viscosity, pins, stiffness=net.stiffness * factor, drag=viscosity.drag * area
    )
    out["tau_mode_edges"] = 1.0 / slowest_mode(Ke, Ce, Gs)[0]
    return out


def body_modes(body, task, damping, *, fraction: float = 1e-2) -> dict[str, float]:
    """The body's modes after the source step (module docstring).

    The state of :func:`~continuum_vs_network.continuum.damped_states.body_relaxation_time`
    (linear): from ``u0`` (sources at zero strain) the ``C``-weighted jump onto the source
    clamps ``G_s u = S_s``, relaxing to the clamped equilibrium; ``K_ff`` and ``C_ff``
    without the task's fixed DOFs, the source material springs a constraint, the target
    material springs read. Drag and Kelvin-Voigt viscosity (no Maxwell arm).
    :func:`modal_response`'s keys."""
    import dataclasses

    from ..continuum.damped_states import DampedStepper
    from ..continuum.damping import damping_matrix
    from ..linalg.kkt import factor_kkt

    if damping.has_arm:
        raise ValueError("body_modes: a Maxwell arm adds internal modes; drag and viscosity only")
    stepper = DampedStepper(body, task, damping, 1.0)
    free = stepper.free
    K = body.stiffness()[free][:, free].tocsc()
    C = damping_matrix(body.body, damping)[free][:, free].tocsc()
    ns = task.n_sources
    Gs, g = stepper.G[:ns], stepper.G[ns:]
    off = dataclasses.replace(task, source_strain=np.zeros(ns))
    u0 = body.free_state(off).u[free]
    jump, _ = factor_kkt(C, Gs).solve(np.zeros(free.size), task.source_strain - Gs @ u0)
    end, _ = factor_kkt(K, Gs).solve(body.load()[free], np.asarray(task.source_strain, float))
    return modal_response(K, C, u0 + jump - end, g, g @ (end - u0), Gs, fraction=fraction)


def global_step_share(net, viscosity, *, side: float = 0.6) -> dict[str, float]:
    """The relaxation scene's drive on the same lattice: the nodes within ``side`` of the
    left edge held, those within ``side`` of the right edge stepped by ``-1 %`` of the
    width in x; read-out: every free coordinate's displacement, the criterion on the
    displacement's norm. :func:`modal_response`'s keys."""
    from scipy.sparse.linalg import splu

    x = net.positions
    left = x[:, 0] < x[:, 0].min() + side
    right = x[:, 0] > x[:, 0].max() - side
    held = np.repeat(left | right, 2)
    u = np.zeros((net.n_nodes, 2))
    u[right, 0] = -0.01 * float(np.ptp(x[:, 0]))
    free = ~held
    Kff, Cff, H, C = _network_matrices(net, viscosity, free)
    uh = u.ravel()[held]
    u_eq = -splu(Kff.tocsc()).solve(H[free][:, held] @ uh)
    jump = -splu(Cff.tocsc()).solve(C[free][:, held] @ uh) if viscosity.dashpot > 0 else 0.0
    return modal_response(Kff, Cff, jump - u_eq, sp.identity(Kff.shape[0]), u_eq)
