"""MKL PARDISO Cholesky with the symbolic analysis kept per sparsity structure (optional).

PARDISO splits a factorisation into an analysis (ordering and symbolic factorisation,
phase 11) and a numerical factorisation (phase 22). On spring-network Hessians the analysis
is about as expensive as the numerical part, and every Newton iteration, shifted retry and
learning step factorises a matrix of the *same* structure. :class:`Analysis` therefore
keeps one PARDISO handle per structure (the last :data:`STRUCTURES` seen) and gives each
numerical factorisation one of its ``maxfct`` slots; a slot is released when its
:class:`~.kkt.Factor` is garbage collected. When every slot is taken the oldest is reused
and its factor, if ever used again, factorises its matrix anew: correct, only slower.

PARDISO orders by METIS: on 2D lattices its numerical factorisation is faster than with
the package's nested-dissection order given as PARDISO's user permutation
(``docs/solver-notes.md#pardiso``), and the analysis is kept. ``mtype = 2`` (real symmetric positive
definite): the factorisation stops with error -4 at the first non-positive pivot, which is
how it proves ``W > 0``.

The library comes from ``pypardiso`` (the optional extra ``continuum_vs_network[pardiso]``,
which installs MKL); this module is imported only when that import succeeds.
"""

from __future__ import annotations

import ctypes
import weakref
from collections import OrderedDict

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

__all__ = ["MAXFCT", "STRUCTURES", "Analysis", "NotPositiveDefinite", "factorise", "forget"]

MAXFCT = 4  # numerical factorisations of one structure alive at once
STRUCTURES = 2  # analyses kept (free/nudged learning states and relax share one)
_I32 = ctypes.POINTER(ctypes.c_int32)
_F64 = ctypes.POINTER(ctypes.c_double)
_LIB: dict = {}


class NotPositiveDefinite(RuntimeError):
    """PARDISO's Cholesky met a non-positive pivot (or a singular matrix)."""


def _library():
    if "pardiso" not in _LIB:
        import pypardiso  # optional (MKL); it locates mkl_rt

        fn = pypardiso.PyPardisoSolver().libmkl.pardiso
        fn.argtypes = [ctypes.POINTER(ctypes.c_int64)] + [_I32] * 5 + [ctypes.c_void_p]
        fn.argtypes += [_I32] * 4 + [_I32, _I32, ctypes.c_void_p, ctypes.c_void_p, _I32]
        fn.restype = None
        _LIB["pardiso"] = fn
    return _LIB["pardiso"]


class Analysis:
    """One PARDISO handle: the symbolic analysis of one structure and ``MAXFCT`` slots."""

    def __init__(self, upper: sp.csr_matrix) -> None:
        self.n = upper.shape[0]
        self.indptr = upper.indptr.astype(np.int32) + 1  # 1-based
        self.indices = upper.indices.astype(np.int32) + 1
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.iparm[0] = 1  # own settings
        self.iparm[1] = 2  # METIS
        self.iparm[7] = 0  # no iterative refinement
        self.iparm[34] = 0  # one-based indices
        self.perm = np.zeros(self.n, dtype=np.int32)
        self.owner: list[int] = [0] * MAXFCT  # id of the factorisation in each slot
        self.order: list[int] = []  # slots, oldest first
        self._next_id = 1
        self._call(11, 1, upper.data, np.zeros(1), np.zeros(1), 1)
        weakref.finalize(self, _release_all, self.pt, self.indptr, self.indices, self.n)

    def matches(self, upper: sp.csr_matrix) -> bool:
        return (
            upper.shape[0] == self.n
            and upper.nnz == self.indices.size
            and np.array_equal(upper.indptr, self.indptr - 1)
            and np.array_equal(upper.indices, self.indices - 1)
        )

    def _call(self, phase: int, mnum: int, data, b, x, nrhs: int) -> None:
        error = ctypes.c_int32(0)
        _library()(
            self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
            ctypes.byref(ctypes.c_int32(MAXFCT)),
            ctypes.byref(ctypes.c_int32(mnum)),
            ctypes.byref(ctypes.c_int32(2)),
            ctypes.byref(ctypes.c_int32(phase)),
            ctypes.byref(ctypes.c_int32(self.n)),
            data.ctypes.data,
            self.indptr.ctypes.data_as(_I32),
            self.indices.ctypes.data_as(_I32),
            self.perm.ctypes.data_as(_I32),
            ctypes.byref(ctypes.c_int32(nrhs)),
            self.iparm.ctypes.data_as(_I32),
            ctypes.byref(ctypes.c_int32(0)),
            b.ctypes.data,
            x.ctypes.data,
            ctypes.byref(error),
        )
        if error.value == -4:
            raise NotPositiveDefinite("PARDISO: non-positive pivot")
        if error.value:
            raise RuntimeError(f"PARDISO error {error.value} in phase {phase}")

    def factorise(self, data: NDArray) -> tuple[int, int]:
        """Numerical Cholesky of the values ``data`` (the structure's); ``(slot, id)``.

        Raises :class:`NotPositiveDefinite`.
        """
        free = [s for s in range(MAXFCT) if self.owner[s] == 0]
        slot = free[0] if free else self.order[0]
        if slot in self.order:
            self.order.remove(slot)
        self.owner[slot] = 0
        self._call(22, slot + 1, data, np.zeros(1), np.zeros(1), 1)
        ident, self._next_id = self._next_id, self._next_id + 1
        self.owner[slot] = ident
        self.order.append(slot)
        return slot, ident

    def solve(self, slot: int, b: NDArray) -> NDArray:
        b2 = np.asfortranarray(b.reshape(self.n, -1), dtype=np.float64)
        x = np.zeros_like(b2)
        self._call(33, slot + 1, np.zeros(1), b2, x, b2.shape[1])
        return x.reshape(b.shape)

    def release(self, slot: int, ident: int) -> None:
        if self.owner[slot] != ident:
            return
        self.owner[slot] = 0
        self.order.remove(slot)
        self._call(0, slot + 1, np.zeros(1), np.zeros(1), np.zeros(1), 1)


