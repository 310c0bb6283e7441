"""Results of the stability units."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["EquilibriumCaseResult", "LockingResult", "StepResult", "StiffLearningResult"]


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
