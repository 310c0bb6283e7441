"""Typed unit results (scenes.results): what a unit returns is what a section reads back,
through the same storage as untyped units."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.scenes.results import from_stored, to_stored
from continuum_vs_network.scenes.results.physics import TransmissionResult
from continuum_vs_network.scenes.store import _read_unit, _save_unit
from continuum_vs_network.scenes.units import Unit, UnitResult


def _network_only(**extra) -> TransmissionResult:
    distance = np.array([1.0, 2.0, 4.0])
    return TransmissionResult(
        n=8, n_nodes=64, n_springs=169, source=84, strain=0.1,
        springs=np.array([3, 1, 2]), distance=distance, network_strain=0.1 / distance**2,
        network_seconds=0.01, network_exponent=2.0, network_exponent_error=float("nan"),
        network_prefactor=0.1, fit_r_min=2.0, fit_r_max=2.4, **extra,
    )  # fmt: skip


def test_a_result_is_stored_and_read_back_field_for_field(tmp_path):
    """Through the unit store (npz + JSON record): arrays, plain values, NaN and the
    ``fields`` mapping come back equal; fields left at None are not stored and read back
    as None."""
    fields = {"net/x": np.ones((4, 2)), "cont/strain": np.zeros((2, 2, 2))}
    result = _network_only(fields=fields)
    unit = Unit("transmission/n8", lambda *a: None, {"n": 8})
    _save_unit(tmp_path, unit, result, 0.5)
    back = from_stored(_read_unit(tmp_path, unit.key), TransmissionResult)
    for name in ("springs", "distance", "network_strain"):
        np.testing.assert_array_equal(getattr(back, name), getattr(result, name))
    assert back.n == 8 and back.source == 84 and np.isnan(back.network_exponent_error)
    assert back.continuum_strain is None and back.exponent("continuum") is None
    assert sorted(back.fields) == sorted(fields)
    np.testing.assert_array_equal(back.fields["net/x"], fields["net/x"])
    arrays, meta = to_stored(result)
    assert "continuum_exponent" not in meta and "net/x" in arrays and "fields" not in meta


def test_a_stored_unit_without_a_required_field_is_refused_by_name():
    arrays, meta = to_stored(_network_only())
    del meta["source"]
    with pytest.raises(KeyError, match="unit 'transmission/n8' stores no 'source'"):
        from_stored(UnitResult("transmission/n8", arrays, meta, 0.0), TransmissionResult)


def test_a_none_marked_keep_none_is_stored_as_null_and_read_back(tmp_path):
    """``first_below`` (never below: None) is stored as null, as the untyped unit wrote it,
    beside a trace that shares its record value's stored name."""
    from continuum_vs_network.scenes.results import read_result
    from continuum_vs_network.scenes.results.mechanism import CLASSES, LatticeResult

    result = LatticeResult(
        refine=0, ratio=0.5, first_below=None, source_share=0.9, coupling="coupled",
        outcome="not met", n_nodes=3, n_springs=3, spacing=0.125, completed=2, seconds=0.2,
        solves=8.0, error=np.array([1.0, 0.7, 0.5]), seconds_trace=np.array([0.0, 0.1, 0.2]),
        solves_trace=np.array([0.0, 4.0, 8.0]), positions=np.zeros((3, 2)),
        springs=np.array([[0, 1], [1, 2], [0, 2]]), k=np.ones(3),
    )  # fmt: skip
    arrays, meta = to_stored(result)
    assert meta["first_below"] is None and meta["seconds"] == 0.2
    assert list(arrays) == ["error", "seconds", "solves", "positions", "springs", "k"]
    unit = Unit("continuum_mechanism/lattice/refine0", lambda *a: None, {"refine": 0})
    _save_unit(tmp_path, unit, result, 0.5)
    back = read_result(_read_unit(tmp_path, unit.key), CLASSES)
    assert isinstance(back, LatticeResult) and back.first_below is None
    np.testing.assert_array_equal(back.seconds_trace, result.seconds_trace)
