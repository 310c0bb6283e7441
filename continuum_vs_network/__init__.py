"""continuum_vs_network: mass-spring networks that learn, against an elastic continuum.

``import continuum_vs_network as cvn`` needs only numpy and scipy; torch, scikit-fem,
meshio, pyvista and matplotlib are imported inside the functions that use them.
"""

from __future__ import annotations

from .network import (
    Equilibrium,
    EquilibriumError,
    SpringNetwork,
    default_pins,
    energy,
    forces,
    gradient,
    hessian,
    relax,
)

__version__ = "0.1.0"

__all__ = [
    "Equilibrium",
    "EquilibriumError",
    "SpringNetwork",
    "__version__",
    "default_pins",
    "energy",
    "forces",
    "gradient",
    "hessian",
    "relax",
]
