"""Bad arguments at every public boundary: one ArgumentError naming the argument and value.

Each case is an input a user can plausibly type; the test asserts the error type (a
``ValueError`` and a ``TypeError`` at once, so either ``except`` catches it), that the
message names the argument, and that no numpy/scipy wording leaks through.
"""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network import _validate
from continuum_vs_network._validate import ArgumentError
from continuum_vs_network.learning import Solver

_NUMPY_WORDS = ("ufunc", "could not convert", "cannot reshape", "unhashable", "object has no")


def _lattice() -> cvn.SpringNetwork:
    return cvn.triangular_lattice(4, 4)


def _assert_named(err: BaseException, *words: str) -> None:
    assert isinstance(err, ArgumentError)
    assert isinstance(err, ValueError) and isinstance(err, TypeError)
    msg = str(err)
    for w in words:
        assert w in msg, (w, msg)
    assert not any(n in msg for n in _NUMPY_WORDS), msg


NET = _lattice()
P, S, K, L = NET.positions, NET.springs, NET.stiffness, NET.rest_length


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: cvn.SpringNetwork(P + 0j, S, K, L), ("positions", "complex")),
        (lambda: cvn.SpringNetwork(P.astype(str), S, K, L), ("positions",)),
        (lambda: cvn.SpringNetwork(P, S.astype(str), K, L), ("springs",)),
        (lambda: cvn.SpringNetwork(P, [[0, 2**70], *S.tolist()[1:]], K, L), ("springs[0, 1]",)),
        (lambda: cvn.SpringNetwork(P, S.astype(bool), K, L), ("springs", "bool")),
        (lambda: cvn.SpringNetwork(P, S + 0.5, K, L), ("springs[0, 0]", "0.5")),
        (
            lambda: cvn.SpringNetwork(np.zeros((0, 2)), np.zeros((0, 2), int), [], []),
            ("positions",),
        ),
        (lambda: cvn.SpringNetwork(P, S, K + 1j, L), ("stiffness",)),
        (lambda: cvn.SpringNetwork(P, S, K, "abc"), ("rest_length",)),
    ],
)
def test_spring_network_refuses_bad_arrays(make, words):
    with pytest.raises(ArgumentError) as info:
        make()
    _assert_named(info.value, *words)


def test_complex_positions_are_refused_not_truncated():
    # the old behaviour dropped the imaginary part with only a ComplexWarning
    with pytest.raises(ArgumentError, match="positions"):
        cvn.SpringNetwork(P + 1e-3j, S, K, L)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"pinned": np.zeros((16, 2), int)}, ("pinned", "dtype=bool")),
        ({"pinned": np.ones((16, 2), float)}, ("pinned",)),
        ({"pinned": [2**70]}, ("pinned[0]", "1180591620717411303424")),
        ({"pinned": ["a"]}, ("pinned",)),
        ({"pinned": [True, False]}, ("pinned",)),
        ({"clamped": {1.7: 1.0}}, ("clamped key", "1.7")),
        ({"clamped": {True: 1.0}}, ("clamped key", "True")),
        ({"clamped": {"3": 1.0}}, ("clamped key",)),
        ({"clamped": {2**70: 1.0}}, ("clamped key",)),
        ({"clamped": {1: "abc"}}, ("clamped[1]", "abc")),
        ({"clamped": {1: None}}, ("clamped[1]", "None")),
        ({"clamped": [(1, 1.0)]}, ("clamped", "mapping")),
        ({"tol": "1e-8"}, ("tol", "'1e-8'")),
        ({"tol": float("nan")}, ("tol",)),
        ({"tol": True}, ("tol", "bool")),
        ({"max_iter": 0}, ("max_iter", "0")),
        ({"max_iter": -5}, ("max_iter", "-5")),
        ({"max_iter": 2.5}, ("max_iter",)),
        ({"max_iter": True}, ("max_iter", "bool")),
        ({"max_seconds": float("nan")}, ("max_seconds", "nan")),
        ({"max_seconds": -1}, ("max_seconds", "-1")),
        ({"max_seconds": "10"}, ("max_seconds",)),
        ({"method": ["newton"]}, ("method", "['newton']")),
        ({"method": None}, ("method",)),
        ({"clamp": "glue"}, ("clamp",)),
        ({"ramp": 1.5}, ("ramp",)),
        ({"rod_stiffness": -1.0}, ("rod_stiffness",)),
        ({"x0": P + 0j}, ("x0",)),
        ({"x0": P[:3]}, ("x0", "shape")),
    ],
)
def test_relax_refuses_bad_arguments(kwargs, words):
    with pytest.raises(ArgumentError) as info:
        cvn.relax(NET, **kwargs)
    _assert_named(info.value, *words)


