"""Thermal noise: states sampled at a temperature instead of equilibria.

A physical learner at temperature ``T`` (``k_B T`` in energy units) never sees the
equilibrium of a state; it sees the network fluctuating around it. This module samples
those fluctuations **exactly in the harmonic approximation**: around an equilibrium ``x*``
with pins and clamps, the Boltzmann distribution of ``E`` to second order is the Gaussian

    x = x* + N y,   y ~ N(0, T (N^T W N)^{-1})

with ``W`` the Hessian of the Lagrangian (the clamp tensions included) and ``N`` an
orthonormal basis of the directions the pins and clamps leave free (the null space of the
clamp rows). This is the stationary distribution of overdamped Langevin dynamics in that
harmonic well, drawn directly: no time step, no burn-in, no correlation between draws; it
is exact for ``T -> 0`` and misses only the anharmonic corrections of order ``T^2``.
(Running Langevin dynamics for a few relaxation times per state would cost hundreds of
force evaluations per state and add time-step and correlation errors for the same
distribution.) Every state a rule reads (free, nudged, clamped) is one independent draw.

Dense linear algebra (a null-space basis and a Cholesky factor per state): problems of at
most :data:`MAX_FREE` free coordinates.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from numpy.typing import NDArray

from .. import _validate as check
from ..network.constraints import Problem
from ..network.equilibrium import Equilibrium
from ..network.lagrangian import Frame, lagrangian_hessian
from ..network.model import SpringNetwork

__all__ = ["MAX_FREE", "thermal_sample"]

#: largest number of free coordinates a thermal sample is drawn for (dense eigensolve)
MAX_FREE = 4000


def thermal_sample(
    net: SpringNetwork,
    pinned: NDArray,
    clamped: dict[int, float],
    eq: Equilibrium,
    temperature: float,
    rng: np.random.Generator,
    *,
    size: int | None = None,
) -> NDArray:
    """Positions drawn from the harmonic Boltzmann distribution around ``eq``.

    Parameters
    ----------
    net : SpringNetwork
    pinned : (n_nodes, 2) bool array
    clamped : {spring: length}
        The clamps of the state (in the order of ``eq.clamp_force``).
    eq : Equilibrium
        The state's equilibrium.
    temperature : float
        ``k_B T`` (energy units, >= 0); 0 returns the equilibrium.
    rng : numpy.random.Generator
    size : int, optional
        Number of draws: (size, n_nodes, 2); one (n_nodes, 2) draw when None.

    Raises
    ------
    ValueError
        The state is not a stable minimum (the reduced Hessian is not positive definite),
        or the problem has more than :data:`MAX_FREE` free coordinates.
    """
    temperature = check.real("temperature", temperature, low=0)
    x = np.asarray(eq.positions, dtype=np.float64)
    n_draws = 1 if size is None else check.integer("size", size, low=1)
    if temperature == 0.0:
        out = np.broadcast_to(x, (n_draws, *x.shape)).copy()
        return out[0] if size is None else out
    problem = Problem.build(net, pinned=pinned, clamped=clamped, clamp="exact")
    frame = Frame(net, problem.free)
    if frame.n > MAX_FREE:
        raise ValueError(
            f"thermal sampling is dense: {frame.n} free coordinates > {MAX_FREE}; use a "
            "smaller network"
        )
    mu = -np.asarray(eq.clamp_force, dtype=np.float64)
    W = lagrangian_hessian(problem, x, mu, frame=frame).toarray()
    if problem.n_clamps:
        A = frame.rows(net, x, problem.clamp_springs, dense=True)
        N = sla.null_space(A)
    else:
        N = np.eye(frame.n)
    try:  # H = R^T R; y = R^{-1} xi has covariance H^{-1}
        R = sla.cholesky(N.T @ W @ N, lower=False)
    except np.linalg.LinAlgError:
        raise ValueError(
            "thermal sampling needs a stable equilibrium: the Hessian on the free directions "
            "is not positive definite (a floppy or unstable state has no harmonic Boltzmann "
            "distribution)"
        ) from None
    xi = rng.standard_normal((R.shape[0], n_draws))
    y = np.sqrt(temperature) * sla.solve_triangular(R, xi, lower=False)
    moves = (N @ y).T
    out = np.empty((n_draws, *x.shape))
    for i in range(n_draws):
        out[i] = x + frame.put(moves[i])
    return out[0] if size is None else out
