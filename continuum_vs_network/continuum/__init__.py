"""Finite-element continuum (scikit-fem): elastic and visco-elastic bodies to compare with networks.

Every submodule imports scikit-fem inside its functions, so importing this package (and
the names below) needs only numpy and scipy; scikit-fem loads on the first mesh or body.

- :mod:`.mesh`: rectangle, disk, annulus and network-outline meshes, mesh quality;
- :mod:`.materials`: Lamé parameters and the network-to-continuum mappings;
- :mod:`.body`: the elastic body (mesh + P1/P2 basis + Lamé parameters), its matrices and loads;
- :mod:`.static`: Dirichlet conditions and static solves with one sparse factorisation;
- :mod:`.probes`: sparse displacement and strain probes;
- :mod:`.transmission`: source patches, the Eshelby inclusion, strain against distance;
- :mod:`.damping`: damping coefficients and matrices, the lattice mapping (:class:`Damping`);
- :mod:`.viscoelastic`: mass and implicit time stepping, relaxation times;
- :mod:`.maxwell`: the Maxwell arm of a standard linear solid (internal strains).
- :mod:`.learnable`: a learning medium, element-wise eigenstrain and modulus fields
  (:func:`learnable_body`), trained by the same rules and ``train`` as networks;
- :mod:`.material_task`: material springs as sources and targets (:class:`MaterialTask`);
- :mod:`.learning_states`: free, clamped and adjoint states from one factorisation;
- :mod:`.learned_fields`: learned fields compared with a network's on its triangles.
"""

from __future__ import annotations

from .body import (
    ElasticBody,
    LockingWarning,
    body_force_load,
    dofs_where,
    eigenstrain_load,
    elastic_body,
    mass_matrix,
    near_segments,
    pressure_load,
    stiffness_matrix,
    strain_energy,
    vertex_displacement,
)
from .inclusion import InclusionField, InclusionSolution, eshelby_inclusion, solve_inclusion
from .learnable import LearnableBody, learnable_body
from .learned_fields import (
    coarse_average,
    field_direction,
    field_magnitude,
    localisation,
    network_rest_strain,
)
from .learning_states import MaterialState, effective_stiffness
from .material_task import MaterialTask
from .materials import (
    Material,
    NetworkModuli,
    lattice_area_per_node,
    lattice_lame,
    lattice_maxwell_arm,
    lattice_viscous_lame,
    network_moduli,
    node_drag_to_continuum,
    plane_stress_lambda,
    voigt_isotropic,
)
from .mesh import (
    MeshQuality,
    annulus_mesh,
    disk_mesh,
    mesh_quality,
    network_faces,
    network_mesh,
    rectangle_mesh,
)
from .probes import (
    Probe,
    chord_strain_probe,
    directional_strain_probe,
    displacement_probe,
    locate,
    region_strain_probe,
    strain_probe,
)
from .static import Dirichlet, Factorisation, StaticSolution, factorise, fix, solve_static
from .transmission import (
    DecayFit,
    StrainProfile,
    Transmission,
    continuum_transmission,
    decay_exponent,
    network_dirichlet,
    network_patch_source,
    network_transmission,
    patch_source,
    strain_profile,
)
from .viscoelastic import (
    ContinuumTrajectory,
    Damping,
    damping_matrix,
    explicit_limit,
    lattice_damping,
    linear_system,
    relaxation_time,
    simulate_body,
    slowest_relaxation_time,
)

__all__ = [
    "ContinuumTrajectory",
    "Damping",
    "DecayFit",
    "Dirichlet",
    "ElasticBody",
    "Factorisation",
    "InclusionField",
    "InclusionSolution",
    "LearnableBody",
    "LockingWarning",
    "Material",
    "MaterialState",
    "MaterialTask",
    "MeshQuality",
    "NetworkModuli",
    "Probe",
    "StaticSolution",
    "StrainProfile",
    "Transmission",
    "annulus_mesh",
    "body_force_load",
    "chord_strain_probe",
    "coarse_average",
    "continuum_transmission",
    "damping_matrix",
    "decay_exponent",
    "directional_strain_probe",
    "disk_mesh",
    "displacement_probe",
    "dofs_where",
    "effective_stiffness",
    "eigenstrain_load",
    "elastic_body",
    "eshelby_inclusion",
    "explicit_limit",
    "factorise",
    "field_direction",
    "field_magnitude",
    "fix",
    "lattice_area_per_node",
    "lattice_damping",
    "lattice_lame",
    "lattice_maxwell_arm",
    "lattice_viscous_lame",
    "learnable_body",
    "linear_system",
    "localisation",
    "locate",
    "mass_matrix",
    "mesh_quality",
    "near_segments",
    "network_dirichlet",
    "network_faces",
    "network_mesh",
    "network_moduli",
    "network_patch_source",
    "network_rest_strain",
    "network_transmission",
    "node_drag_to_continuum",
    "patch_source",
    "plane_stress_lambda",
    "pressure_load",
    "rectangle_mesh",
    "region_strain_probe",
    "relaxation_time",
    "simulate_body",
    "slowest_relaxation_time",
    "solve_inclusion",
    "solve_static",
    "stiffness_matrix",
    "strain_energy",
    "strain_probe",
    "strain_profile",
    "vertex_displacement",
    "voigt_isotropic",
]
