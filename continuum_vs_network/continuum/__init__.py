"""Finite-element continuum (scikit-fem): elastic and visco-elastic bodies to compare with networks.

The submodules import scikit-fem inside their functions, and this package imports no
submodule: ``import continuum_vs_network.continuum`` needs only numpy and scipy. Import what
you use from the submodules:

- :mod:`.mesh`: rectangle, disk, annulus and network-outline meshes, mesh quality;
- :mod:`.materials`: Lamé parameters and the network-to-continuum mappings;
- :mod:`.body`: the elastic body (mesh + P1/P2 basis + Lamé parameters), its matrices and loads;
- :mod:`.static`: Dirichlet conditions and static solves with one sparse factorisation;
- :mod:`.probes`: sparse displacement and strain probes;
- :mod:`.transmission`: source patches, the Eshelby inclusion, strain against distance;
- :mod:`.viscoelastic`: mass, damping and implicit time stepping, relaxation times.
"""

from __future__ import annotations

__all__: list[str] = []
