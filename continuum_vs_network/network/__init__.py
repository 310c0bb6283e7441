"""Mass-spring networks: model, builders, energy, constraints, equilibrium and dynamics."""

from .builders import diluted_lattice, paper_network, strain_tunable, triangular_lattice
from .constraints import Problem, default_pins, pin_mask
from .dynamics import (
    Trajectory,
    relaxation_time,
    simulate,
    simulate_viscous,
    stability_limit,
)
from .energy import HessianPattern, energy, forces, gradient, hessian
from .equilibrium import Equilibrium, EquilibriumError, relax
from .jammed import jammed_network
from .model import SpringNetwork
from .rigidity import is_rigid, rigidity_matrix, self_stress_support, self_stresses, zero_modes
from .viscous import Viscosity

__all__ = [
    "Equilibrium",
    "EquilibriumError",
    "HessianPattern",
    "Problem",
    "SpringNetwork",
    "Trajectory",
    "Viscosity",
    "default_pins",
    "diluted_lattice",
    "energy",
    "forces",
    "gradient",
    "hessian",
    "is_rigid",
    "jammed_network",
    "paper_network",
    "pin_mask",
    "relax",
    "relaxation_time",
    "rigidity_matrix",
    "self_stress_support",
    "self_stresses",
    "simulate",
    "simulate_viscous",
    "stability_limit",
    "strain_tunable",
    "triangular_lattice",
    "zero_modes",
]
