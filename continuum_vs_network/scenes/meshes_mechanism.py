"""VTU of a ``continuum_mechanism`` unit: its modulus field (and SIMP density) as cell data."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .units import UnitResult

__all__ = ["mechanism_field_mesh"]


def mechanism_field_mesh(unit: UnitResult, folder: Path) -> Path | None:
    """``mechanism_<unit>.vtu``: cell data ``modulus``, ``log10_modulus`` (learned, optimal
    or SIMP modulus; the inverter's density there) and ``density`` or ``frozen`` where the
    unit has them, on the undeformed mesh; None for a unit without a field on a mesh (dof
    runs, their optima, the lattice)."""
    from ..io.export import continuum_mesh, write_mesh
    from .results import read_result
    from .results.mechanism import CLASSES

    r = read_result(unit, CLASSES)
    if not hasattr(r, "triangles"):
        return None
    points = np.asarray(r.points, dtype=float)
    s = np.asarray(r.field, dtype=float)
    fields = {"modulus": s, "log10_modulus": np.log10(np.maximum(s, 1e-300))}
    if getattr(r, "density", None) is not None:
        fields["density"] = np.asarray(r.density, dtype=float)
    if getattr(r, "frozen", None) is not None:
        fields["frozen"] = np.asarray(r.frozen, dtype=bool)
    mesh = continuum_mesh(points, r.triangles, np.zeros_like(points), cell_fields=fields)
    name = unit.key.removeprefix("continuum_mechanism/").replace("/", "_")
    return write_mesh(mesh, Path(folder) / f"mechanism_{name}.vtu")
