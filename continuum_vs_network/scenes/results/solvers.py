"""Results of the solvers units."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["SolverResult"]


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
