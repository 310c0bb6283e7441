"""Typed unit results: a unit returns a frozen dataclass, a report section reads it back.

One codec for every result class. A result is a frozen dataclass whose fields hold plain
values (numbers, strings, lists: the unit's JSON record), arrays (annotated ``np.ndarray``:
the unit's ``.npz`` payload) or, in one field named ``fields``, a mapping of further
arrays whose names carry a ``/`` (``"net/x"``, ``"cont/strain"``: what mesh export reads).
Each is stored under the field's name, or under ``field(metadata={"stored": name})``
(an array and a record value may share a stored name). A field with a default may be
absent from a stored unit (a continuum part a scene leaves out). The stored layout is the
one untyped units write, so results computed before a kind was typed read back as its
class.

    arrays, meta = to_stored(TransmissionResult(...))   # what the store writes
    result = from_stored(unit, TransmissionResult)      # what a section reads
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from .units import UnitResult

__all__ = [
    "EquilibriumCaseResult",
    "FiniteElementResult",
    "IntegratorResult",
    "LockingResult",
    "RelaxationResult",
    "SolverResult",
    "StepResult",
    "StiffLearningResult",
    "TransmissionResult",
    "from_stored",
    "is_result",
    "to_stored",
]

T = TypeVar("T")


def is_result(output: Any) -> bool:
    """True for an instance of a result dataclass (not a class, not a History)."""
    return dataclasses.is_dataclass(output) and not isinstance(output, type)


def _stored(f: dataclasses.Field) -> tuple[str, bool]:
    """A field's stored name and whether it is an array (in the payload, not the record)."""
    kind = str(f.type)
    return f.metadata.get("stored", f.name), "ndarray" in kind and "Mapping" not in kind


def to_stored(result: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, meta)`` of a result dataclass: array fields and the ``fields`` mapping
    to ``arrays``, every other field to ``meta``; fields left at None are not stored."""
    arrays: dict[str, np.ndarray] = {}
    meta: dict[str, Any] = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        name, is_array = _stored(f)
        if value is None:
            continue
        if f.name == "fields":
            arrays.update(value)
        elif is_array:
            arrays[name] = np.asarray(value)
        else:
            meta[name] = value
    return arrays, meta


def from_stored(unit: UnitResult, cls: type[T]) -> T:
    """``unit``'s arrays and record read as ``cls`` (a result dataclass).

    Raises KeyError naming the unit and the field when a field without a default is not
    stored (a result of another kind, or of an older layout).
    """
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        name, is_array = _stored(f)
        stored = unit.arrays if is_array else unit.meta
        if f.name == "fields":
            values["fields"] = {k: v for k, v in unit.arrays.items() if "/" in k}
        elif name in stored:
            values[f.name] = stored[name]
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise KeyError(f"unit {unit.key!r} stores no {name!r} for {cls.__name__}")
    return cls(**values)


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


@dataclass(frozen=True)
class SolverResult:
    """One equilibrium method at one lattice size (a ``solvers`` unit).

    ``residual``: the relative residual (each net force over its node's sum k L) reached;
    ``seconds``: the whole solve's wall-clock time; ``error``: the method's reason where
    it did not converge (empty otherwise). The traces (R,) record the relative residual,
    the wall-clock seconds and the method's own iteration number at its records (stored
    as ``residual``, ``seconds`` and ``iteration``).
    """

    n: int
    method: str
    n_nodes: int
    n_springs: int
    converged: bool
    residual: float
    iterations: int
    seconds: float
    error: str
    residual_trace: np.ndarray = field(metadata={"stored": "residual"})
    seconds_trace: np.ndarray = field(metadata={"stored": "seconds"})
    iteration_trace: np.ndarray = field(metadata={"stored": "iteration"})


@dataclass(frozen=True)
class FiniteElementResult:
    """One element type at one mesh size on Lamé's cylinder (an ``accuracy/fe`` unit):
    the relative L2 displacement error, the DOFs, the whole solve's seconds and whether
    the locking warning was raised."""

    element: str
    h: float
    error: float
    dofs: int
    seconds: float
    warned: bool


@dataclass(frozen=True)
class IntegratorResult:
    """One time integrator at one step count (an ``accuracy/network`` or
    ``accuracy/continuum`` unit): the error against the reference (NaN where refused),
    its wall-clock seconds, the step ``dt`` in model time; for the network also the
    explicit stability limit ``dt_limit``, the run's ``t_end`` and why a step was refused
    (empty: not refused; None for the continuum, which refuses none)."""

    problem: str
    scheme: str
    steps: int
    dt: float
    error: float
    seconds: float
    dt_limit: float | None = None
    t_end: float | None = None
    refused: str | None = None


@dataclass(frozen=True)
class EquilibriumCaseResult:
    """One equilibrium method on one stability case (a ``stability/<case>`` unit).

    ``error``: what was raised, as ``"Type: message"`` (empty: nothing); ``imbalance``: the
    local imbalance measured independently of the solver at the returned positions (NaN
    where none were returned); ``clamp_error``: the clamped spring's length error over its
    rest length; ``check``: a case's own check (``check_name`` says which; NaN and empty
    where it has none).
    """

    case: str
    value: float
    method: str
    n_nodes: int
    error: str = ""
    converged: bool = False
    imbalance: float = math.nan
    clamp_error: float = math.nan
    seconds: float = math.nan
    iterations: int = 0
    check: float = math.nan
    check_name: str = ""


@dataclass(frozen=True)
class StepResult:
    """A dynamics scheme at ``f`` times the explicit stability limit ``dt_limit`` (a
    ``stability/dynamics`` unit): mechanical energy at the start and end, the final local
    imbalance and seconds (NaN where the run raised; ``error`` says what)."""

    scheme: str
    f: float
    dt: float
    dt_limit: float
    steps: int
    error: str = ""
    energy_start: float = math.nan
    energy_end: float = math.nan
    imbalance: float = math.nan
    seconds: float = math.nan


@dataclass(frozen=True)
class LockingResult:
    """Lamé's cylinder at one Poisson's ratio (a ``stability/locking`` unit): the relative
    L2 error, DOFs, seconds and whether the locking warning was raised."""

    element: str
    poisson: float
    error: float
    dofs: int
    seconds: float
    warned: bool


@dataclass(frozen=True)
class StiffLearningResult:
    """Coupled learning on a lattice with stiff springs of stiffness ``ratio`` (a
    ``stability/learning`` unit): steps asked and completed, the stop reason or what was
    raised (``error``), C/C0 at the last completed step and whether every error was
    finite."""

    ratio: float
    steps: int
    error: str
    completed: int
    ratio_error: float
    seconds: float
    finite: bool