def _release_all(pt: NDArray, indptr: NDArray, indices: NDArray, n: int) -> None:
    """Free every PARDISO buffer of a handle (phase -1)."""
    if not np.any(pt):
        return
    error = ctypes.c_int32(0)
    _library()(
        pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
        ctypes.byref(ctypes.c_int32(MAXFCT)),
        ctypes.byref(ctypes.c_int32(1)),
        ctypes.byref(ctypes.c_int32(2)),
        ctypes.byref(ctypes.c_int32(-1)),
        ctypes.byref(ctypes.c_int32(n)),
        None,
        indptr.ctypes.data_as(_I32),
        indices.ctypes.data_as(_I32),
        None,
        ctypes.byref(ctypes.c_int32(1)),
        np.zeros(64, dtype=np.int32).ctypes.data_as(_I32),
        ctypes.byref(ctypes.c_int32(0)),
        None,
        None,
        ctypes.byref(error),
    )


_ANALYSES: OrderedDict[int, Analysis] = OrderedDict()


def _analysis(upper: sp.csr_matrix) -> Analysis:
    for key, analysis in _ANALYSES.items():
        if analysis.matches(upper):
            _ANALYSES.move_to_end(key)
            return analysis
    analysis = Analysis(upper)
    _ANALYSES[id(analysis)] = analysis
    while len(_ANALYSES) > STRUCTURES:
        _ANALYSES.popitem(last=False)  # freed when its last factor dies
    return analysis


def forget() -> None:
    """Drop the kept analyses (the next factorisation of every structure analyses anew)."""
    _ANALYSES.clear()


class _Numeric:
    """One numerical factorisation: a slot of an :class:`Analysis` and its values."""

    def __init__(self, analysis: Analysis, data: NDArray) -> None:
        self.analysis = analysis
        self.data = data
        self.slot, self.ident = analysis.factorise(data)
        weakref.finalize(self, analysis.release, self.slot, self.ident)

    def solve(self, b: NDArray) -> NDArray:
        a = self.analysis
        if a.owner[self.slot] != self.ident:  # the slot was taken: factorise again
            a.release(self.slot, self.ident)
            self.slot, self.ident = a.factorise(self.data)
            weakref.finalize(self, a.release, self.slot, self.ident)
        return a.solve(self.slot, np.asarray(b, dtype=np.float64))


def factorise(W: sp.spmatrix):
    """A solver ``b -> W^-1 b`` for symmetric positive-definite ``W``, or None if it is not."""
    upper = sp.triu(W, format="csr")
    upper.sort_indices()
    analysis = _analysis(upper)
    try:
        return _Numeric(analysis, np.ascontiguousarray(upper.data, dtype=np.float64)).solve
    except NotPositiveDefinite:
        return None
