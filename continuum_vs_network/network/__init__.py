"""Mass-spring networks: model, builders, energy, constraints, equilibrium and dynamics."""

from .constraints import Problem, default_pins, pin_mask
from .energy import HessianPattern, energy, forces, gradient, hessian
from .equilibrium import Equilibrium, EquilibriumError, relax
from .model import SpringNetwork

__all__ = [
    "Equilibrium",
    "EquilibriumError",
    "HessianPattern",
    "Problem",
    "SpringNetwork",
    "default_pins",
    "energy",
    "forces",
    "gradient",
    "hessian",
    "pin_mask",
    "relax",
]
