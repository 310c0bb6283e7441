"""jammed_network(..., dz=...): pruning a jammed contact network to an excess coordination."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.network.jammed import jammed_network
from continuum_vs_network.network.rigidity import is_rigid, rigidity_matrix

N_DISCS, PHI, SEED = 300, 0.92, 3  # Z - Z_iso of the unpruned network is about 0.7


def _degrees(net):
    return np.bincount(net.springs.ravel(), minlength=net.n_nodes)


@pytest.fixture(scope="module")
def full_and_state():
    """The unpruned network (no dz argument) and the state of its rng afterwards."""
    rng = np.random.default_rng(SEED)
    return jammed_network(N_DISCS, rng, phi=PHI), rng.bit_generator.state


@pytest.fixture(scope="module")
def full(full_and_state):
    return full_and_state[0]


@pytest.fixture(scope="module", params=[0.0, 0.1, 0.5])
def pruned(request):
    dz = request.param
    return dz, jammed_network(N_DISCS, np.random.default_rng(SEED), phi=PHI, dz=dz)


def test_spring_count_is_exact(pruned):
    dz, net = pruned
    n = net.n_nodes
    assert 200 <= n <= N_DISCS
    assert net.n_springs == 2 * n - 3 + round(n * dz / 2)
    z, z_iso = 2 * net.n_springs / n, 2 * (2 * n - 3) / n
    assert abs((z - z_iso) - dz) <= 1 / n  # round() moves S by at most 1/2 spring


def test_rigid_with_the_expected_states_of_self_stress(pruned):
    dz, net = pruned
    assert is_rigid(net, method="dense")
    rank = np.linalg.matrix_rank(rigidity_matrix(net).toarray())
    assert 2 * net.n_nodes - rank == 3  # zero modes: the rigid motions only
    assert net.n_springs - rank == round(net.n_nodes * dz / 2)  # states of self-stress
    assert _degrees(net).min() >= 3


def test_stress_free_and_a_subnetwork_of_the_contacts(pruned, full):
    _, net = pruned
    d = net.positions[net.springs[:, 1]] - net.positions[net.springs[:, 0]]
    np.testing.assert_allclose(net.rest_length, np.hypot(d[:, 0], d[:, 1]), rtol=1e-14)
    np.testing.assert_allclose(net.stiffness, 1.0 / net.rest_length, rtol=1e-14)
    assert cvn.energy(net.positions, net) < 1e-28
    assert np.max(np.abs(cvn.forces(net.positions, net))) < 1e-12
    # same packing (dz draws only after it), springs only removed, order kept
    np.testing.assert_array_equal(net.positions, full.positions)
    index = {tuple(s): i for i, s in enumerate(full.springs.tolist())}
    rows = np.array([index[tuple(s)] for s in net.springs.tolist()])
    assert np.all(np.diff(rows) > 0)
    np.testing.assert_array_equal(net.rest_length, full.rest_length[rows])


def test_removal_favours_highly_coordinated_nodes(pruned, full):
    _, net = pruned
    before, after = _degrees(full), _degrees(net)
    assert after.std() < before.std()
    assert after.max() <= before.max()


def test_dz_none_is_the_unpruned_network_and_draws_nothing_more(full_and_state):
    full, state = full_and_state
    rng = np.random.default_rng(SEED)
    net = jammed_network(N_DISCS, rng, phi=PHI, dz=None)
    np.testing.assert_array_equal(net.positions, full.positions)
    np.testing.assert_array_equal(net.springs, full.springs)
    np.testing.assert_array_equal(net.rest_length, full.rest_length)
    np.testing.assert_array_equal(net.stiffness, full.stiffness)
    assert rng.bit_generator.state == state


def test_reproducible_and_uniform_stiffness():
    a = jammed_network(150, np.random.default_rng(11), phi=PHI, dz=0.2, stiffness=2.5)
    b = jammed_network(150, np.random.default_rng(11), phi=PHI, dz=0.2, stiffness=2.5)
    np.testing.assert_array_equal(a.springs, b.springs)
    np.testing.assert_array_equal(a.stiffness, 2.5)
    assert a.n_springs == 2 * a.n_nodes - 3 + round(a.n_nodes * 0.2 / 2)
    assert is_rigid(a, method="dense")


def test_dz_of_the_unpruned_network_keeps_every_spring(full):
    n = full.n_nodes
    dz_full = 2 * full.n_springs / n - 2 * (2 * n - 3) / n
    net = jammed_network(N_DISCS, np.random.default_rng(SEED), phi=PHI, dz=dz_full)
    np.testing.assert_array_equal(net.springs, full.springs)


def test_too_large_dz_raises_naming_dz_and_the_z_reached():
    with pytest.raises(ValueError, match=r"dz = 2\.0 .*Z = 4\.\d+.*dz must be <= 0\.\d+") as err:
        jammed_network(150, np.random.default_rng(0), phi=0.86, dz=2.0)
    assert err.value.argument == "dz"
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"dz": -0.1}, "dz"),
        ({"dz": float("nan")}, "dz"),
        ({"dz": "0.1"}, "dz"),
        ({"dz": True}, "dz"),
        ({"dz": 0.1, "n_nodes": 5000}, "n_nodes"),
    ],
)
def test_bad_dz_is_refused_before_packing(kwargs, name):
    kwargs = {"n_nodes": 100, **kwargs}
    with pytest.raises(ValueError, match=name):
        jammed_network(rng=np.random.default_rng(0), **kwargs)
