"""What a state must satisfy besides zero net force to be returned as an equilibrium.

* **Rigidity by rank** (:func:`floppy_modes`): the rank of the rigidity matrix restricted to
  the free coordinates, evaluated at a *generic* configuration (the positions moved by a
  fixed pseudo-random 10 % of the mean rest length), so that a dangling node or a hinge
  that passes Maxwell's count is found, while an accidentally collinear start is not
  mistaken for a mechanism. Cached per topology, stiffness pattern, pins and clamps.
* **Second order** (:func:`lowest_curvature`): the smallest eigenvalue of the reduced
  Hessian of the Lagrangian ``Q^T D^-1/2 W D^-1/2 Q`` (``Q`` a basis of the clamps'
  tangent space, and orthogonal to the rigid motions when nothing is pinned; ``D`` the
  node stiffness ``sum k``): negative at a saddle.
* **No collapsed spring** (:func:`collapsed_springs`): a spring with ``k > 0`` at length
  ``<= 1e-9 L`` exerts a force whose direction is undefined (taken as zero), so a state
  with one is not an equilibrium however small its residual.

:func:`refuse_floppy` raises before a solve when Maxwell's count or the rank finds a
floppy problem. And, for the message of a solve that stops short, :func:`roundoff_floor`
and :func:`clamp_roundoff_floor`: the residual and the clamp error that float64 cannot
resolve at a state.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..linalg.kkt import factor_spd
from ..linalg.memo import per_array, per_network
from .arguments import lone_nodes
from .constraints import Problem, clamp_tensions
from .hessian_ladder import shifted
from .lagrangian import Frame, lagrangian_blocks, lagrangian_hessian
from .length_jacobian import length_jacobian
from .model import SpringNetwork
from .rigidity import count_zero_modes
from .trust_model import null_basis, rigid_motions

__all__ = [
    "CURVATURE_DENSE_MAX",
    "RANK_MAX",
    "clamp_roundoff_floor",
    "collapse_note",
    "collapsed_springs",
    "escape_direction",
    "floppy_modes",
    "lowest_curvature",
    "refuse_floppy",
    "roundoff_floor",
]

RANK_MAX = 20_000  # free coordinates up to which rigidity is checked by rank
CURVATURE_DENSE_MAX = 1200  # dense eigenvalues of the reduced Hessian up to this size
_NONE = np.empty(0, dtype=np.int64)
_NONE.setflags(write=False)


def _generic(net: SpringNetwork) -> NDArray:
    """``net.positions`` moved by a fixed pseudo-random 10 % of the mean rest length."""
    i = np.arange(net.n_nodes)
    angle = 2.399963229728653 * i  # golden angle: a deterministic, generic pattern
    radius = 0.1 * float(np.mean(net.rest_length)) * np.sqrt(((i * 0.6180339887) % 1.0) + 0.1)
    return net.positions + radius[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)


def floppy_modes(problem: Problem) -> int:
    """Internal zero modes of ``problem`` by rank at a generic configuration (0 when rigid).

    Rows: springs with ``k > 0`` and clamped springs; columns: free coordinates. Above
    :data:`RANK_MAX` free coordinates the check is skipped (returns 0): Maxwell's count and
    the factorisations still catch most mechanisms there.
    """
    net = problem.net
    n_free = int(problem.free_flat.size)
    if n_free == 0 or n_free > RANK_MAX:
        return 0
    rows = net.stiffness > 0
    rows[problem.clamp_springs] = True
    key = (net.n_nodes, problem.free.tobytes(), rows.tobytes())
    per = per_array(net.springs, "floppy_modes")
    if key not in per:
        per[key] = count_zero_modes(
            net, problem.free, problem.clamp_springs, _generic(net), rtol=1e-9
        )
    return int(per[key])


def collapsed_springs(problem: Problem, x: NDArray) -> NDArray[np.int64]:
    """Springs with ``k > 0`` whose length at ``x`` is ``<= 1e-9`` of their rest length."""
    net = problem.net
    short = net.lengths(x) <= 1e-9 * net.rest_length
    if not np.count_nonzero(short):  # the common case, without the index search
        return _NONE
    return np.flatnonzero(short & (net.stiffness > 0))


def collapse_note(collapsed: NDArray[np.int64]) -> str:
    """What a message says of the :func:`collapsed_springs` ``collapsed`` (first five)."""
    return (
        f"springs {collapsed[:5].tolist()} collapsed to zero length (k > 0: their force "
        "has no direction)"
    )


def _node_scale(problem: Problem) -> NDArray:
    """Each flat coordinate's node stiffness ``kappa_i = sum_j k_j`` over its springs and
    rods (2 n_nodes,; 0 replaced by the largest, or 1): the reduced Hessian's scaling."""
    net = problem.net
    springs, k, _ = problem.all_springs()
    kappa = np.bincount(springs[:, 0], k, net.n_nodes) + np.bincount(springs[:, 1], k, net.n_nodes)
    kappa[kappa <= 0] = max(float(kappa.max(initial=0.0)), 1.0)
    return np.repeat(kappa, 2)


