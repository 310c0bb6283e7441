"""The implicit step of the damped dynamics: minimise ``E(x) + a/2 |x - x_hat|^2``.

Newton iterations with the sparse Hessian ``H + a I`` (the tangentially clipped Hessian where
that is indefinite), factorisations reused across chord corrections (and across steps with
``jacobian="frozen"``), and an Armijo line search on the proximal objective with energy
differences computed without cancellation. See :mod:`.dynamics` for the schemes that set
``a`` and ``x_hat``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..linalg.spd import factor_spd
from .energy import spring_energy_change, spring_gradient, spring_hessian_blocks
from .lagrangian import pattern_for
from .model import SpringNetwork, spring_vectors

__all__ = ["ProximalSolver"]


class ProximalSolver:
    """Minimises ``Phi(x) = E(x) + a/2 |x - x_hat|^2`` over free coordinates (see module)."""

    def __init__(
        self,
        net: SpringNetwork,
        free: NDArray,
        a: float,
        *,
        tol: float,
        jacobian: str,
        max_newton: int,
    ) -> None:
        self.net = net
        self.a = a
        self.pattern = pattern_for(net.springs, net.n_nodes, free, net.positions)
        self.rows = self.pattern.coords
        self.force_tol = tol * net.force_scale
        self.length_tol = tol * float(np.mean(net.rest_length)) if net.n_springs else tol
        self.jacobian = jacobian
        self.max_newton = max_newton
        self.factor = None
        self.factorisations = 0

    def _grad(self, x: NDArray, x_hat: NDArray) -> NDArray:
        net = self.net
        g = spring_gradient(x, net.springs, net.stiffness, net.rest_length).ravel()
        return g[self.rows] + self.a * (x.ravel()[self.rows] - x_hat.ravel()[self.rows])

    def _factorise(self, x: NDArray, t: float) -> None:
        """Factorise ``H + a I`` at ``x``; if indefinite, the tangentially clipped model.

        A spring compressed below its rest length has negative tangential stiffness
        ``k (1 - L/r)`` (buckling). When that makes ``H + a I`` indefinite (large ``dt``,
        strong compression), the step uses ``k max(0, 1 - L/r)`` instead, which is positive
        semi-definite, so ``H_clip + a I`` is positive definite (``a > 0``) and the step
        direction a descent direction of ``Phi``; the line search does the rest.
        """
        net = self.net
        ordered = self.pattern.ordered
        for clip in (False, True):
            L = net.rest_length
            if clip:
                d = spring_vectors(x, net.springs)
                L = np.minimum(L, np.hypot(d[:, 0], d[:, 1]))
            blocks = spring_hessian_blocks(x, net.springs, net.stiffness, L)
            W = self.pattern.assemble(blocks, shift=self.a)
            factor = factor_spd(W, ordered=ordered)
            self.factorisations += 1
            if factor is not None:
                self.factor = factor
                return
        raise RuntimeError(f"implicit step at t={t:g}: H + a I could not be factorised")

    def step(self, x_start: NDArray, x_hat: NDArray, t: float) -> NDArray:
        """One implicit step from the guess ``x_start`` (n_nodes, 2); returns the new state."""
        net = self.net
        springs, k, L = net.springs, net.stiffness, net.rest_length
        rows, a = self.rows, self.a
        x = x_start.copy()
        fresh = self.factor is None or self.jacobian == "update"  # factorised at x
        if fresh:
            self._factorise(x, t)
        g = self._grad(x, x_hat)
        gnorm = float(np.max(np.abs(g))) if g.size else 0.0
        newton = False
        for _ in range(self.max_newton):
            if gnorm <= self.force_tol:
                return x
            d = -self.factor.solve(g)
            slope = float(g @ d)
            offset = x.ravel()[rows] - x_hat.ravel()[rows]
            alpha = 1.0
            while True:
                y = x.copy()
                y.ravel()[rows] += alpha * d
                gy = self._grad(y, x_hat)
                gny = float(np.max(np.abs(gy)))
                s = alpha * d
                dphi = spring_energy_change(y, x, springs, k, L) + 0.5 * a * float(
                    s @ (s + 2.0 * offset)
                )
                if np.isfinite(gny) and (dphi <= 1e-4 * alpha * slope or gny <= 0.5 * gnorm):
                    break
                if not fresh:  # a reused factor gave a bad step: refactorise here, retry
                    alpha = 0.0
                    break
                alpha *= 0.5
                if alpha < 1e-12:
                    raise RuntimeError(
                        f"implicit step at t={t:g}: line search failed (residual {gnorm:.3e}); "
                        "reduce dt"
                    )
            if alpha == 0.0:
                self._factorise(x, t)
                fresh = newton = True
                continue
            small = alpha == 1.0 and float(np.max(np.abs(d))) <= self.length_tol
            # a chord (reused-factor) correction that does not cut the residual 4-fold means
            # the step is nonlinear (large rotations, stiff springs): full Newton from here
            newton = newton or gny > 0.25 * gnorm
            x, g, gnorm = y, gy, gny
            if small:
                return x
            fresh = newton
            if newton:
                self._factorise(x, t)
        if gnorm <= self.force_tol:
            return x
        raise RuntimeError(
            f"implicit step at t={t:g} did not converge in {self.max_newton} Newton iterations "
            f"(residual {gnorm:.3e} > {self.force_tol:.3e}); reduce dt"
        )
