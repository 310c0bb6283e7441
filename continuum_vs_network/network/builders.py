"""Network builders: the paper patch, triangular lattices (full and diluted).

Jammed packings are in :mod:`.jammed`.

Every builder returns a :class:`SpringNetwork`. Randomness comes only from the
``numpy.random.Generator`` passed in, so the same seed gives the same network. Lengths are
in the builder's own unit: ``spacing`` for lattices and the paper patch, the small disc
diameter for jammed packings.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from .model import SpringNetwork, spring_vectors
from .rigidity import is_rigid, self_stress_support

__all__ = [
    "diluted_lattice",
    "paper_network",
    "strain_tunable",
    "triangular_lattice",
]

_ROW_HEIGHT = math.sqrt(3.0) / 2.0


# -- argument checks ------------------------------------------------------------------
def _check_generator(rng: object, name: str = "rng") -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(
            f"{name} must be a numpy.random.Generator (np.random.default_rng(seed)), "
            f"got {type(rng).__name__}"
        )
    return rng


def _check_positive(name: str, value: float) -> float:
    return check.real(name, value, low=0, low_open=True)


def _check_noise(noise: float, rng: np.random.Generator | None) -> float:
    noise = check.real("noise", noise, low=0)
    if noise > 0:
        _check_generator(rng, "rng (needed because noise > 0)")
    return noise


def _check_range(name: str, bounds: tuple[float, float]) -> tuple[float, float]:
    try:
        low, high = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (low, high), got {bounds!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low <= high):
        raise ValueError(f"{name} must satisfy 0 < low <= high (finite), got {bounds!r}")
    return low, high


def _per_spring(name: str, value: ArrayLike, n_springs: int) -> NDArray[np.float64]:
    arr = check.float_array(name, value, finite=False)
    if arr.ndim == 0:
        return np.full(n_springs, float(arr))
    if arr.shape != (n_springs,):
        raise ValueError(f"{name} must be a scalar or have shape ({n_springs},), got {arr.shape}")
    return arr.copy()


# -- the paper's patch ----------------------------------------------------------------
def _triangle_patch(rows: int) -> tuple[NDArray, NDArray]:
    """Unit-spacing triangle of a triangular lattice: rows of ``rows, rows-1, ..., 1`` nodes."""
    index: dict[tuple[int, int], int] = {}
    pos = []
    for j in range(rows):
        for i in range(rows - j):
            index[i, j] = len(pos)
            pos.append((i + 0.5 * j, _ROW_HEIGHT * j))
    springs = []
    for (i, j), a in index.items():
        for nb in ((i + 1, j), (i, j + 1), (i - 1, j + 1)):
            if nb in index:
                springs.append((a, index[nb]))
    return np.array(pos), np.array(springs, dtype=np.int64)


def paper_network(
    rng: np.random.Generator,
    *,
    noise: float = 0.1,
    spacing: float = 10.0,
    rest_length_range: tuple[float, float] = (0.5, 20.0),
    stiffness_range: tuple[float, float] = (0.5, 50.0),
) -> SpringNetwork:
    """The paper's N = 10, S = 18 network (Fig. 1): a triangular patch with random springs.

    Nodes sit on a triangle of a triangular lattice of lattice constant ``spacing``, in rows
    of 4, 3, 2 and 1 nodes (row-major from the bottom row, left to right), joined by their
    18 nearest-neighbour springs. Each trial adds Gaussian noise of standard deviation
    ``noise * spacing`` to every coordinate (Sec. 5.1), then draws rest lengths
    ``L ~ U(rest_length_range)`` and stiffnesses ``k ~ U(stiffness_range)``, in that order.

    The paper draws ``L`` from 0-20 and ``k`` from 0-50 (footnote 4); the lower bounds here
    default to 0.5 because ``L = 0`` is not a valid rest length and a spring with ``k``
    near 0 has almost no influence (and makes the network nearly floppy).

    The three corner nodes have two springs each (dyads): see :func:`strain_tunable`.

    Parameters
    ----------
    rng : numpy.random.Generator
    noise : float
        Position noise as a fraction of ``spacing`` (>= 0).
    spacing : float
        Lattice constant (length units).
    rest_length_range, stiffness_range : (low, high)
        Bounds of the uniform draws, ``0 < low <= high``.

    Returns
    -------
    SpringNetwork with 10 nodes and 18 springs; the network is not stress-free.
    """
    _check_generator(rng)
    spacing = _check_positive("spacing", spacing)
    noise = _check_noise(noise, rng)
    l_lo, l_hi = _check_range("rest_length_range", rest_length_range)
    k_lo, k_hi = _check_range("stiffness_range", stiffness_range)
    pos, springs = _triangle_patch(4)
    pos = spacing * pos + rng.normal(0.0, noise * spacing, size=pos.shape)
    rest_length = rng.uniform(l_lo, l_hi, size=len(springs))
    stiffness = rng.uniform(k_lo, k_hi, size=len(springs))
    return SpringNetwork(pos, springs, stiffness, rest_length)


def strain_tunable(
    net: SpringNetwork, *, x: ArrayLike | None = None, tol: float = 1e-9
) -> NDArray[np.bool_]:
    """Springs whose strain learning can change in an equilibrium at ``x``, a (n_springs,) mask.

    In an equilibrium with no external force (a free state) the spring tensions balance at
    every node: they form a state of self-stress. The same holds with clamped springs,
    counting the clamps' tensions. A spring that carries no state of self-stress at the
    equilibrium positions ``x`` therefore has zero tension and zero strain, whatever the
    rest lengths and stiffnesses: learning cannot move it, nor get a gradient from it. The
    mask is ``self_stress_support(net, x=x) > tol``
    (:func:`~continuum_vs_network.network.rigidity.self_stress_support`).

    The commonest untunable springs are dyads: the two springs of a node that has only two
    (the three corners of :func:`paper_network`). The node moves until both are at rest,
    so they stay at zero strain. This holds only while the two rest lengths can reach
    the two anchor nodes: when ``L_1 + L_2`` is shorter than the anchors' distance (or
    ``|L_1 - L_2|`` longer), the dyad is pulled straight and taut, both springs carry the
    same tension, and their strains are nonzero and tunable. At straight dyads the two
    rows of the rigidity matrix are parallel and carry a self-stress, so evaluating the
    mask at the equilibrium positions (rather than the default ``net.positions``, where
    noisy dyads are bent) classifies both cases correctly.

    Parameters
    ----------
    net : SpringNetwork
    x : (n_nodes, 2) float array, optional
        Equilibrium positions (default ``net.positions``: right for stress-free networks and
        for generic positions where every dyad is bent).
    tol : float
        Threshold on the self-stress support, which lies in [0, 1].
    """
    tol = _check_positive("tol", tol)
    return self_stress_support(net, x=x) > tol


# -- triangular lattices ----------------------------------------------------------------
def _lattice_geometry(nx: int, ny: int) -> tuple[NDArray, NDArray]:
    """Unit-spacing triangular lattice, node ``i + nx * j``; odd rows shifted by 1/2."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    i, j = i.ravel(), j.ravel()
    pos = np.column_stack([i + 0.5 * (j % 2), _ROW_HEIGHT * j])
    node = i + nx * j
    pairs = []
    right = i < nx - 1
    pairs.append(np.column_stack([node[right], node[right] + 1]))
    up = j < ny - 1
    # Up-neighbours of (i, j): (i, j+1) always; (i-1, j+1) on even rows, (i+1, j+1) on odd rows.
    pairs.append(np.column_stack([node[up], node[up] + nx]))
    even_up = up & (j % 2 == 0) & (i > 0)
    pairs.append(np.column_stack([node[even_up], node[even_up] + nx - 1]))
    odd_up = up & (j % 2 == 1) & (i < nx - 1)
    pairs.append(np.column_stack([node[odd_up], node[odd_up] + nx + 1]))
    springs = np.concatenate(pairs).astype(np.int64)
    order = np.lexsort((springs[:, 1], springs[:, 0]))
    return pos, springs[order]


