"""Jammed packings of soft discs (bidisperse or polydisperse) turned into spring networks.

Discs are compressed to packing fraction ``phi`` by minimising the overlap energy; the
contact network, pruned to rigidity, becomes a :class:`SpringNetwork` whose rest lengths
are the contact distances (stress-free). Lengths are in units of the small disc diameter.
Optionally springs are then removed, keeping the network rigid, down to a target excess
coordination ``dz = Z - Z_iso`` (:func:`_prune_to_coordination`).
"""

from __future__ import annotations

import logging
import math

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .. import _validate as check
from .builders import (
    _PACKING_BYTES_PER_NODE,
    _check_generator,
    _check_positive,
    _greedy_removal,
)
from .model import SpringNetwork
from .rigidity import is_rigid, rigidity_matrix

__all__ = ["jammed_network"]

_log = logging.getLogger(__name__)

_DZ_MAX_NODES = 4096  # dz needs a dense QR of the (2N, S) compatibility matrix: O(N^3)
_MIN_DEGREE = 3  # pruning for dz never takes a node below this many springs
_MIN_LOAD = 1e-2  # pruning for dz prefers springs loaded this much (see _prune_to_coordination)


def _diameters(n: int, rng: np.random.Generator, polydispersity: float | None) -> NDArray:
    if polydispersity is None:
        big = rng.permutation(n) < n // 2
        return np.where(big, 1.4, 1.0)
    delta = float(polydispersity)
    half_width = math.sqrt(3.0) * delta
    if not (math.isfinite(delta) and 0 < half_width < 1):
        raise ValueError(
            f"polydispersity must be None (bidisperse) or in (0, {1 / math.sqrt(3):.4f}), "
            f"got {polydispersity}"
        )
    return rng.uniform(1.0 - half_width, 1.0 + half_width, size=n)