def _reduced(problem: Problem, x: NDArray) -> tuple[NDArray, NDArray, Frame, NDArray]:
    """Scaled reduced Hessian ``H`` (dense), the basis ``Q``, the frame and ``D^-1/2``."""
    net = problem.net
    frame = Frame(net, problem.free, sparse_solver=problem.sparse_solver)
    coords = frame.coords
    inv_root = 1.0 / np.sqrt(_node_scale(problem)[coords])
    m = problem.n_clamps if problem.exact else 0
    g = problem.gradient(x).ravel()[coords]
    rows = []
    if m:
        A = problem.clamp_jacobian(x, coords, dense=True)
        mu = clamp_tensions(A, g, problem.scale[coords])
        rows.append(A)
    else:
        mu = np.empty(0)
    if problem.free.all():  # nothing pinned: rigid motions are not modes to judge
        rows.append(rigid_motions(x, coords))
    Q = null_basis(np.vstack(rows) * inv_root[None, :]) if rows else np.eye(coords.size)
    W = frame.pattern.assemble_dense(lagrangian_blocks(problem, x, mu, 0.0))
    Ws = W * inv_root[:, None] * inv_root[None, :]
    H = Q.T @ Ws @ Q
    return 0.5 * (H + H.T), Q, frame, inv_root


def lowest_curvature(problem: Problem, x: NDArray, threshold: float = 0.0) -> float | None:
    """Smallest eigenvalue of the scaled reduced Hessian at ``x`` (dimensionless: relative
    to each node's stiffness), or +inf when it is shown to be above ``-threshold``.

    That test is a positive-definite factorisation of ``W + rho A^T A + threshold K``
    (``K`` the node stiffnesses): on the clamps' tangent space it is the reduced
    Hessian's own test, so its success proves the bound. It is made first with
    ``threshold > 0``, and above :data:`CURVATURE_DENSE_MAX` free coordinates; otherwise,
    or where it fails, the dense eigenvalue decides up to that size, and above it None is
    returned. A plain sign test refused a 1013-node mesh at a scaled eigenvalue of
    -1.5e-10, which the dense rule accepts. On a 24 x 18 lattice (k over 9 decades, a
    clamp at strain -0.3) the dense eigenvalues took 190 of 228 ms of a relax (the
    second-order check of :func:`~.escapes.second_order`); the factorisation about 1 ms.
    """
    size = problem.free_flat.size
    if size == 0:
        return np.inf
    dense = size <= CURVATURE_DENSE_MAX
    if (threshold > 0.0 or not dense) and _above(problem, x, threshold):
        return np.inf
    if dense:
        H = _reduced(problem, x)[0]
        return float(np.linalg.eigvalsh(H)[0]) if H.size else np.inf
    return None


