"""The network's strain clamp in time (stiff rods): it converges to the length constraint,
relaxes to the exact-clamp equilibrium, and decays at the strain-constrained slowest mode."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp

from continuum_vs_network.network.builders import triangular_lattice
from continuum_vs_network.network.energy import hessian
from continuum_vs_network.network.equilibrium import relax
from continuum_vs_network.network.length_jacobian import strain_jacobian
from continuum_vs_network.network.strain_clamp import (
    rod_clamped,
    rod_strain_error,
    simulate_strain_clamped,
)
from continuum_vs_network.scenes import units_time_modes as um


def _setup(strain=1e-3):
    net = triangular_lattice(6, 6)
    pinned = np.zeros((net.n_nodes, 2), dtype=bool)
    pinned[[0, 5]] = True  # two nodes, both coordinates: no rigid motion left
    s = net.n_springs // 2
    clamp = {s: float(net.rest_length[s] * (1 + strain))}
    return net, pinned, s, clamp


@pytest.mark.parametrize("factor", [1e5, 1e6])
def test_rod_clamp_holds_the_clamp_strain_and_ends_at_the_exact_clamp_state(factor):
    net, pinned, _, clamp = _setup(strain=1e-2)
    traj = simulate_strain_clamped(
        net, clamped=clamp, factor=factor, dt=2.0, t_end=1200.0, pinned=pinned, inertia=False
    )
    err = max(float(np.max(np.abs(rod_strain_error(net, clamp, x)))) for x in traj.positions[1:])
    assert err < 1e-6
    assert err < 1e2 / factor  # a penalty: the strain error ~ tension / k_rod
    exact = relax(net, pinned=pinned, clamped=clamp, tol=1e-14).positions
    # the clamp step moves nodes by ~1e-2; the run ends within its stall distance
    # (100 eps factor / lambda_min ~ 1.5e-6 at factor 1e6)
    assert np.max(np.abs(traj.positions[-1] - exact)) < 1e-5


def test_rod_strain_error_falls_as_one_over_the_rod_stiffness():
    net, pinned, _, clamp = _setup(strain=1e-2)
    errs = []
    for factor in (1e5, 1e7):
        traj = simulate_strain_clamped(
            net, clamped=clamp, factor=factor, dt=0.5, t_end=2.0, pinned=pinned, inertia=False
        )
        errs.append(float(np.max(np.abs(rod_strain_error(net, clamp, traj.positions[-1])))))
    assert 50 < errs[0] / errs[1] < 200


def test_rod_clamp_decays_at_the_strain_constrained_slowest_mode():
    net, pinned, s, clamp = _setup(strain=1e-3)  # linear response
    dt = 0.5
    traj = simulate_strain_clamped(
        net, clamped=clamp, factor=1e5, dt=dt, t_end=400.0, pinned=pinned, inertia=False
    )  # factor 1e5: the stall distance (module docstring) far below d(400)
    x_end = relax(net, pinned=pinned, clamped=clamp, tol=1e-14).positions
    d = np.array([np.linalg.norm(x - x_end) for x in traj.positions])
    i0, i1 = int(200 / dt), int(400 / dt)  # the next mode (2x faster) has decayed
    assert d[i1] > 1e-3 * d[0]  # still above the solver tolerance
    rate = math.log(d[i0] / d[i1]) / ((i1 - i0) * dt)  # backward Euler: (1 + lam dt)^-1 a step
    lam_measured = (math.exp(rate * dt) - 1.0) / dt
    free = ~pinned.ravel()
    K = hessian(net.positions, net).tocsr()[free][:, free]
    C = sp.identity(int(free.sum()), format="csr")
    G = strain_jacobian(net.positions, net.springs[[s]]).tocsc()[:, free]
    lam_constraint = um.slowest_mode(K, C, G)[0]
    assert lam_measured == pytest.approx(lam_constraint, rel=1e-3)  # unclamped: 0.9 % off
    # the end-node clamp (both end nodes held) is a different, faster mode
    held = pinned.copy()
    held[net.springs[s]] = True
    f2 = ~held.ravel()
    Kh = hessian(net.positions, net).tocsr()[f2][:, f2]
    lam_nodes = um.slowest_mode(Kh, sp.identity(int(f2.sum()), format="csr"))[0]
    assert lam_nodes > 1.5 * lam_constraint


def test_rod_clamped_rejects_bad_input():
    net, _, s, _ = _setup()
    with pytest.raises(ValueError, match="outside"):
        rod_clamped(net, {net.n_springs: 1.0})
    with pytest.raises(ValueError, match="finite and > 0"):
        rod_clamped(net, {s: -1.0})
    with pytest.raises(ValueError, match="factor"):
        rod_clamped(net, {s: 1.0}, factor=0.0)
