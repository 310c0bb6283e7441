"""SpringNetwork: validation at the boundary, geometry helpers, copies."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn


def _triangle(**overrides):
    args = dict(
        positions=[[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]],
        springs=[[0, 1], [1, 2], [2, 0]],
        stiffness=[1.0, 2.0, 3.0],
        rest_length=[1.0, 1.0, 1.0],
    )
    args.update(overrides)
    return cvn.SpringNetwork(**args)


def test_arrays_are_read_only_float64_copies():
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.8]], dtype=np.float32)
    net = _triangle(positions=pos)
    assert net.positions.dtype == np.float64 and net.springs.dtype == np.int64
    pos[0, 0] = 99.0
    assert net.positions[0, 0] == 0.0
    with pytest.raises(ValueError):
        net.positions[0, 0] = 1.0


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"positions": [[0, 0], [1, 0]]}, r"springs\[1, 1\] must be node indices in 0..1, got 2"),
        ({"positions": np.zeros((3, 3))}, r"positions must be an array of shape \(n, 2\)"),
        ({"positions": [[0, 0], [1, np.nan], [0, 1]]}, r"positions must be finite; entry 1"),
        ({"springs": [[0, 1], [1, 1], [2, 0]]}, r"springs\[1\] is a self-loop on node 1"),
        ({"springs": [[0, 1], [1, 0], [2, 0]]}, r"springs\[1\] duplicates springs\[0\]"),
        (
            {"springs": [[0, 1.5], [1, 2], [2, 0]]},
            r"springs\[0, 1\] must be node indices in 0..2, got 1.5",
        ),
        ({"stiffness": [1.0, -2.0, 3.0]}, r"stiffness must be >= 0; stiffness\[1\] = -2.0"),
        ({"stiffness": [1.0, 2.0]}, r"stiffness must be an array of shape \(3,\)"),
        ({"rest_length": [1.0, 1.0, 0.0]}, r"rest_length must be > 0; rest_length\[2\] = 0.0"),
        ({"rest_length": [1.0, np.inf, 1.0]}, r"rest_length must be finite; entry 1"),
    ],
)
def test_validation_names_argument_and_first_bad_index(overrides, message):
    with pytest.raises(ValueError, match=message):
        _triangle(**overrides)


def test_strain_and_clamp_length_are_inverse():
    net = _triangle(rest_length=[2.0, 0.5, 1.0])
    lengths = net.lengths()
    np.testing.assert_allclose(lengths, 1.0)
    np.testing.assert_allclose(net.strains(), lengths / net.rest_length - 1)  # Eq. 24
    target = np.array([0.3, -0.5, 5.0])
    clamp = net.clamp_length([0, 1, 2], target)  # Eq. 25
    np.testing.assert_allclose(clamp / net.rest_length - 1, target)
    with pytest.raises(ValueError, match="strain must be > -1"):
        net.clamp_length(0, -1.0)
    with pytest.raises(ValueError, match=r"spring must be a spring index in 0\.\.2, got 3"):
        net.clamp_length(3, 0.1)


def test_lengths_of_chosen_springs_equal_the_full_lengths_there():
    """``lengths(x, springs)`` measures only the springs named: the same numbers as the full
    lengths at those indices, shaped as the selection; bad selections are named."""
    net = _triangle(positions=[[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    full = net.lengths()
    np.testing.assert_array_equal(full, [3.0, 5.0, 4.0])
    np.testing.assert_array_equal(net.lengths(None, [2, 0]), full[[2, 0]])
    assert net.lengths(None, 1).shape == () and float(net.lengths(None, 1)) == 5.0
    np.testing.assert_array_equal(net.lengths(None, full > 3.5), [5.0, 4.0])
    assert net.lengths(None, [[0, 1], [1, 2]]).shape == (2, 2)
    with pytest.raises(ValueError, match=r"springs must be a spring index in 0\.\.2, got 3"):
        net.lengths(None, 3)
    with pytest.raises(ValueError, match=r"springs\[1\] must be spring indices in 0\.\.2"):
        net.lengths(None, [0, -1])
    with pytest.raises(ValueError, match=r"springs must be a bool mask of shape \(3,\)"):
        net.lengths(None, np.ones(2, dtype=bool))


def test_with_copies_validate_and_share_topology():
    net = _triangle()
    moved = net.with_rest_length([1.5, 1.5, 1.5])
    assert moved.springs is net.springs  # shared: the Hessian pattern is cached per topology
    np.testing.assert_array_equal(net.rest_length, 1.0)
    with pytest.raises(ValueError, match="rest_length"):
        net.with_rest_length([1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="stiffness"):
        net.with_stiffness([1.0, 1.0])


@pytest.mark.parametrize("rows", [10, 5000])
def test_vector_lengths_match_hypot_also_where_squares_leave_float64(rows):
    """Ordinary lengths to a rounding unit of ``np.hypot``; lengths whose squares would
    overflow (1e200) or underflow (1e-200), zero and NaN exactly as ``np.hypot`` gives them
    and without a warning (RuntimeWarnings from the package are errors here)."""
    from continuum_vs_network.network.model import vector_lengths

    d = np.random.default_rng(0).normal(size=(rows, 2))
    assert np.allclose(vector_lengths(d), np.hypot(d[:, 0], d[:, 1]), rtol=3e-16, atol=0)
    for value in (1e200, -1e200, 1e-200, 0.0, np.nan, np.inf):
        extreme = d.copy()
        extreme[rows // 2] = (value, 3e-201)
        got = vector_lengths(extreme)
        assert np.array_equal(got, np.hypot(extreme[:, 0], extreme[:, 1]), equal_nan=True)
    assert np.isclose(vector_lengths(np.array([[3e200, 4e200]] * rows))[0], 5e200, rtol=1e-15)