#: peak bytes per node while a triangular lattice is built (measured: 515 at 10**6 nodes)
_LATTICE_BYTES_PER_NODE = 600
#: peak bytes per disc while a jammed packing is minimised (an estimate: neighbour lists)
_PACKING_BYTES_PER_NODE = 4000


def _check_size(nx: int, ny: int) -> tuple[int, int]:
    nx, ny = check.integer("nx", nx, low=2), check.integer("ny", ny, low=2)
    check.memory(
        "nx, ny", (nx, ny), nx * ny * _LATTICE_BYTES_PER_NODE, f"a lattice of {nx * ny} nodes"
    )
    return nx, ny


def triangular_lattice(
    nx: int,
    ny: int,
    *,
    spacing: float = 1.0,
    noise: float = 0.0,
    rng: np.random.Generator | None = None,
    stiffness: ArrayLike = 1.0,
    rest_length: ArrayLike | None = None,
) -> SpringNetwork:
    """A ``nx`` by ``ny`` patch of a triangular lattice with nearest-neighbour springs.

    Node ``i + nx * j`` (column ``i``, row ``j``, row-major) sits at
    ``spacing * (i + (j % 2) / 2, j * sqrt(3) / 2)``: odd rows are shifted right by half a
    spacing, so the patch is a rectangle-like parallelogram with zig-zag sides. Springs are
    sorted by ``(first node, second node)`` with the first node the smaller; there are
    ``3 nx ny - 2 nx - 2 ny + 1`` of them.

    Parameters
    ----------
    nx, ny : int
        Nodes per row and number of rows (>= 2 each).
    spacing : float
        Lattice constant (length units).
    noise : float
        Standard deviation of Gaussian noise on every coordinate, as a fraction of
        ``spacing``. Needs ``rng`` when > 0.
    rng : numpy.random.Generator, optional
    stiffness : float or (n_springs,) array
    rest_length : None, float or (n_springs,) array
        None makes the lattice stress-free: ``L`` is each spring's length after the noise.

    Returns
    -------
    SpringNetwork
    """
    nx, ny = _check_size(nx, ny)
    spacing = _check_positive("spacing", spacing)
    noise = _check_noise(noise, rng)
    pos, springs = _lattice_geometry(nx, ny)
    pos = spacing * pos
    if noise > 0:
        pos = pos + rng.normal(0.0, noise * spacing, size=pos.shape)
    k = _per_spring("stiffness", stiffness, len(springs))
    if rest_length is None:
        d = spring_vectors(pos, springs)
        L = np.hypot(d[:, 0], d[:, 1])
    else:
        L = _per_spring("rest_length", rest_length, len(springs))
    return SpringNetwork(pos, springs, k, L)


