"""Topology stores: small springs arrays share results by content, large ones by identity."""

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.linalg import memo
from continuum_vs_network.network.builders import paper_network, triangular_lattice


def _read_only(a):
    a = np.array(a, dtype=np.int64)
    a.setflags(write=False)
    return a


def test_equal_small_arrays_share_a_store_and_different_ones_do_not():
    a = _read_only([[0, 1], [1, 2]])
    b = _read_only([[0, 1], [1, 2]])  # built apart, equal content
    c = _read_only([[0, 1], [2, 1]])
    assert memo.per_array(a, "test_share") is memo.per_array(b, "test_share")
    assert memo.per_array(a, "test_share") is not memo.per_array(c, "test_share")
    assert memo.per_array(a, "test_share") is not memo.per_array(a, "test_other_name")


def test_content_stores_keep_only_the_most_recent_topologies():
    first = _read_only([[0, 1]])
    memo.per_array(first, "test_lru")["x"] = 1
    for i in range(memo.CONTENT_KEPT):
        memo.per_array(_read_only([[0, i + 2]]), "test_lru")
    assert memo.per_array(first, "test_lru") == {}  # dropped, recomputed on demand


def test_large_arrays_are_kept_by_identity():
    n = memo.CONTENT_MAX_BYTES // 16 + 1
    a = _read_only(np.stack([np.arange(n), np.arange(n) + 1], axis=1))
    b = a.copy()
    b.setflags(write=False)
    assert memo.per_array(a, "test_big") is memo.per_array(a, "test_big")
    assert memo.per_array(a, "test_big") is not memo.per_array(b, "test_big")


def test_a_shared_rank_verdict_follows_the_springs_that_carry_load():
    """Patches built anew share their topology and so the rank count; the count cached
    for all springs must not serve the same springs with one of them at k = 0."""
    rigid = paper_network(np.random.default_rng(0))
    again = paper_network(np.random.default_rng(1))
    assert np.array_equal(rigid.springs, again.springs) and rigid.springs is not again.springs
    assert cvn.relax(rigid).converged and cvn.relax(again).converged
    # an over-braced lattice passes Maxwell's count with one spring at k = 0, but a
    # corner node then hangs on one spring: floppy by rank only
    lattice = triangular_lattice(4, 4)
    extra = np.array([[0, 5], [3, 12], [1, 9]])
    springs = np.vstack([lattice.springs, extra])
    n = len(springs)
    d = np.linalg.norm(np.diff(lattice.positions[springs], axis=1)[:, 0], axis=1)
    braced = cvn.SpringNetwork(lattice.positions, springs, np.ones(n), d)
    assert cvn.relax(braced).converged
    corner = int(np.flatnonzero(np.bincount(lattice.springs.ravel()) == 2)[-1])  # no brace
    k = np.ones(n)
    k[np.flatnonzero((springs == corner).any(axis=1))[0]] = 0.0
    rebuilt = cvn.SpringNetwork(lattice.positions, springs.copy(), k, d)
    with pytest.raises(ValueError, match="floppy: 1 zero modes"):
        cvn.relax(rebuilt)
