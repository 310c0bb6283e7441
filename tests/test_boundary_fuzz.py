"""Junk for every argument of relax, SpringNetwork and the rules: a named error or a result.

Hypothesis draws values a user might pass by mistake (wrong types, NaN, huge integers,
nested containers) for one argument at a time; the only acceptable outcomes are a valid
result, an :class:`ArgumentError`, or the documented ValueError / EquilibriumError of the
physics (a floppy network, no convergence). Any other exception (AttributeError,
OverflowError, IndexError, numpy's TypeError) is a boundary that let junk through.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import continuum_vs_network as cvn
from continuum_vs_network._validate import ArgumentError
from continuum_vs_network.learning import Solver

NET = cvn.triangular_lattice(3, 3)

JUNK = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.floats(allow_nan=True, allow_infinity=True),
    st.complex_numbers(allow_nan=True, allow_infinity=True),
    st.text(max_size=5),
    st.lists(st.integers(min_value=-3, max_value=40), max_size=4),
    st.lists(st.lists(st.booleans(), min_size=2, max_size=2), max_size=10),
    st.dictionaries(st.integers(-2, 30), st.floats(allow_nan=True), max_size=3),
    st.dictionaries(st.floats(allow_nan=True), st.floats(), max_size=2),
    st.dictionaries(st.text(max_size=2), st.text(max_size=2), max_size=2),
    st.builds(np.zeros, st.tuples(st.integers(0, 10), st.integers(1, 3))),
)


def _acceptable(err: BaseException, name: str) -> bool:
    """A named error: ours, the solver's, or a plain ValueError naming the argument."""
    if isinstance(err, ArgumentError | cvn.EquilibriumError):
        return True
    return type(err) is ValueError and ("floppy" in str(err) or name in str(err))


RELAX_ARGS = ["pinned", "clamped", "x0", "method", "tol", "clamp", "rod_stiffness", "ramp",
              "max_iter", "max_seconds"]  # fmt: skip


@pytest.mark.parametrize("name", RELAX_ARGS)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(value=JUNK)
def test_relax_answers_junk_with_a_named_error(name, value):
    try:
        eq = cvn.relax(NET, **{"max_seconds": 5.0, name: value})
    except Exception as err:
        assert _acceptable(err, name), f"{name}={value!r}: {type(err).__name__}: {err}"
        if isinstance(err, ArgumentError):
            assert err.argument.split("[")[0].split(" ")[0] in (name, "net"), str(err)
    else:
        assert eq.converged and np.all(np.isfinite(eq.positions))


@pytest.mark.parametrize("name", ["positions", "springs", "stiffness", "rest_length"])
@settings(max_examples=40, deadline=None)
@given(value=JUNK)
def test_spring_network_answers_junk_with_a_named_error(name, value):
    fields = {
        "positions": NET.positions,
        "springs": NET.springs,
        "stiffness": NET.stiffness,
        "rest_length": NET.rest_length,
    }
    fields[name] = value
    try:
        net = cvn.SpringNetwork(**fields)
    except Exception as err:
        # a wrong count shows in another field (springs naming missing nodes, stiffness
        # of the wrong length): a named error too
        assert any(_acceptable(err, f) for f in fields), (
            f"{name}={value!r}: {type(err).__name__}: {err}"
        )
    else:
        assert net.n_nodes >= 1


SOLVER_ARGS = ["method", "tol", "clamp", "rod_stiffness", "max_iter", "ramp", "reuse",
               "refactor_ratio", "accept_unconverged", "max_seconds", "retry_ramps", "anderson",
               "trust_region", "trust_region_max_free"]  # fmt: skip


@pytest.mark.parametrize("name", SOLVER_ARGS)
@settings(max_examples=25, deadline=None)
@given(value=JUNK)
def test_solver_answers_junk_with_a_named_error(name, value):
    try:
        Solver(**{name: value})
    except Exception as err:
        assert isinstance(err, ArgumentError), f"{name}={value!r}: {type(err).__name__}: {err}"


@pytest.mark.parametrize("name", ["alpha", "eta", "dof", "learn_sources", "min_rest_length"])
@settings(max_examples=25, deadline=None)
@given(value=JUNK)
def test_coupled_learning_answers_junk_with_a_named_error(name, value):
    kwargs = {"alpha": 1e-3, "eta": 0.1, name: value}
    try:
        cvn.CoupledLearning(**kwargs)
    except Exception as err:
        assert isinstance(err, ArgumentError), f"{name}={value!r}: {type(err).__name__}: {err}"


TOML_JUNK = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.integers(min_value=-(2**64), max_value=2**64), max_size=3),
    st.lists(st.text(max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


def _scene_keys() -> list[tuple[str, str]]:
    import tomllib

    from continuum_vs_network.scenes.schema import builtin_path

    keys = []
    for name in ("paper", "transmission", "relaxation"):
        data = tomllib.loads(builtin_path(name).read_text())
        for top, value in data.items():
            if isinstance(value, dict):
                keys += [(name, f"{top}.{k}") for k in value]
            else:
                keys.append((name, top))
    return keys


@pytest.mark.parametrize(("scene", "key"), _scene_keys())
@settings(max_examples=15, deadline=None)
@given(value=TOML_JUNK)
def test_scene_keys_answer_junk_with_a_scene_error(scene, key, value):
    import tomllib

    from continuum_vs_network.scenes.schema import SceneError, builtin_path, parse_scene

    data = tomllib.loads(builtin_path(scene).read_text())
    table, _, name = key.rpartition(".")
    (data[table] if table else data)[name] = value
    try:
        parse_scene(data, "fuzz.toml")
    except SceneError as err:
        assert name in str(err) or "fuzz.toml" in str(err)
