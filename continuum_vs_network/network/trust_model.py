"""The quadratic model of one trust-region iteration (:mod:`.trust`) and its exact
subproblem, in scaled reduced coordinates.

A model is ``m(p) = gr . p + p . H p / 2`` over reduced coordinates ``p`` (r,) that move
the free coordinates by ``B p`` (``B`` (n, r) the scaled basis: ``D^-1/2`` times an
orthonormal basis of the clamps' tangent space, rigid motions removed when nothing is
pinned). It is first factored by Cholesky, which gives the Newton step; the second-order
certificate (a Cholesky with a shift ``1e-8``) is made only for the model a solve ends at;
when a trial needs a boundary step it is eigen-decomposed once, and every trial at that
model solves the secular equation on the eigenvalues alone (vector operations of length
r) and corrects its bending by one division. LAPACK is called directly: at the paper's
N = 10 patch numpy's per-call overhead is the cost.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack

from ..linalg.memo import per_array
from .trust_kernels import SparseKernels

__all__ = ["CURVATURE", "Model", "RigidBasis", "Spectrum", "null_basis", "rigid_motions"]

CURVATURE = 1e-8  # smallest eigenvalue of the scaled reduced Hessian that certifies a minimum
_EYE: dict[int, tuple[NDArray, NDArray]] = {}  # CURVATURE I, I by size (shifted_positive)


def null_basis(M: NDArray) -> NDArray:
    """Orthonormal basis (n, n - rank) of the null space of ``M`` (k, n)."""
    _, sv, vt, info = lapack.dgesdd(M)  # numpy's SVD, without its per-call overhead
    if info != 0:
        _, sv, vt = np.linalg.svd(M)
    rank = int((sv > 1e-12 * max(float(sv[0]), 1e-300)).sum()) if sv.size else 0
    return vt[rank:].T


def rigid_motions(x: NDArray, coords: NDArray) -> NDArray:
    """The rigid motions of ``x`` (n_nodes, 2) at flat coordinates ``coords``, (3, n):
    the two translations and the rotation about the centroid."""
    c = x - np.add.reduce(x, 0) / x.shape[0]  # x.mean(axis=0), without its overhead
    full = np.zeros((3, 2 * x.shape[0]))
    full[0, 0::2] = 1.0
    full[1, 1::2] = 1.0
    full[2, 0::2] = -c[:, 1]
    full[2, 1::2] = c[:, 0]
    return full[:, coords]


class RigidBasis:
    """Scaled bases ``B = D^-1/2 Q`` (n, n - 3) of a free network's coordinates (all of
    them, natural order) with the rigid motions removed, ``Q`` orthonormal.

    The translations do not depend on the positions: ``Q0`` (n, n - 2), orthogonal to
    them, is found once (one Householder reflection per axis). At each ``x`` the
    rotation's component ``v`` in ``Q0``'s coordinates is removed by one more reflection
    ``I - 2 h h^T / h.h`` that maps ``v`` onto the first axis:
    ``Q = Q0 (I - 2 h h^T / h.h)[:, 1:]``. The same space as :func:`null_basis` of the
    three rigid rows (another orthonormal basis of it), in a handful of vector operations
    instead of a rigid-row build and an SVD.
    """

    def __init__(self, x: NDArray, inv_root: NDArray, length: float) -> None:
        self.B0, self.B0S, inv2, pairs = _translations(inv_root)
        # the rotation about the centre c: turn(x) = (-(y - c_y), x - c_x) per node, so
        # B0^T turn(x) = x.B0S - c.B0S with B0S the rows of B0 swapped, the x rows negated
        centre = np.add.reduce(x, 0) / x.shape[0]
        self.v_centre = centre[pairs] @ self.B0S  # centre[pairs]: np.tile(centre, n_nodes)
        # below this |v| the rotation is a translation (every node at one point)
        self.floor = (1e-12 * length) ** 2 * inv2

    def __call__(self, x: NDArray) -> NDArray:
        v = x.ravel().dot(self.B0S) - self.v_centre  # the rotation in Q0's coordinates
        v2 = float(v.dot(v))
        if v2 <= self.floor:
            return self.B0
        h = v.copy()
        h[0] += math.copysign(math.sqrt(v2), float(v[0]))
        B0 = self.B0
        return B0[:, 1:] - B0.dot(h)[:, None] * (h[1:] * (2.0 / float(h.dot(h))))


_TRANSLATIONS_N = 64  # coordinates up to which they are kept (memo.per_array, by content)


def _translations(inv_root: NDArray) -> tuple[NDArray, NDArray, float, NDArray]:
    """:class:`RigidBasis`'s constants for ``inv_root`` (n,): ``B0``, ``B0S`` (read-only),
    ``inv_root . inv_root`` and the flat index ``0, 1, 0, 1, ...`` (n,); kept for small
    ``n`` (repeated solves of one network at the same stiffness)."""
    store = per_array(inv_root, "rigid_translations") if inv_root.size <= _TRANSLATIONS_N else {}
    hit = store.get("constants")
    if hit is not None:
        return hit
    n = inv_root.size
    half = n // 2
    B0 = np.zeros((n, n - 2))
    for axis in (0, 1):  # translation along axis: inv_root on that axis' rows
        a = inv_root[axis::2]
        h = a.copy()
        h[0] += math.copysign(math.sqrt(float(a @ a)), float(a[0]))
        Q = np.eye(half)[:, 1:] - h[:, None] * (h[1:] * (2.0 / float(h @ h)))
        B0[axis::2, axis * (half - 1) : (axis + 1) * (half - 1)] = Q * a[:, None]
    B0S = np.empty_like(B0)
    B0S[0::2], B0S[1::2] = B0[1::2], -B0[0::2]
    B0.setflags(write=False)
    B0S.setflags(write=False)
    hit = store["constants"] = (B0, B0S, float(inv_root @ inv_root), np.arange(n) % 2)
    return hit


def _eigh(H: NDArray) -> tuple[NDArray, NDArray]:
    """``np.linalg.eigh`` (the same LAPACK driver), without its per-call overhead."""
    vals, vecs, info = lapack.dsyevd(H)
    return (vals, vecs) if info == 0 else np.linalg.eigh(H)


class Spectrum:
    """Eigenvalues ``vals`` (r,) of a model (ascending) and its gradient ``gt`` (r,) in
    the eigenbasis, with what every subproblem on them reuses (:func:`subproblem`)."""

    def __init__(self, vals: NDArray, gt: NDArray) -> None:
        self.vals, self.gt, self.half_vals = vals, gt, 0.5 * vals
        lowest, top = float(vals[0]), float(vals[-1])
        self.lowest, self.low = lowest, max(0.0, -lowest)
        self.abs_gt = np.abs(gt)
        self.g_norm = math.sqrt(float(gt.dot(gt)))
        self.tiny = 1e-12 * max(abs(lowest), abs(top), 1e-300)
        self.top = abs(top) + self.tiny
        self.newton, self.newton_length = None, math.inf
        if lowest > 0:
            self.newton = -(gt / vals)
            self.newton_length = math.sqrt(float(self.newton.dot(self.newton)))
        self.hard = None
        if lowest <= 0:  # the hard case: (almost) no gradient on the lowest eigenvectors
            on_low = np.abs(vals - lowest) <= self.tiny
            if math.sqrt(float(gt[on_low] @ gt[on_low])) <= 1e-10 * max(self.g_norm, 1e-300):
                safe = ~on_low
                p = np.zeros_like(gt)
                p[safe] = -gt[safe] / (vals[safe] + self.low)
                e = int(np.flatnonzero(on_low)[0])
                self.hard = (p, float(p @ p), e, 1.0 if gt[e] <= 0 else -1.0)


def subproblem(spec: Spectrum, radius: float) -> tuple[NDArray, NDArray, float]:
    """Exact solution ``p`` (r,) of ``min gt.p + p.diag(vals).p / 2, |p| <= radius`` in
    the eigenbasis, the shifted eigenvalues ``vals + shift`` it solves and ``|p|``.

    The Newton step when it is admissible; else the boundary step of the smallest
    admissible shift, following negative curvature (the hard case adds the lowest
    eigenvector).
    """
    if spec.newton_length <= radius:
        return spec.newton, spec.vals, spec.newton_length
    vals, gt = spec.vals, spec.gt
    if spec.hard is not None:
        p, p2, e, sign = spec.hard
        rest = radius**2 - p2
        if rest > 0:
            p = p.copy()
            p[e] += math.sqrt(rest) * sign
            return p, vals + spec.low, math.sqrt(float(p @ p))
    # safeguarded Newton on the secular equation 1/|p(shift)| = 1/radius (More-Sorensen),
    # bracketed by bisection. Started from a shift that is provably below the root (each
    # component alone ``|gt_i| / (vals_i + shift)`` already reaches the radius there),
    # where Newton on the concave secular function converges monotonically: 3-5 steps
    lo, hi = spec.low, spec.low + spec.g_norm / radius + spec.top
    shift = max(lo, float(np.maximum.reduce(spec.abs_gt / radius - vals)))
    if not ((shift > lo or spec.lowest > 0) and shift < hi):
        shift = hi
    for _ in range(60):
        den = vals + shift
        h = gt / den  # -p(shift)
        norm2 = float(h.dot(h))
        norm = math.sqrt(norm2)
        if norm2 == 0.0:  # no gradient left in float64 (it underflowed): no step
            return -h, den, 0.0
        if abs(norm - radius) <= 1e-6 * radius:
            return -h, den, norm
        if norm > radius:
            lo = shift
        else:
            hi = shift
        # Newton on phi = 1/radius - 1/|p|, which is nearly linear in the shift
        slope = float(h.dot(h / den)) / (norm2 * norm)  # -d(phi)/d(shift)
        trial = shift + (1.0 / radius - 1.0 / norm) / slope
        shift = trial if lo < trial < hi else 0.5 * (lo + hi)
    den = vals + shift
    h = gt / den
    return -h, den, math.sqrt(float(h.dot(h)))


class Model:
    """The quadratic model of one iteration: Hessian ``H`` (r, r), gradient ``gr`` (r,) and
    basis ``basis`` (n, r) (None: ``diag(inv_root)``) at positions ``x``.

    ``H`` is first factored (Cholesky): when that succeeds the Newton step comes from the
    factor. :attr:`certified` (every eigenvalue above ``sigma = max(1e-8, 1e-12 |H|)``,
    the second-order certificate) is decided only when asked, by a Cholesky of
    ``H - sigma I``, or from the spectrum when :meth:`eigen` (the boundary step, negative
    curvature) has been computed. ``trials`` keeps the trust region's trials at this model
    by radius (``attempt`` in :func:`~.trust.trust_region_newton`).
    """

    def __init__(
        self, x: NDArray, H: NDArray, gr: NDArray, basis: NDArray | None, inv_root: NDArray,
        terms: SparseKernels,
    ) -> None:  # fmt: skip
        self.x, self.H, self.gr, self.basis, self.inv_root = x, H, gr, basis, inv_root
        self.terms = terms
        self.spectrum: Spectrum | None = None
        self.vecs: NDArray | None = None
        self.factor, self.newton, self.newton_length = cholesky_newton(H, gr)
        self._certified: bool | None = None if self.factor is not None else False
        self.trials: dict[float, tuple] = {}

    @property
    def certified(self) -> bool:
        """Every eigenvalue of ``H`` exceeds ``sigma`` (:data:`CURVATURE` at least)."""
        if self._certified is None:
            self._certified = shifted_positive(self.H)
        return self._certified

    def lift(self, p: NDArray) -> NDArray:
        """The move (n,) of the free coordinates for reduced scaled coordinates ``p`` (r,)."""
        return self.basis.dot(p) if self.basis is not None else p * self.inv_root

    def eigen(self) -> Spectrum:
        """The spectrum of ``H`` (the eigenvectors in ``vecs``), computed once."""
        if self.spectrum is None:
            vals, self.vecs = _eigh(self.H)
            self.spectrum = Spectrum(vals, self.vecs.T.dot(self.gr))
            self._certified = bool(vals.size == 0 or vals[0] > CURVATURE)
        return self.spectrum


def cholesky_newton(H: NDArray, gr: NDArray) -> tuple[NDArray | None, NDArray | None, float]:
    """Cholesky factor of ``H`` (r, r), the Newton step ``-H^-1 gr`` and its length, when
    ``H`` is positive definite (numerically: the factorisation completes and the step is
    finite); else ``(None, None, inf)``."""
    if not H.size:
        return None, None, math.inf
    factor, info = lapack.dpotrf(H)
    if info != 0:
        return None, None, math.inf
    step, info = lapack.dpotrs(factor, gr)
    length = math.sqrt(float(step.dot(step)))
    if info != 0 or not math.isfinite(length):
        return None, None, math.inf
    return factor, -step, length


def shifted_positive(H: NDArray) -> bool:
    """``H - sigma I`` (r, r) is positive definite, ``sigma = max(CURVATURE, 1e-12 |H|)``
    (``|H|`` the largest row sum of ``|H_ij|``); False for an empty ``H``."""
    if not H.size:
        return False
    r = H.shape[0]
    magnitude = np.abs(H)
    top = float(np.maximum.reduce(magnitude, None))
    # 1e-12 max row sum |H| exceeds CURVATURE only where r max |H_ij| does
    norm = float(np.maximum.reduce(np.add.reduce(magnitude, 1))) if r * top > 1e4 else 0.0
    sigma = max(CURVATURE, 1e-12 * norm)
    shifts = _EYE.get(r)  # CURVATURE I and I: the usual shift is one subtraction
    if shifts is None:
        eye = np.eye(r)
        shifts = _EYE.setdefault(r, (CURVATURE * eye, eye))
    shift = shifts[0] if sigma == CURVATURE else sigma * shifts[1]
    _, info = lapack.dpotrf(H - shift, overwrite_a=True)
    return info == 0