class _PackingEnergy:
    """Harmonic overlap energy of soft discs in a square box with soft walls.

    ``E = sum_pairs (d_ij - r_ij)_+^2 / 2 + sum_discs sum_walls (overlap with wall)_+^2 / 2``
    with ``d_ij`` the mean diameter. A Verlet list with a skin is rebuilt when a disc has
    moved more than half the skin, so the function is exact at every call.
    """

    def __init__(self, diameters: NDArray, box: float, skin: float = 0.3) -> None:
        self.d = diameters
        self.r = diameters / 2
        self.box = box
        self.skin = skin
        self.cutoff = float(diameters.max()) + skin
        self.ref: NDArray | None = None
        self.pairs = np.empty((0, 2), dtype=np.int64)

    def _update(self, x: NDArray) -> None:
        if self.ref is None or np.max(np.abs(x - self.ref)) > 0.5 * self.skin / math.sqrt(2):
            self.pairs = cKDTree(x).query_pairs(self.cutoff, output_type="ndarray")
            self.ref = x.copy()

    def overlaps(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """Pairs with positive overlap, their separation vectors and overlaps."""
        self._update(x)
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        dvec = x[j] - x[i]
        dist = np.hypot(dvec[:, 0], dvec[:, 1])
        ov = 0.5 * (self.d[i] + self.d[j]) - dist
        hit = ov > 0
        return self.pairs[hit], dvec[hit], ov[hit]

    def __call__(self, flat: NDArray) -> tuple[float, NDArray]:
        x = flat.reshape(-1, 2)
        n = x.shape[0]
        pairs, dvec, ov = self.overlaps(x)
        dist = 0.5 * (self.d[pairs[:, 0]] + self.d[pairs[:, 1]]) - ov
        t = (ov / np.maximum(dist, 1e-300))[:, None] * dvec  # dE/dx_i = +t, dE/dx_j = -t
        g = np.zeros((n, 2))
        for c in range(2):
            g[:, c] = np.bincount(pairs[:, 0], t[:, c], n) - np.bincount(pairs[:, 1], t[:, c], n)
        low = np.maximum(self.r[:, None] - x, 0.0)
        high = np.maximum(x + self.r[:, None] - self.box, 0.0)
        g += high - low
        e = 0.5 * (np.dot(ov, ov) + np.sum(low**2) + np.sum(high**2))
        return float(e), g.ravel()


def _prune(springs: NDArray, n_nodes: int, keep_nodes: NDArray, min_degree: int) -> NDArray:
    """Node mask after repeatedly removing nodes with fewer than ``min_degree`` springs."""
    keep_nodes = keep_nodes.copy()
    while True:
        live = keep_nodes[springs].all(axis=1)
        deg = np.bincount(springs[live].ravel(), minlength=n_nodes)
        weak = keep_nodes & (deg < min_degree)
        if not weak.any():
            return keep_nodes
        keep_nodes &= ~weak


def _subnetwork(pos: NDArray, springs: NDArray, keep_nodes: NDArray) -> tuple[NDArray, NDArray]:
    live = keep_nodes[springs].all(axis=1)
    new_index = np.cumsum(keep_nodes) - 1
    return pos[keep_nodes], new_index[springs[live]]


def _lbfgs(
    fg, x: NDArray, *, gtol: float, max_iter: int, memory: int = 10, max_step: float = 0.1
) -> tuple[NDArray, int, bool]:
    """Minimise ``fg(x) -> (f, grad)`` with L-BFGS and a backtracking Armijo line search.

    Each step moves no coordinate by more than ``max_step``. Stops when the largest
    gradient entry is ``<= gtol`` (returns converged True), after ``max_iter`` steps, or
    when even a steepest-descent step cannot lower ``f`` (round-off; converged False).
    Returns ``(x, iterations, converged)``.
    """
    f, g = fg(x)
    pairs: list[tuple[NDArray, NDArray, float]] = []
    for it in range(max_iter):
        if np.max(np.abs(g)) <= gtol:
            return x, it, True
        d = -g.copy()
        alphas = []
        for s, y, rho in reversed(pairs):
            a = rho * np.dot(s, d)
            d -= a * y
            alphas.append(a)
        if pairs:
            s, y, _ = pairs[-1]
            d *= np.dot(s, y) / np.dot(y, y)
        for (s, y, rho), a in zip(pairs, reversed(alphas)):
            d += (a - rho * np.dot(y, d)) * s
        slope = float(np.dot(g, d))
        if slope >= 0:
            pairs.clear()
            d, slope = -g, -float(np.dot(g, g))
        step = min(1.0, max_step / float(np.max(np.abs(d))))
        for _ in range(50):
            x_new = x + step * d
            f_new, g_new = fg(x_new)
            if f_new <= f + 1e-4 * step * slope:
                break
            step *= 0.5
        else:
            if not pairs:
                return x, it, False
            pairs.clear()
            continue
        s, y = x_new - x, g_new - g
        sy = float(np.dot(s, y))
        if sy > 1e-12 * float(np.linalg.norm(s) * np.linalg.norm(y)):
            pairs.append((s, y, 1.0 / sy))
            if len(pairs) > memory:
                pairs.pop(0)
        x, f, g = x_new, f_new, g_new
    return x, max_iter, bool(np.max(np.abs(g)) <= gtol)


def jammed_network(
    n_nodes: int,
    rng: np.random.Generator,
    *,
    phi: float = 0.88,
    polydispersity: float | None = None,
    stiffness: str | float = "inverse_length",
    force_tol: float = 1e-6,
    max_iter: int = 20_000,
    max_attempts: int = 5,
    dz: float | None = None,
) -> SpringNetwork:
    """The contact network of a jammed packing of soft discs in a box with hard walls.

    ``n_nodes`` discs (bidisperse: half of diameter 1, half 1.4; or polydisperse) are put
    at uniformly random positions in a square box sized so that the disc area fraction is
    ``phi``, then the harmonic overlap energy of disc pairs and of discs with the four
    walls is minimised (an instantaneous quench, as in O'Hern et al. 2003) with the
    package's own L-BFGS (``_lbfgs``) until the largest force is below ``force_tol`` times
    the mean contact force. For ``phi`` above jamming (about 0.84 for this mixture) the
    packing is jammed, with more than 4 contacts per disc on average (about 4.5 at 0.88).

    Overlapping disc pairs become springs with rest length equal to their distance in the
    packing, so the network is stress-free at the returned positions. Wall contacts are
    dropped: hard walls rather than a cut from a periodic packing, because fewer boundary
    nodes lose contacts and the network fills the square ``[0, B]^2``. Rattlers, nodes
    with fewer than 3 springs, are removed repeatedly. If what is left is not rigid
    (``rank R = 2N - 3``; not seen at the default ``phi``, possible close to jamming), the
    packing is drawn again from ``rng``, up to ``max_attempts`` times. The network has
    somewhat fewer than ``n_nodes`` nodes (typically 90-95 %), renumbered ``0..N-1`` in
    the order of the packed discs. Lengths are in units of the small (bidisperse) or mean
    (polydisperse) diameter.

    With ``dz`` set, springs are then removed, keeping the network rigid, until its excess
    coordination ``Z - Z_iso`` is ``dz``, as physical-learning studies prune jammed
    networks (Rocks et al. 2017, Stern et al. 2021). With ``N`` nodes and ``S`` springs,
    ``Z = 2 S / N`` and ``Z_iso = 2 (2N - 3) / N`` (``2N - 3`` springs, the fewest a rigid
    network can have), so exactly ``S* = 2N - 3 + round(N dz / 2)`` springs are kept and
    ``S* - (2N - 3)`` states of self-stress remain. The order of removal favours the most
    highly coordinated nodes, so that ``Z`` stays homogeneous: each step removes the first
    removable spring in decreasing order of the current ``degree[i] + degree[j]`` of its two
    ends, ties broken by a random permutation of the springs drawn from ``rng``; a spring
    is removable when it carries a state of self-stress (then ``rank R`` stays ``2N - 3``;
    greedy Gaussian elimination on a self-stress basis, as in ``diluted_lattice``) and
    neither end has only 3 springs left (a 2-spring node can be rigid but is a hinge that
    carries no stress). Springs loaded by less than 1 % of the largest tension of every
    basis stress are tried only when no other is left, so that no removal leaves a nearly
    floppy mode (at ``dz = 0`` the smallest nonzero singular value of ``R`` was >= 1e-4
    of the largest for ``N`` ~ 200-400 and >= 1e-5 for ``N`` ~ 1000 in tests; down to 1e-6
    at ``N`` ~ 400 without this rule). Nodes, positions, rest lengths (the contact
    distances: stress-free) and the stiffness rule are unchanged; springs keep their order.
    Cost: a dense pivoted QR of the (2N, S) compatibility matrix ``R^T``, O(N^3) time and
    ``2N S`` floats (about 1 s and 30 MB at ``N`` ~ 1000 on one core, some 8x the time
    and 4x the memory per doubling of ``N``), plus one elimination per removed spring
    (O(S (S - 2N)) each, about as long again in all); ``dz`` is therefore refused for
    ``n_nodes`` above 4096.

    Parameters
    ----------
    n_nodes : int
        Number of discs packed (>= 8).
    rng : numpy.random.Generator
        Draws the diameters and then the initial positions (again for each attempt).
    phi : float
        Packing fraction in (0.8, 1).
    polydispersity : None or float
        None: 50:50 bidisperse, diameter ratio 1.4. A float ``delta``: diameters uniform
        with mean 1 and relative standard deviation ``delta`` (< 1/sqrt(3)).
    stiffness : "inverse_length" or float
        ``k = 1 / L`` (as in the coupled-learning and allostery literature), or a uniform
        positive stiffness.
    force_tol, max_iter :
        Relative force tolerance and iteration budget of the packing minimisation; a
        packing that does not reach the tolerance raises RuntimeError.
    max_attempts : int
        Packings tried before giving up with RuntimeError.
    dz : None or float
        None (default): the contact network as packed, with its own ``Z`` (and no extra
        random numbers drawn). A number ``>= 0``: the target excess coordination
        ``Z - Z_iso`` (0: isostatic, exactly ``2N - 3`` springs). A ``dz`` above what the
        packing reached (about 0.4 at ``phi`` = 0.86, 0.5 at 0.88, 0.7 at 0.92) raises
        ValueError; raise ``phi`` for more contacts.

    Returns
    -------
    SpringNetwork
    """
    n_nodes = check.integer("n_nodes", n_nodes, low=8)
    check.memory("n_nodes", n_nodes, n_nodes * _PACKING_BYTES_PER_NODE, "the packing")
    _check_generator(rng)
    phi = check.real("phi", phi)
    if not (0.8 < phi < 1.0):
        raise ValueError(f"phi must be in (0.8, 1) so that the packing jams, got {phi}")
    if isinstance(stiffness, str):
        if stiffness != "inverse_length":
            raise ValueError(f"stiffness must be 'inverse_length' or a number, got {stiffness!r}")
    else:
        stiffness = _check_positive("stiffness", stiffness)
    force_tol = _check_positive("force_tol", force_tol)
    max_iter = check.integer("max_iter", max_iter, low=1)
    max_attempts = check.integer("max_attempts", max_attempts, low=1)
    _diameters(2, np.random.default_rng(0), polydispersity)  # validate before any work
    if dz is not None:
        dz = check.real("dz", dz, low=0)
        if n_nodes > _DZ_MAX_NODES:
            raise check.ArgumentError(
                "n_nodes",
                n_nodes,
                f"<= {_DZ_MAX_NODES} when dz is given",
                message=f"n_nodes = {n_nodes} is too large for dz: pruning to a coordination "
                f"uses a dense QR of the compatibility matrix, limited to n_nodes <= "
                f"{_DZ_MAX_NODES}",
            )
        check.memory("n_nodes", n_nodes, 80.0 * n_nodes**2, "the dense QR for dz")
    failure = "not rigid"
    for attempt in range(int(max_attempts)):
        net = _jammed_attempt(
            int(n_nodes), rng, phi, polydispersity, stiffness, force_tol, int(max_iter)
        )
        if net is not None and dz is not None:
            net = _prune_to_coordination(net, dz, rng, phi)
            failure = "not rigid, or its pruning for dz failed"
        if net is not None:
            return net
        _log.info("jammed_network: attempt %d failed, drawing a new packing", attempt + 1)
    raise RuntimeError(
        f"no rigid contact network in {max_attempts} packings at phi={phi} ({failure}); raise phi"
    )


def _jammed_attempt(
    n_nodes: int,
    rng: np.random.Generator,
    phi: float,
    polydispersity: float | None,
    stiffness: str | float,
    force_tol: float,
    max_iter: int,
) -> SpringNetwork | None:
    """One packing and its pruned contact network; None when that network is not rigid."""
    diam = _diameters(n_nodes, rng, polydispersity)
    box = math.sqrt(np.sum(np.pi * diam**2 / 4) / phi)
    x0 = rng.uniform(0.0, box, size=(n_nodes, 2))
    fun = _PackingEnergy(diam, box)
    # Contact forces are overlaps (unit stiffness); a first pass to 1e-3 sets their scale,
    # a few % of a diameter well above jamming, and so the final tolerance.
    flat, it1, _ = _lbfgs(fun, x0.ravel(), gtol=1e-3, max_iter=max_iter)
    _, _, ov = fun.overlaps(flat.reshape(-1, 2))
    gtol = force_tol * float(np.mean(ov)) if ov.size else force_tol
    flat, it2, ok = _lbfgs(fun, flat, gtol=gtol, max_iter=max_iter)
    if not ok:
        force = float(np.max(np.abs(fun(flat)[1])))
        raise RuntimeError(
            f"packing minimisation stopped at max force {force:.2e} > {gtol:.1e} "
            f"(force_tol={force_tol} x mean contact force) after {it1 + it2} iterations; "
            f"raise force_tol or max_iter"
        )
    x = flat.reshape(-1, 2)
    pairs, _, _ = fun.overlaps(x)
    springs = np.sort(pairs, axis=1)
    springs = springs[np.lexsort((springs[:, 1], springs[:, 0]))]
    keep = _prune(springs, n_nodes, np.ones(n_nodes, dtype=bool), 3)
    if keep.sum() < 3:
        return None
    pos, sub = _subnetwork(x, springs, keep)
    d = pos[sub[:, 1]] - pos[sub[:, 0]]
    L = np.hypot(d[:, 0], d[:, 1])
    k = 1.0 / L if isinstance(stiffness, str) else np.full(len(L), stiffness)
    net = SpringNetwork(pos, sub, k, L)
    _log.debug("jammed_network: %d of %d discs kept", net.n_nodes, n_nodes)
    return net if is_rigid(net) else None


def _self_stress_basis(net: SpringNetwork) -> NDArray[np.float64]:
    """A basis of the states of self-stress of a rigid ``net``: (S, S - 2N + 3), Fortran order.

    Pivoted QR of the compatibility matrix ``R^T P = Q [T11 T12; 0 0]`` (``R`` the (S, 2N)
    rigidity matrix, rank ``r = 2N - 3``): the columns ``P [-T11^-1 T12; I]`` span the null
    space of ``R^T``; column ``c`` is 1 on the ``c``-th non-pivot spring and 0 on the others
    (a fundamental circuit). Raises RuntimeError when ``R^T B`` is not ~0 (round-off).
    """
    n_springs, r = net.n_springs, 2 * net.n_nodes - 3
    Rt = rigidity_matrix(net).T.tocsr()
    T, perm = sla.qr(
        Rt.toarray(order="F"), overwrite_a=True, mode="r", pivoting=True, check_finite=False
    )
    basis = np.zeros((n_springs, n_springs - r), order="F")
    basis[perm[:r]] = -sla.solve_triangular(T[:r, :r], T[:r, r:], check_finite=False)
    basis[perm[r:], np.arange(n_springs - r)] = 1.0
    residual = float(np.max(np.abs(Rt @ basis), initial=0.0))
    if not residual <= 1e-8 * float(np.max(np.abs(basis), initial=1.0)):
        raise RuntimeError(f"self-stress basis has residual {residual:.1e}; please report this")
    return basis


def _prune_to_coordination(
    net: SpringNetwork, dz: float, rng: np.random.Generator, phi: float
) -> SpringNetwork | None:
    """``net`` (rigid) with springs removed down to ``2N - 3 + round(N dz / 2)``, still rigid.

    Each step removes, by :func:`~.builders._greedy_removal` on a self-stress basis (see
    :func:`_self_stress_basis`), the first spring carrying self-stress in decreasing order
    of the current degree sum of its ends, ties broken by a permutation drawn from ``rng``.
    Springs at a node with ``_MIN_DEGREE`` springs are not tried; nor, while any other is
    left, springs whose largest relative entry ``|basis[j, c]| / max |basis[:, c]|`` is
    below ``_MIN_LOAD`` (removing a weakly loaded spring leaves a nearly floppy mode).
    Returns None when no spring is removable before the target, or when the result fails
    :func:`is_rigid` (neither seen; the caller draws a new packing). Raises ValueError
    when ``net`` has fewer springs than the target.
    """
    n, springs = net.n_nodes, net.springs
    target = 2 * n - 3 + round(n * dz / 2)
    if net.n_springs < target:
        z, z_iso = 2 * net.n_springs / n, 2 * (2 * n - 3) / n
        raise check.ArgumentError(
            "dz",
            dz,
            f"<= {z - z_iso:.4f} for this packing",
            message=f"dz = {dz} is above what the packing at phi={phi} reached: Z = {z:.4f}, "
            f"Z_iso = {z_iso:.4f} ({n} nodes, {net.n_springs} springs < {target} needed), "
            f"so dz must be <= {z - z_iso:.4f}; raise phi for more contacts",
        )
    tie = rng.permutation(net.n_springs)  # drawn even when nothing is removed
    if target == net.n_springs:
        return net
    basis = _self_stress_basis(net)
    keep = np.ones(net.n_springs, dtype=bool)
    active = basis.shape[1]
    deg = np.bincount(springs.ravel(), minlength=n)
    for _ in range(net.n_springs - target):
        cand = np.flatnonzero(keep & (np.min(deg[springs], axis=1) > _MIN_DEGREE))
        colmax = np.max(np.abs(basis[:, :active]), axis=0)
        load = np.max(np.abs(basis[cand, :active]) / colmax, axis=1, initial=0.0)
        if np.any(load >= _MIN_LOAD):
            cand = cand[load >= _MIN_LOAD]
        ends = deg[springs[cand]].sum(axis=1)
        order = cand[np.lexsort((tie[cand], -ends))]
        try:  # one removal per call: the order depends on the degrees it changes
            j = int(_greedy_removal(basis[:, :active], order, 1)[0])
        except RuntimeError:  # no spring in order carries self-stress
            _log.info("jammed_network: pruning for dz=%g stalled at %d springs", dz, keep.sum())
            return None
        active -= 1
        keep[j] = False
        deg[springs[j]] -= 1
    out = SpringNetwork(net.positions, springs[keep], net.stiffness[keep], net.rest_length[keep])
    if deg.min() < _MIN_DEGREE:
        raise RuntimeError(f"pruning for dz={dz} left a node with {deg.min()} springs; a bug")
    if not is_rigid(out):
        _log.info("jammed_network: pruning for dz=%g lost rigidity", dz)
        return None
    return out