@pytest.mark.parametrize(
    ("net", "words"),
    [
        ({}, ("net", "SpringNetwork", "dict")),
        (None, ("net",)),
        (cvn.SpringNetwork(P, np.zeros((0, 2), int), [], []), ("net", "at least one spring")),
        (cvn.SpringNetwork(np.vstack([P, [[9.0, 9.0]]]), S, K, L), ("net", "node 16")),
    ],
)
def test_relax_refuses_what_is_not_a_solvable_network(net, words):
    with pytest.raises(ArgumentError) as info:
        cvn.relax(net)
    _assert_named(info.value, *words)


def test_valid_spellings_still_work():
    mask = np.zeros((16, 2), bool)
    mask[0] = True
    mask[3, 1] = True
    eq = cvn.relax(NET, pinned=mask, clamped={np.int64(5): float(L[5]) * 1.05}, max_iter=50)
    assert eq.converged
    eq2 = cvn.relax(NET, pinned=[0, 3], clamped={5.0: float(L[5]) * 1.05}, tol=1e-9)
    assert eq2.converged and abs(NET.lengths(eq2.positions)[5] - L[5] * 1.05) < 1e-8


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"anderson": -3}, ("anderson", "-3")),
        ({"ramp": 0}, ("ramp", "0")),
        ({"max_seconds": -1}, ("max_seconds", "-1")),
        ({"max_seconds": float("nan")}, ("max_seconds",)),
        ({"max_iter": 0}, ("max_iter",)),
        ({"tol": "1e-8"}, ("tol",)),
        ({"method": ["newton"]}, ("method",)),
        ({"retry_ramps": (5, 0)}, ("retry_ramps[1]",)),
        ({"retry_ramps": 5}, ("retry_ramps",)),
        ({"reuse": "yes"}, ("reuse",)),
        ({"refactor_ratio": 1.0}, ("refactor_ratio",)),
        ({"trust_region_max_free": -1}, ("trust_region_max_free",)),
    ],
)
def test_solver_refuses_bad_fields_at_construction(kwargs, words):
    with pytest.raises(ArgumentError) as info:
        Solver(**kwargs)
    _assert_named(info.value, *words)


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: cvn.CoupledLearning("a", 0.1), ("alpha", "'a'")),
        (lambda: cvn.CoupledLearning(rate=0.1), ("rate", "0.1")),
        (lambda: cvn.CoupledLearning(1e-3, float("inf")), ("eta",)),
        (lambda: cvn.ProspectiveConfiguration(-1.0), ("alpha",)),
        (lambda: cvn.ExactGradient(1.0, cost="energy"), ("cost",)),
        (lambda: cvn.CoupledLearning(1e-3, 0.1, dof="mass"), ("dof",)),
        (lambda: cvn.CoupledLearning(1e-3, 0.1, learn_sources=1), ("learn_sources",)),
        (lambda: cvn.CoupledLearning(1e-3, 0.1, min_rest_length="0"), ("min_rest_length",)),
        (lambda: cvn.CoupledLearning(1e-3, 0.1, strain_reference=None), ("strain_reference",)),
    ],
)
def test_rules_refuse_bad_parameters(make, words):
    with pytest.raises(ArgumentError) as info:
        make()
    _assert_named(info.value, *words)


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: cvn.triangular_lattice(10**7, 10**7), ("nx, ny", "too large", "memory")),
        (lambda: cvn.triangular_lattice(True, 3), ("nx", "bool")),
        (lambda: cvn.triangular_lattice(3, "4"), ("ny",)),
        (lambda: cvn.triangular_lattice(3, 3, spacing="1"), ("spacing",)),
        (lambda: cvn.triangular_lattice(3, 3, noise=0.1), ("rng",)),
        (lambda: cvn.triangular_lattice(3, 3, stiffness="k"), ("stiffness",)),
        (lambda: cvn.paper_network(np.random.default_rng(0), noise=float("nan")), ("noise",)),
        (lambda: cvn.paper_network(0), ("rng",)),
        (lambda: cvn.diluted_lattice(4, 4, "0.1", np.random.default_rng(0)), ("fraction",)),
        (lambda: cvn.jammed_network(10**12, np.random.default_rng(0)), ("n_nodes", "memory")),
    ],
)
def test_builders_refuse_bad_arguments_before_allocating(make, words):
    with pytest.raises((ArgumentError, ValueError)) as info:
        make()
    for w in words:
        assert w in str(info.value)