def _wheel_stresses(net: SpringNetwork, nx: int, ny: int) -> NDArray[np.float64]:
    """A basis of the self-stresses of a full triangular lattice, one per interior node.

    Node ``c`` with its six neighbours and their 12 springs (6 spokes, 6 rim) is a wheel,
    a minimal overconstrained set with exactly one state of self-stress, found as the left
    null vector of its 12 x 14 rigidity matrix. There are ``(nx - 2)(ny - 2) = S - (2N - 3)``
    interior nodes: as many as the lattice has self-stresses. Returns a dense
    (n_springs, n_interior) array, column-major, each column scaled to max-abs 1.
    """
    n = net.n_nodes
    key = net.springs[:, 0] * n + net.springs[:, 1]

    def index(a: NDArray, b: NDArray) -> NDArray:
        k = np.minimum(a, b) * n + np.maximum(a, b)
        return np.searchsorted(key, k)

    i, j = np.meshgrid(np.arange(1, nx - 1), np.arange(1, ny - 1), indexing="xy")
    i, j = i.ravel(), j.ravel()
    c = i + nx * j
    up_right = c + nx + (j % 2)
    down_right = c - nx + (j % 2)
    ring = np.stack([c + 1, up_right, up_right - 1, c - 1, down_right - 1, down_right], axis=1)
    local_a = np.array([0] * 6 + [1, 2, 3, 4, 5, 6])
    local_b = np.array([1, 2, 3, 4, 5, 6, 2, 3, 4, 5, 6, 1])
    nodes = np.concatenate([c[:, None], ring], axis=1)  # (W, 7)
    ends_a, ends_b = nodes[:, local_a], nodes[:, local_b]  # (W, 12)
    d = net.positions[ends_b] - net.positions[ends_a]
    u = d / np.linalg.norm(d, axis=2, keepdims=True)
    rows = np.arange(12)
    R = np.zeros((len(c), 12, 14))
    for comp in range(2):
        R[:, rows, 2 * local_a + comp] = -u[..., comp]
        R[:, rows, 2 * local_b + comp] = u[..., comp]
    U, _, _ = np.linalg.svd(R)  # rank R <= 11 < 12 rows: U[:, :, -1] is a self-stress
    stress = U[:, :, -1] / np.max(np.abs(U[:, :, -1]), axis=1, keepdims=True)
    basis = np.zeros((net.n_springs, len(c)), order="F")
    basis[index(ends_a, ends_b), np.arange(len(c))[:, None]] = stress
    return basis


_SUPPORT_RTOL = 1e-9  # a basis entry below this fraction of its column's largest is zero