def _above(problem: Problem, x: NDArray, threshold: float) -> bool:
    """True when ``W + rho A^T A + threshold K`` at ``x`` is positive definite (see
    :func:`lowest_curvature`)."""
    net = problem.net
    frame = Frame(net, problem.free, sparse_solver=problem.sparse_solver)
    coords = frame.coords
    mu = np.empty(0)
    if problem.exact:
        g = problem.gradient(x).ravel()[coords]
        A = problem.clamp_jacobian(x, coords)
        mu = clamp_tensions(A, g, problem.scale[coords])
    rho = 100.0 * float(np.max(net.stiffness)) if problem.exact else 0.0
    W = lagrangian_hessian(problem, x, mu, rho=rho, frame=frame)
    if threshold > 0.0:
        W = shifted(W, threshold, _node_scale(problem)[coords])
    return factor_spd(W, ordered=frame.ordered, sparse_solver=frame.sparse_solver) is not None


def escape_direction(problem: Problem, x: NDArray) -> NDArray | None:
    """A unit move (n_nodes, 2) along the reduced Hessian's lowest eigenvector, in length
    units of the mean rest length; None when the problem is too large for dense
    eigenvectors."""
    if problem.free_flat.size > CURVATURE_DENSE_MAX:
        return None
    H, Q, frame, inv_root = _reduced(problem, x)
    vecs = np.linalg.eigh(H)[1]
    move = (Q @ vecs[:, 0]) * inv_root
    move /= max(float(np.max(np.abs(move))), 1e-300)
    return frame.put(move) * float(np.mean(problem.net.rest_length))


def _rounded_copies(x: NDArray, copies: int):
    """``2 copies`` copies of ``x`` with every coordinate moved by exactly one rounding
    unit (``np.nextafter``), in fixed pseudo-random directions and in the opposite ones."""
    rng = np.random.default_rng(0)
    for _ in range(copies):
        up = rng.random(x.shape) < 0.5
        for direction in (np.where(up, np.inf, -np.inf), np.where(up, -np.inf, np.inf)):
            yield np.nextafter(x, direction)


def roundoff_floor(problem: Problem, x: NDArray, copies: int = 8) -> float:
    """The relative imbalance that rounding alone makes at ``x`` (n_nodes, 2): the largest
    change of ``|F_ic| / f_i`` (:meth:`~.constraints.Problem.residual`'s measure) over
    ``copies`` pairs of copies of ``x`` with every coordinate moved by exactly one rounding
    unit (``np.nextafter``), in fixed pseudo-random directions and in the opposite ones.
    A residual within a few times it cannot be reduced in float64 (a solver's iterates
    carry several rounding units). Two clamped springs folded onto each other at a soft
    node fix their tensions only through an angle of 6e-7 rad: there one rounding unit
    moves the residual by up to 2.3e-13 (``benchmarks/bench_family.py --seed 4``, network
    406), against 6e-15 at the same lattice relaxed at its rest lengths. What moves the
    residual is the difference of two neighbours' coordinates, which moves only where
    their directions differ: single random moves at that state gave 5e-14 to 2.1e-13."""
    coords = problem.free_flat
    if not coords.size:
        return 0.0
    scale = problem.scale[coords]
    force = problem.unbalanced_force(x, coords)[0]
    worst = 0.0
    for moved in _rounded_copies(x, copies):
        change = problem.unbalanced_force(moved, coords)[0] - force
        worst = max(worst, float(np.max(np.abs(change) / scale)))
    return worst


def clamp_roundoff_floor(problem: Problem, x: NDArray, copies: int = 8) -> float:
    """The relative clamp error that rounding alone makes at ``x`` (n_nodes, 2): the
    largest change of ``|r_c - l_c| / L_c`` (the stop rule's measure, ``L_c`` the clamped
    spring's rest length) over the copies of :func:`roundoff_floor`; 0 without clamps.

    A clamp error within a few times it cannot be reduced in float64. Learning that
    drives rest lengths apart reaches it: on a 10-node patch whose GPC rule had grown one
    clamped spring to 2.7e9 (coordinates up to 1.7e9), another of rest length 249 was
    held at a relative error of 2.0e-10 against a floor of 9.6e-10 (the paper scene: the
    trust region collapsed there, against tol 1e-10, with the net forces at 1e-15).
    """
    if not problem.n_clamps:
        return 0.0
    scale = problem.net.rest_length[problem.clamp_springs]
    error = problem.clamp_violation(x)
    worst = 0.0
    for moved in _rounded_copies(x, copies):
        change = problem.clamp_violation(moved) - error
        worst = max(worst, float(np.max(np.abs(change) / scale)))
    return worst