def test_memory_limit_follows_the_machine(monkeypatch):
    """The same lattice is refused on a small machine and built on a large one."""
    monkeypatch.setattr(_validate, "available_memory", lambda: 1_000_000)
    with pytest.raises(ArgumentError, match="nx, ny"):
        cvn.triangular_lattice(100, 100)  # 10**4 nodes need about 6 MB
    monkeypatch.setattr(_validate, "available_memory", lambda: 10**12)
    assert cvn.triangular_lattice(100, 100).n_nodes == 10**4


def test_available_memory_is_positive_and_below_a_petabyte():
    avail = _validate.available_memory()
    assert 0 < avail < 2**50


def _gcl():
    return cvn.CoupledLearning(1e-3, 0.1)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"seeds": [-1]}, ("seeds[0]", "-1")),
        ({"seeds": [2**70]}, ("seeds[0]", "1180591620717411303424")),
        ({"seeds": [0, "1"]}, ("seeds[1]",)),
        ({"seeds": 3}, ("seeds",)),
        ({"seeds": []}, ("seeds",)),
        ({"steps": 10**12}, ("steps", "too large", "memory")),
        ({"steps": -1}, ("steps",)),
        ({"steps": 2.5}, ("steps",)),
        ({"noise": "0"}, ("noise",)),
        ({"checkpoint_every": 0}, ("checkpoint_every",)),
        ({"callback": 3}, ("callback",)),
    ],
)
def test_train_refuses_bad_arguments_at_once(kwargs, words):
    args = {"steps": 2, **kwargs}
    steps = args.pop("steps")
    with pytest.raises(ArgumentError) as info:
        cvn.train(cvn.paper_network, cvn.paper_task, _gcl(), steps, progress=False, **args)
    _assert_named(info.value, *words)


def test_train_checkpoint_in_a_missing_folder_fails_before_the_first_step(tmp_path):
    calls = []
    with pytest.raises(ArgumentError, match="no folder") as info:
        cvn.train(
            cvn.paper_network,
            cvn.paper_task,
            _gcl(),
            5,
            checkpoint=tmp_path / "missing" / "ckpt.npz",
            checkpoint_every=2,
            progress=False,
            callback=lambda *a: calls.append(a),
        )
    assert calls == [] and "checkpoint" in str(info.value)
    with pytest.raises(ArgumentError, match="folder"):
        cvn.train(cvn.paper_network, cvn.paper_task, _gcl(), 1, checkpoint=tmp_path)


