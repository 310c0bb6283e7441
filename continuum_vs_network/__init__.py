"""continuum_vs_network: mass-spring networks that learn, against an elastic continuum.

``import continuum_vs_network as cvn`` needs only numpy and scipy; torch, scikit-fem,
meshio, pyvista and matplotlib are imported inside the functions that use them.
"""

from __future__ import annotations

from .learning import (
    AllosteryTask,
    CoupledLearning,
    ExactGradient,
    History,
    LearningError,
    ProspectiveConfiguration,
    paper_task,
    stern_task,
    train,
)
from .network import (
    Equilibrium,
    EquilibriumError,
    SpringNetwork,
    Trajectory,
    default_pins,
    diluted_lattice,
    energy,
    forces,
    gradient,
    hessian,
    is_rigid,
    jammed_network,
    paper_network,
    relax,
    relaxation_time,
    rigidity_matrix,
    simulate,
    strain_tunable,
    triangular_lattice,
    zero_modes,
)
from .scenes import SceneError, load_scene, run_scene

__version__ = "0.1.0"

__all__ = [
    "AllosteryTask",
    "CoupledLearning",
    "Equilibrium",
    "EquilibriumError",
    "ExactGradient",
    "History",
    "LearningError",
    "ProspectiveConfiguration",
    "SceneError",
    "SpringNetwork",
    "Trajectory",
    "__version__",
    "default_pins",
    "diluted_lattice",
    "energy",
    "forces",
    "gradient",
    "hessian",
    "is_rigid",
    "jammed_network",
    "load_scene",
    "paper_network",
    "paper_task",
    "relax",
    "relaxation_time",
    "rigidity_matrix",
    "run_scene",
    "simulate",
    "stern_task",
    "strain_tunable",
    "train",
    "triangular_lattice",
    "zero_modes",
]
