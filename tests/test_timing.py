"""Timed units run with one BLAS thread, whatever the process has."""

from __future__ import annotations

from threadpoolctl import threadpool_info

from continuum_vs_network.scenes.timing import single_threaded
from continuum_vs_network.scenes.units_solvers import solver_unit


def test_single_threaded_limits_every_pool_inside_and_restores_it():
    import numpy  # noqa: F401  (loads the BLAS pool)

    before = [p["num_threads"] for p in threadpool_info()]

    @single_threaded
    def inside():
        return [p["num_threads"] for p in threadpool_info()]

    assert set(inside()) == {1}
    assert [p["num_threads"] for p in threadpool_info()] == before


def test_timed_units_keep_their_names_for_fingerprints():
    assert solver_unit.__name__ == "solver_unit"
    assert solver_unit.__module__ == "continuum_vs_network.scenes.units_solvers"