def diluted_lattice(
    nx: int,
    ny: int,
    fraction: float,
    rng: np.random.Generator,
    *,
    spacing: float = 1.0,
    noise: float = 0.0,
    stiffness: ArrayLike = 1.0,
) -> SpringNetwork:
    """A stress-free triangular lattice with a random ``fraction`` of springs removed, kept rigid.

    Springs are visited in a random order and removed unless the removal would break
    rigidity, until ``round(fraction * S)`` are gone (``S`` springs in the full lattice).
    Removing spring ``j`` keeps ``rank R = 2N - 3`` exactly when ``j`` carries a state of
    self-stress. The builder keeps a basis of the self-stresses of the current network,
    starting from the local "wheel" stresses of the full lattice (one per interior node),
    and removes spring ``j`` by Gaussian elimination: the basis vector with the largest
    relative entry at ``j`` is eliminated from the others at row ``j`` and dropped. A
    spring whose entries are all below ``1e-9`` of their column's largest is rejected (it
    carries no self-stress). Each removal touches only the few basis vectors that load
    ``j``, so N = 1024 takes about 0.1 s; memory is one dense (S, S - 2N + 3) array (20 MB
    at N = 1024, 350 MB at N = 4096). The rigidity of the result is checked again from
    scratch with :func:`~continuum_vs_network.network.rigidity.is_rigid`.

    Because removable springs form a matroid, every order reaches the isostatic limit of
    ``2N - 3`` springs, so every ``fraction <= (S - 2N + 3) / S`` (about 1/3 for large
    lattices) gives exactly ``round(fraction * S)`` springs removed; the result is the
    same as removing springs one at a time in that order with a full rank test for each.
    Larger fractions raise ValueError.

    Parameters
    ----------
    nx, ny : int
        Lattice size, as in :func:`triangular_lattice` (same node numbering; no node is
        removed).
    fraction : float
        Fraction of springs to remove, in [0, 1).
    rng : numpy.random.Generator
        Draws the position noise (if any), then the order in which springs are tried.
    spacing, noise, stiffness : as in :func:`triangular_lattice`; the result is stress-free.

    Returns
    -------
    SpringNetwork
        The remaining springs, in their lattice order.
    """
    nx, ny = _check_size(nx, ny)
    fraction = check.real("fraction", fraction, low=0, high=1, high_open=True)
    _check_generator(rng)
    full = triangular_lattice(nx, ny, spacing=spacing, noise=noise, rng=rng, stiffness=stiffness)
    n_springs = full.n_springs
    n_remove = round(fraction * n_springs)
    n_max = n_springs - (2 * full.n_nodes - 3)
    if n_remove > n_max:
        raise ValueError(
            f"fraction {fraction} asks to remove {n_remove} of {n_springs} springs, but a rigid "
            f"network of {full.n_nodes} nodes needs {2 * full.n_nodes - 3}: fraction must be "
            f"<= {n_max / n_springs:.4f}"
        )
    keep = np.ones(n_springs, dtype=bool)
    order = rng.permutation(n_springs)
    if n_remove:
        keep[_greedy_removal(_wheel_stresses(full, nx, ny), order, n_remove)] = False
    net = SpringNetwork(
        full.positions, full.springs[keep], full.stiffness[keep], full.rest_length[keep]
    )
    if n_remove and not is_rigid(net):
        raise RuntimeError("diluted lattice lost rigidity; please report this as a bug")
    return net


def _greedy_removal(basis: NDArray, order: NDArray, n_remove: int) -> NDArray[np.int64]:
    """Springs removed greedily in ``order`` while a self-stress basis still loads them.

    ``basis`` (n_springs, s), column-major, is overwritten. Returns the removed indices.
    """
    colmax = np.max(np.abs(basis), axis=0)
    active = basis.shape[1]
    removed: list[int] = []
    for j in order:
        rel = np.abs(basis[j, :active]) / colmax[:active]
        loads = np.flatnonzero(rel > _SUPPORT_RTOL)
        if loads.size == 0:
            continue
        p = int(loads[np.argmax(rel[loads])])
        pivot = basis[:, p] / basis[j, p]
        for c in loads:
            if c != p:
                basis[:, c] -= basis[j, c] * pivot
                basis[j, c] = 0.0
                colmax[c] = np.max(np.abs(basis[:, c]))
                basis[:, c] /= colmax[c]
                colmax[c] = 1.0
        active -= 1
        if p != active:
            basis[:, p] = basis[:, active]
            colmax[p] = colmax[active]
        removed.append(int(j))
        if len(removed) == n_remove:
            break
    if len(removed) < n_remove:
        raise RuntimeError(
            f"only {len(removed)} of {n_remove} springs could be removed keeping rigidity; "
            "the lattice positions may be degenerate"
        )
    return np.array(removed, dtype=np.int64)
