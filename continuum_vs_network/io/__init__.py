"""Export for inspection: meshio files (VTU, PVD series) and pyvista off-screen images.

This package imports nothing heavy: meshio and pyvista are imported inside the functions that
use them. Import the submodules directly::

    from continuum_vs_network.io.export import network_mesh, write_mesh, write_series
    from continuum_vs_network.io.render import render_network, rendering_available
"""

from __future__ import annotations

__all__: list[str] = []
