"""Results of the transmission and relaxation units (lattice and continuum)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["RelaxationResult", "TransmissionResult"]


@dataclass(frozen=True)
class TransmissionResult:
    """Strain against distance from a clamped source spring (a ``transmission`` unit).

    Arrays (n_springs,): ``springs`` (the springs read, in distance order), ``distance``
    (from the source, lattice spacings), ``network_strain`` and, with a continuum,
    ``continuum_strain`` (chord strain of the same springs). Decay fits ``|strain| ~
    prefactor * distance**exponent`` between ``fit_r_min`` and ``fit_r_max`` (NaN where
    the lattice is too small), each with its standard error; ``correlation``: of the two
    media's strains. ``fields``: the relaxed network and continuum for mesh export (empty
    unless the scene asks for fields). Seconds are wall-clock.
    """

    n: int
    n_nodes: int
    n_springs: int
    source: int
    strain: float
    springs: np.ndarray
    distance: np.ndarray
    network_strain: np.ndarray
    network_seconds: float
    network_exponent: float
    network_exponent_error: float
    network_prefactor: float
    fit_r_min: float
    fit_r_max: float
    continuum_strain: np.ndarray | None = None
    continuum_seconds: float | None = None
    continuum_exponent: float | None = None
    continuum_exponent_error: float | None = None
    continuum_prefactor: float | None = None
    correlation: float | None = None
    fields: Mapping[str, np.ndarray] = field(default_factory=dict)

    def exponent(self, medium: str) -> tuple[float, float] | None:
        """``(exponent, standard error)`` of ``medium`` ("network" or "continuum"); None
        when that medium was not run."""
        value = getattr(self, f"{medium}_exponent")
        return None if value is None else (value, getattr(self, f"{medium}_exponent_error"))


@dataclass(frozen=True)
class RelaxationResult:
    """Relaxation after one side of a lattice is stepped (a ``relaxation`` unit).

    ``network_times`` (T,) and ``network_deviation`` (T,): the largest displacement to the
    final state over time; ``network_tau``: when it stays below the scene's fraction of its
    start; ``network_tau_mode``: 1 / the smallest decay rate of the linearised equations;
    ``dt`` and ``t_end`` in the same time unit. The ``continuum_*`` values (with a
    continuum) are the same for the finite-element body with the drag smeared over the
    area per node. ``fields``: the network (and continuum) for mesh export.
    """

    n: int
    n_nodes: int
    dt: float
    t_end: float
    network_times: np.ndarray
    network_deviation: np.ndarray
    network_tau_mode: float
    network_tau: float
    network_seconds: float
    network_factorisations: int
    continuum_times: np.ndarray | None = None
    continuum_deviation: np.ndarray | None = None
    continuum_tau_mode: float | None = None
    continuum_tau: float | None = None
    continuum_seconds: float | None = None
    continuum_dofs: int | None = None
    fields: Mapping[str, np.ndarray] = field(default_factory=dict)
