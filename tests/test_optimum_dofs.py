"""The optimum of a task for every learning dof (learning.optimum): what the task allows."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import AllosteryTask, anchored
from continuum_vs_network.learning import optimum as om
from continuum_vs_network.learning.optimum import exact_optimum, optima
from continuum_vs_network.learning.ranges import REST_LENGTH_RANGE, STIFFNESS_RANGE

DOFS = ("stiffness", "rest_length", "both")
TIGHT = {"stiffness_range": (0.5, 2.0), "rest_length_range": (0.95, 1.05)}


def _setup(n: int = 64, seed: int = 1):
    """A small jammed network, a 1 -> 1 task (source and target half the box apart,
    on either side of its centre) anchored by its rest example."""
    net = cvn.jammed_network(n, np.random.default_rng(seed), phi=0.86)
    mid = 0.5 * (net.positions[net.springs[:, 0]] + net.positions[net.springs[:, 1]])
    low, high = net.positions.min(axis=0), net.positions.max(axis=0)
    centre, width = (low + high) / 2, high[0] - low[0]

    def nearest(x: float) -> int:
        return int(np.argmin(np.hypot(mid[:, 0] - x, mid[:, 1] - centre[1])))

    src, tgt = nearest(centre[0] - width / 4), nearest(centre[0] + width / 4)
    assert src != tgt
    task = AllosteryTask.create(net, [src], 0.05, [tgt], 0.015)
    return net, anchored(task, net)


@pytest.fixture(scope="module")
def case():
    return _setup()


def _frozen(net, tasks):
    out = np.zeros(net.n_springs, dtype=bool)
    for task in tasks.tasks:
        out[task.sources] = out[task.targets] = True
    return out


@pytest.mark.parametrize("dof", DOFS)
def test_the_gradient_the_search_sees_matches_a_finite_difference_of_c(case, dof):
    net, tasks = case
    p = om._Problem(net, tasks, dof, STIFFNESS_RANGE, REST_LENGTH_RANGE, None, None)
    rng = np.random.default_rng(7)
    # at the untrained network and at a point 2 % away (every example with C_e > 0 there)
    u1 = p.u0 + 0.02 * rng.uniform(-1, 1, p.u0.size) / p.a
    for u in (p.u0, u1):
        _, g, _ = p.objective(u)
        p.accept(u)
        d = rng.normal(size=u.size)
        d /= np.max(np.abs(p.a * d))  # a step h moves every z = v / mean(v0) by <= h
        h = 1e-4
        fd = (p.objective(u + h * d)[0] - p.objective(u - h * d)[0]) / (2 * h)
        assert fd == pytest.approx(g @ d, rel=1e-5), (dof, fd, g @ d)
    # the variables: relative values of the learning springs, JOINT order for "both"
    mask = ~_frozen(net, tasks)
    z = p.z(u1)
    values = p.values(z)
    parts = ("rest_length", "stiffness") if dof == "both" else (dof,)
    for i, d in enumerate(parts):
        n = int(mask.sum())
        assert np.allclose(values[d][mask] / np.mean(getattr(net, d)), z[i * n : (i + 1) * n])
        assert np.array_equal(values[d][~mask], getattr(net, d)[~mask])


@pytest.mark.parametrize("dof", DOFS)
def test_the_optimum_stays_within_the_ranges(case, dof):
    net, tasks = case
    o = exact_optimum(net, tasks, dof=dof, **TIGHT)
    assert o.dof == dof and o.error < o.error_initial
    assert o.ratio == pytest.approx(o.error / o.error_initial)
    frozen = _frozen(net, tasks)
    q_k = o.net.stiffness / net.stiffness
    q_L = o.net.rest_length / net.rest_length
    eps = 1e-12
    for q, (low, high), learns in (
        (q_k, TIGHT["stiffness_range"], dof != "rest_length"),
        (q_L, TIGHT["rest_length_range"], dof != "stiffness"),
    ):
        assert np.all(q >= low * (1 - eps)) and np.all(q <= high * (1 + eps))
        assert np.all(q[frozen] == 1.0)  # bulk learning: sources and targets keep theirs
        if learns:  # the tight range binds: some value sits on a bound
            assert np.any(np.isclose(q, low, rtol=1e-9) | np.isclose(q, high, rtol=1e-9))
        else:
            assert np.all(q == 1.0)
    bulk = ~frozen
    expected = q_k[bulk].max() / q_k[bulk].min() if dof != "rest_length" else 1.0
    assert o.contrast == pytest.approx(expected)
    # the reported errors are those of the free states at the optimum; the rest example
    # starts met (C_e0 = 0), so both examples are measured against C0 (the task's C_e0)
    for task, x, ratio in zip(tasks.tasks, o.free, o.example_ratio):
        assert ratio == pytest.approx(task.error(o.net, x) / o.error_initial, rel=1e-9)
    assert sum(task.error(o.net, x) for task, x in zip(tasks.tasks, o.free)) == pytest.approx(
        o.error, rel=1e-9
    )
    assert o.feasible(1.0 + np.max(o.example_ratio))
    assert not o.feasible(0.5 * np.max(o.example_ratio))


def test_both_dofs_together_do_no_worse_than_either_alone(case):
    # A joint local search from the untrained network can stop at a snap-through that a
    # single-dof search avoids (seen on jammed networks), so optima() starts it from the
    # better single optimum: L-BFGS-B accepts no increase, so it keeps or lowers that error.
    net, tasks = case
    r = optima(net, tasks, **TIGHT)
    best = min(r["stiffness"].error, r["rest_length"].error)
    assert r["both"].error <= best * (1 + 1e-6)
    # on this draw neither dof alone meets the task in the tight ranges, and both do better
    assert r["both"].ratio < 0.9 * best / r["both"].error_initial
    assert r["both"].dof == "both"
    assert not np.array_equal(r["both"].net.stiffness, net.stiffness)
    assert not np.array_equal(r["both"].net.rest_length, net.rest_length)


@pytest.mark.parametrize("dof", DOFS)
def test_no_freedom_leaves_the_initial_error(case, dof):
    net, tasks = case
    o = exact_optimum(net, tasks, dof=dof, stiffness_range=(1, 1), rest_length_range=(1, 1))
    assert o.error == pytest.approx(o.error_initial, rel=1e-12)
    assert o.ratio == pytest.approx(1.0, rel=1e-12)
    assert np.array_equal(o.net.stiffness, net.stiffness)
    assert np.array_equal(o.net.rest_length, net.rest_length)
    assert o.contrast == 1.0


def test_a_floor_still_bounds_the_stiffnesses(case):
    net, tasks = case
    k0 = net.stiffness
    floor = 0.5 * float(np.mean(k0))
    o = exact_optimum(net, tasks, floor=floor, stiffness_range=None)  # as before: floor only
    assert o.error < o.error_initial
    learned = ~_frozen(net, tasks)
    assert o.net.stiffness[learned].min() >= floor * (1 - 1e-12)
    assert np.any(np.isclose(o.net.stiffness[learned], floor, rtol=1e-9))
    # with the range: the larger of the two lower bounds
    o = exact_optimum(net, tasks, floor=floor)
    low = np.maximum(floor, STIFFNESS_RANGE[0] * k0)
    high = np.maximum(STIFFNESS_RANGE[1] * k0, low)
    assert np.all(o.net.stiffness[learned] >= low[learned] * (1 - 1e-12))
    assert np.all(o.net.stiffness[learned] <= high[learned] * (1 + 1e-12))
    # a floor has nothing to bound when the rest lengths learn
    o = exact_optimum(net, tasks, dof="rest_length", floor=10 * float(np.max(k0)))
    assert np.array_equal(o.net.stiffness, k0)


def test_bad_arguments_are_refused(case):
    net, tasks = case
    with pytest.raises(ValueError, match="dof"):
        exact_optimum(net, tasks, dof="modulus")
    with pytest.raises(ValueError, match="stiffness_range"):
        exact_optimum(net, tasks, stiffness_range=(2.0, 3.0))
    with pytest.raises(ValueError, match="rest_length_range"):
        exact_optimum(net, tasks, rest_length_range=(0.5,))
    with pytest.raises(ValueError, match="floor"):
        exact_optimum(net, tasks, floor=-1.0)
    with pytest.raises(ValueError, match="start"):
        exact_optimum(net, tasks, start=net)
