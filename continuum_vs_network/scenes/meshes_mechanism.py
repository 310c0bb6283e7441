"""VTU of a ``continuum_mechanism`` unit: its modulus field (and SIMP density) as cell data."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["mechanism_field_mesh"]


def mechanism_field_mesh(key: str, a: dict, folder: Path) -> Path:
    """``mechanism_<unit>.vtu``: cell data ``modulus``, ``log10_modulus`` (learned, optimal
    or SIMP modulus; the inverter's density there) and ``density`` where the unit has one,
    on the undeformed mesh."""
    from ..io.export import continuum_mesh, write_mesh

    points = np.asarray(a["points"], dtype=float)
    s = np.asarray(a["field"], dtype=float)
    fields = {"modulus": s, "log10_modulus": np.log10(np.maximum(s, 1e-300))}
    if "density" in a:
        fields["density"] = np.asarray(a["density"], dtype=float)
    if "frozen" in a:
        fields["frozen"] = np.asarray(a["frozen"], dtype=bool)
    mesh = continuum_mesh(points, a["triangles"], np.zeros_like(points), cell_fields=fields)
    name = key.removeprefix("continuum_mechanism/").replace("/", "_")
    return write_mesh(mesh, Path(folder) / f"mechanism_{name}.vtu")