def test_overflowing_update_stops_each_trial_with_a_learning_error():
    """An update that overflows to inf/nan ends its trial with a reason; the others run."""
    huge = cvn.CoupledLearning(1e300, 1e-300)
    with np.errstate(all="ignore"):
        h = cvn.train(cvn.paper_network, cvn.paper_task, huge, 3, seeds=[0, 1], progress=False)
    assert list(h.completed) == [0, 0]
    for reason in h.stop_reason:
        assert "LearningError" in reason and "not finite" in reason
    assert all(np.all(np.isfinite(n.rest_length)) for n in h.final)


def test_step_apply_refuses_a_non_finite_delta():
    from continuum_vs_network.learning import Step

    delta = np.zeros(NET.n_springs)
    delta[4] = np.inf
    step = Step(delta=delta, dof="rest_length", free=None, clamped=None)
    with pytest.raises(cvn.LearningError, match="spring 4"):
        step.apply(NET)


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: cvn.AllosteryTask.create(NET, ["a"], [0.1], [9], [0.1]), ("sources",)),
        (lambda: cvn.AllosteryTask.create(NET, [2**70], [0.1], [9], [0.1]), ("sources[0]",)),
        (lambda: cvn.AllosteryTask.create(NET, [1], [0.1 + 1j], [9], [0.1]), ("source_strain",)),
        (lambda: cvn.AllosteryTask.create(NET, [1], [0.1], [9], ["x"]), ("target_strain",)),
        (
            lambda: cvn.AllosteryTask.create(NET, [1], [0.1], [9], [0.1], pinned=np.ones((16, 2))),
            ("pinned", "bool"),
        ),
        (lambda: cvn.stern_task(NET, 2, 1, None), ("rng",)),
        (lambda: cvn.stern_task(NET, True, 1, np.random.default_rng(0)), ("n_sources",)),
        (lambda: cvn.paper_task(NET, np.random.default_rng(0), source_std="1"), ("source_std",)),
        (lambda: cvn.paper_task({}, np.random.default_rng(0)), ("net",)),
    ],
)
def test_tasks_refuse_bad_arguments(make, words):
    with pytest.raises(ArgumentError) as info:
        make()
    _assert_named(info.value, *words)


def test_a_pinned_node_without_springs_is_allowed():
    net = cvn.SpringNetwork(np.vstack([P, [[9.0, 9.0]]]), S, K, L)
    eq = cvn.relax(net, pinned=[0, 3, 16])
    assert eq.converged and np.array_equal(eq.positions[16], [9.0, 9.0])


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: cvn.energy(P + 1j, NET), ("x", "complex")),
        (lambda: cvn.energy(P, {}), ("net", "dict")),
        (lambda: cvn.forces(P[:3], NET), ("x", "shape")),
        (lambda: cvn.hessian("x", NET), ("x",)),
        (lambda: cvn.is_rigid({}), ("net",)),
        (lambda: cvn.zero_modes(None), ("net",)),
        (lambda: cvn.rigidity_matrix(NET, x=P + 1j), ("x",)),
        (lambda: cvn.default_pins(NET, avoid=[2**70]), ("avoid[0]",)),
        (lambda: cvn.simulate(NET, dt="0.1", t_end=1.0), ("dt", "'0.1'")),
        (lambda: cvn.simulate(NET, dt=1e-6, t_end=1e12), ("t_end", "too large", "memory")),
        (lambda: cvn.simulate(NET, dt=0.1, t_end=1.0, record_every=0), ("record_every",)),
        (lambda: NET.clamp_length(1.7, 0.1), ("spring", "1.7")),
        (lambda: NET.clamp_length(1, "a"), ("strain",)),
        (lambda: NET.lengths(P + 1j), ("x",)),
    ],
)
def test_physics_functions_refuse_bad_arguments(make, words):
    with pytest.raises(ArgumentError) as info:
        make()
    _assert_named(info.value, *words)
