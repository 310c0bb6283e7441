"""The spring network: node positions, springs, stiffness and rest lengths (Eq. 9-11)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..linalg.memo import per_array

__all__ = ["SpringNetwork", "spring_vectors"]


def _as_float_array(name: str, value: ArrayLike, shape: tuple[int | None, ...]) -> NDArray:
    if isinstance(value, np.ndarray) and value.dtype == np.float64 and not value.flags.writeable:
        arr = value  # a validated network's array, shared between copies
        _check_shape(name, arr, shape)
    else:
        arr = check.float_array(name, value, shape, finite=False)
    bad = (
        np.flatnonzero(~np.isfinite(arr).reshape(arr.shape[0], -1).all(axis=1)) if arr.size else ()
    )
    if len(bad):
        raise ValueError(f"{name} must be finite; entry {bad[0]} is {arr[bad[0]]}")
    if arr.flags.writeable:
        arr.setflags(write=False)
    return arr


def _check_shape(name: str, arr: NDArray, shape: tuple[int | None, ...]) -> None:
    ok = arr.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, arr.shape))
    if not ok:
        dims = ["n" if s is None else str(s) for s in shape]
        want = f"({dims[0]},)" if len(dims) == 1 else "(" + ", ".join(dims) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")


def _validate_topology(springs: NDArray, n_nodes: int) -> None:
    """Indices in range, no self-loops, no duplicate pairs; the first offender is named."""
    out = np.flatnonzero((springs < 0).any(axis=1) | (springs >= n_nodes).any(axis=1))
    if out.size:
        raise ValueError(
            f"springs[{out[0]}] = {springs[out[0]].tolist()} names a node outside 0..{n_nodes - 1}"
        )
    loops = np.flatnonzero(springs[:, 0] == springs[:, 1])
    if loops.size:
        raise ValueError(f"springs[{loops[0]}] is a self-loop on node {springs[loops[0], 0]}")
    pairs = np.sort(springs, axis=1)
    _, first, counts = np.unique(pairs, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup_pair = pairs[first[counts > 1][0]]
        dups = np.flatnonzero((pairs == dup_pair).all(axis=1))
        raise ValueError(
            f"springs[{dups[1]}] duplicates springs[{dups[0]}] (nodes {dup_pair.tolist()})"
        )


def spring_vectors(x: NDArray, springs: NDArray) -> NDArray:
    """``x[b] - x[a]`` for every spring ``a -> b``: (n_springs, 2) from positions (or any
    per-node vectors) ``x`` (n_nodes, 2). ``ndarray.take`` gathers rows faster than fancy
    indexing, with the same numbers; the method, not ``np.take``, skips numpy's dispatch
    wrapper (``docs/solver-notes.md#model``)."""
    return x.take(springs[:, 1], axis=0) - x.take(springs[:, 0], axis=0)


_SQRT_ROWS = 1000  # rows from which vector_lengths pays (below, np.hypot is as fast)
_SQUARE_SAFE = (1e-150, 1e150)  # lengths whose squares neither underflow nor overflow


def vector_lengths(d: NDArray) -> NDArray:
    """``|d|`` (s,) of vectors ``d`` (s, 2).

    From :data:`_SQRT_ROWS` rows ``sqrt(dx^2 + dy^2)``: faster than ``np.hypot`` of
    the columns (it strides them), the same to a rounding
    unit; ``np.hypot`` itself below, and where a square could underflow or overflow (a
    length outside 1e-150..1e150, 0 or not finite), so that collapsed and extreme springs
    get its exact result.
    """
    dx, dy = d[:, 0], d[:, 1]
    low, high = _SQUARE_SAFE
    # NaN fails every comparison: np.hypot; squares checked before they are made (an
    # overflow warns), lengths after (an underflow does not)
    if len(d) < _SQRT_ROWS or not (-high < d.min() and d.max() < high):
        return np.hypot(dx, dy)
    r = np.sqrt(dx * dx + dy * dy)
    return r if r.min() > low else np.hypot(dx, dy)


def unit_vectors(x: NDArray, springs: NDArray) -> tuple[NDArray, NDArray]:
    """Unit vectors ``u`` (s, 2) from each spring's first node to its second, and lengths
    ``r`` (s,), at positions ``x`` (n_nodes, 2); a spring of zero length gets ``u = 0``."""
    d = spring_vectors(x, springs)
    r = vector_lengths(d)
    return d / np.maximum(r, 1e-300)[:, None], r


@dataclass(frozen=True, eq=False)
class SpringNetwork:
    """A 2D network of unit point masses joined by Hookean springs.

    Parameters
    ----------
    positions : (n_nodes, 2) float array
        Reference node positions (length units).
    springs : (n_springs, 2) int array
        Node pairs ``(i, j)``; no self-loops, no duplicate pairs.
    stiffness : (n_springs,) float array
        Spring constants ``k_j >= 0`` (force per length).
    rest_length : (n_springs,) float array
        Rest lengths ``L_j > 0`` (length units).

    The elastic energy is ``E = sum_j k_j (r_j - L_j)^2 / 2`` (Eq. 11). Arrays are stored
    as read-only float64 (int64 for ``springs``) copies; change a network with the
    ``with_*`` methods, which return validated copies.
    """

    positions: NDArray[np.float64]
    springs: NDArray[np.int64]
    stiffness: NDArray[np.float64]
    rest_length: NDArray[np.float64]

    def __post_init__(self) -> None:
        positions = _as_float_array("positions", self.positions, (None, 2))
        n_nodes = positions.shape[0]
        if n_nodes == 0:
            raise check.ArgumentError("positions", self.positions, "an array of at least one node")
        springs = self.springs
        if not (
            isinstance(springs, np.ndarray)
            and springs.dtype == np.int64
            and not springs.flags.writeable
        ):
            springs = check.index_array(
                "springs", springs, n_nodes, what="node indices", shape=(None, 2)
            )
        _check_shape("springs", springs, (None, 2))
        n_springs = springs.shape[0]
        checked = per_array(springs, "validated") if not springs.flags.writeable else {}
        if n_nodes not in checked:  # a shared read-only topology is checked once
            _validate_topology(springs, n_nodes)
            checked[n_nodes] = True
        stiffness = _as_float_array("stiffness", self.stiffness, (n_springs,))
        rest_length = _as_float_array("rest_length", self.rest_length, (n_springs,))

        neg = np.flatnonzero(stiffness < 0)
        if neg.size:
            raise ValueError(f"stiffness must be >= 0; stiffness[{neg[0]}] = {stiffness[neg[0]]}")
        nonpos = np.flatnonzero(rest_length <= 0)
        if nonpos.size:
            raise ValueError(
                f"rest_length must be > 0; rest_length[{nonpos[0]}] = {rest_length[nonpos[0]]}"
            )
        if springs.flags.writeable:
            springs.setflags(write=False)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "springs", springs)
        object.__setattr__(self, "stiffness", stiffness)
        object.__setattr__(self, "rest_length", rest_length)

    # -- sizes and scales -------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_springs(self) -> int:
        return int(self.springs.shape[0])

    @property
    def force_scale(self) -> float:
        """Typical spring force ``F = mean(k) * mean(L)``: the unit of relative tolerances."""
        return float(np.mean(self.stiffness) * np.mean(self.rest_length)) if self.n_springs else 1.0

    # -- geometry ---------------------------------------------------------------------
    def lengths(
        self, x: ArrayLike | None = None, springs: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Spring lengths ``r_j`` at positions ``x`` (default: the stored positions).

        ``springs``: the springs to measure (an index, an integer array of indices or a
        (n_springs,) bool mask; default all), e.g. a task's targets, without computing the
        others. Returns a (n_springs,) float array, or one shaped as
        ``net.stiffness[springs]``.
        """
        x = self.positions if x is None else self._positions_like(x)
        pairs = self.springs if springs is None else self.springs[self._selection(springs)]
        d = spring_vectors(x, pairs.reshape(-1, 2))
        return vector_lengths(d).reshape(pairs.shape[:-1])

    def _selection(self, springs: ArrayLike) -> NDArray | int:
        """``springs`` checked as a spring index, indices or a (n_springs,) bool mask."""
        n, top = self.n_springs, self.n_springs - 1
        if isinstance(springs, np.ndarray) and springs.dtype == bool:
            if springs.shape != (n,):
                raise check.ArgumentError("springs", springs, f"a bool mask of shape ({n},)")
            return springs
        if np.ndim(springs) == 0:
            return check.integer(
                "springs", springs, low=0, high=top, what=f"a spring index in 0..{top}"
            )
        shape = np.shape(springs)
        flat = check.index_array("springs", np.ravel(springs), n, what="spring indices")
        return flat.reshape(shape)

    def _positions_like(self, x: ArrayLike) -> NDArray[np.float64]:
        """``x`` as (n_nodes, 2) float64 positions: arrays already so pass without a copy."""
        if isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == (self.n_nodes, 2):
            return x
        return check.float_array("x", x, (self.n_nodes, 2), finite=False)

    def strains(self, x: ArrayLike | None = None) -> NDArray[np.float64]:
        """Spring strains ``S_j = r_j / L_j - 1`` (Eq. 24), (n_springs,) float array."""
        return self.lengths(x) / self.rest_length - 1.0

    def clamp_length(self, spring: ArrayLike, strain: ArrayLike) -> NDArray[np.float64]:
        """Length ``L_j (S + 1)`` at which spring(s) ``spring`` have strain ``strain`` (Eq. 25)."""
        top = self.n_springs - 1
        if np.ndim(spring) == 0:
            idx = check.integer(
                "spring", spring, low=0, high=top, what=f"a spring index in 0..{top}"
            )
        else:
            idx = check.index_array("spring", spring, self.n_springs, what="spring indices")
        strain = check.float_array("strain", strain)
        length = self.rest_length[idx] * (strain + 1.0)
        if np.any(length <= 0):
            raise ValueError(f"strain must be > -1 so that the clamp length is positive: {strain}")
        return length

    # -- copies -----------------------------------------------------------------------
    def with_positions(self, positions: ArrayLike) -> SpringNetwork:
        """A copy with new reference positions (validated)."""
        return dataclasses.replace(self, positions=positions)

    def with_stiffness(self, stiffness: ArrayLike) -> SpringNetwork:
        """A copy with new spring constants (validated)."""
        return dataclasses.replace(self, stiffness=stiffness)

    def with_rest_length(self, rest_length: ArrayLike) -> SpringNetwork:
        """A copy with new rest lengths (validated)."""
        return dataclasses.replace(self, rest_length=rest_length)

    def __repr__(self) -> str:
        return f"SpringNetwork(n_nodes={self.n_nodes}, n_springs={self.n_springs})"