def dependent_clamps(problem: Problem, x: NDArray, tol: float = 1e-6) -> NDArray[np.int64]:
    """Clamped springs whose unit length gradients on the free coordinates are linearly
    dependent at ``x`` (n_nodes, 2) to within ``tol`` (a singular value of the unit rows),
    (k,) spring indices, empty if none: no finite clamp tensions balance a force across
    them. Two clamped springs in a straight line between pinned nodes, their lengths
    adding up to the distance, hold the middle node only to first order; met to the
    solvers' 1e-14, their lengths leave it ~1e-7 off the line (singular value 1e-7)."""
    none = np.empty(0, dtype=np.int64)
    if problem.n_clamps < 2 or not problem.exact:
        return none
    # the length gradients on the clamps' own free coordinates only, dense: no (m, n)
    # sparse Jacobian (0.4-0.6 ms of scipy.sparse overhead at 1e3-1e4 nodes, 2 clamps)
    pairs = problem.net.springs[problem.clamp_springs]
    nodes = np.unique(pairs)
    if nodes.size == pairs.size:  # no shared node: the rows are orthogonal (or zero)
        return none
    own = (2 * nodes[:, None] + np.arange(2)).ravel()
    own = own[problem.free.ravel()[own]]
    column = np.full(2 * problem.net.n_nodes, -1, dtype=np.int64)
    column[own] = np.arange(own.size)
    A = length_jacobian(x, pairs, column, own.size, dense=True)
    gram = A @ A.T
    norms = np.sqrt(np.diag(gram))
    keep = norms > 0
    if np.count_nonzero(keep) < 2:
        return none
    unit = gram[np.ix_(keep, keep)] / np.outer(norms[keep], norms[keep])
    values, vectors = np.linalg.eigh(unit)  # the unit rows' squared singular values
    small = values < tol**2
    if not small.any():
        return none
    involved = np.abs(vectors[:, small]).max(axis=1) > 0.1
    return problem.clamp_springs[keep][involved].astype(np.int64)


def refuse_floppy(problem: Problem) -> None:
    """Refuse a floppy problem (Maxwell's count, lone nodes, the rigidity rank); a pin mask
    and clamp set that passed is remembered while the network lives (read-only arrays)."""
    net = problem.net
    passed = per_network(net, "rigid")  # the pin masks and clamp sets that passed
    key = (problem.free.tobytes(), problem.clamp_springs.tobytes())
    if key in passed:
        return
    floppy = problem.maxwell_zero_modes()
    if floppy:
        raise ValueError(
            f"network is floppy: at least {floppy} zero modes beyond rigid motion "
            f"({int(problem.free.sum())} free coordinates, {int((net.stiffness > 0).sum())} "
            f"springs with k > 0, {problem.n_clamps} clamps); add springs or pins"
        )
    lone_nodes(net, problem.free)
    _refuse_by_rank(problem)
    passed[key] = True


def _refuse_by_rank(problem: Problem) -> None:
    """Raise a clear error when the rigidity matrix is rank deficient (generic positions)."""
    modes = floppy_modes(problem) - max(0, 3 - (problem.free.size - np.count_nonzero(problem.free)))
    if modes <= 0:
        return
    net = problem.net
    stiff = net.stiffness > 0
    degree = np.bincount(net.springs[stiff].ravel(), minlength=net.n_nodes)
    degree += np.bincount(net.springs[problem.clamp_springs].ravel(), minlength=net.n_nodes)
    free_nodes = problem.free.any(axis=1)
    dangling = np.flatnonzero(free_nodes & (degree < 2))
    where = (
        f"; nodes with fewer than two springs: {dangling[:8].tolist()}"
        if dangling.size
        else " (a hinge or a floppy region: rigid parts joined by fewer than three springs)"
    )
    raise ValueError(
        f"network is floppy: {modes} zero modes beyond rigid motion by the rank of the "
        f"rigidity matrix, though Maxwell's count passes{where}; add springs or pins"
    )
