"""Mesh export for inspection in ParaView: networks and continua as VTU, time series as PVD.

Networks become VTK line cells (one per spring) and continua linear triangles. Points are the
*reference* positions padded to 3D; the deformation travels as the point array
``displacement`` (3 components), so ParaView's *Warp By Vector* shows the deformed body. Cell
arrays are evaluated in the deformed state.

Files are written atomically (temporary file in the target folder, then rename): a failing
write never leaves a half-written file. A time series is one VTU per frame plus a ``.pvd``
index written last, so a series that fails half-way has no index pointing at missing frames.
meshio's XDMF writer is deliberately not used (meshio 5.3.5 puts its ``.h5`` file in the
current directory, meshio issue #1442).

meshio is imported inside the functions that need it.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_vs_network.io.atomic import atomic_path, write_text_atomic

if TYPE_CHECKING:
    import meshio

    from continuum_vs_network.network.model import SpringNetwork

__all__ = [
    "FORMATS",
    "NETWORK_CELL_FIELDS",
    "ROLE_HIDDEN",
    "ROLE_SOURCE",
    "ROLE_TARGET",
    "body_history_series",
    "continuum_mesh",
    "default_mesh_dir",
    "network_mesh",
    "read_series_index",
    "spring_roles",
    "time_history_series",
    "write_mesh",
    "write_series",
]

#: File suffixes :func:`write_mesh` accepts and the meshio format each one is written in.
FORMATS: dict[str, str] = {".vtu": "vtu", ".vtk": "vtk"}

#: Cell arrays every network mesh carries (units: strain 1, stiffness force/length,
#: lengths length, force force; force = k (r - L) is the tension, positive when stretched).
NETWORK_CELL_FIELDS = ("strain", "stiffness", "rest_length", "length", "force")

ROLE_HIDDEN, ROLE_SOURCE, ROLE_TARGET = 0, 1, 2

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]*$")


# -- helpers -------------------------------------------------------------------------------
def _pad3(arr: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 2) -> (n, 3) with a zero third column; (n, 3) unchanged."""
    if arr.shape[1] == 3:
        return np.ascontiguousarray(arr, dtype=np.float64)
    out = np.zeros((arr.shape[0], 3), dtype=np.float64)
    out[:, :2] = arr
    return out


def _float_array(name: str, value: ArrayLike, shape: tuple[int | None, ...]) -> NDArray:
    arr = np.asarray(value, dtype=np.float64)
    ok = arr.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, arr.shape))
    if not ok:
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} must be finite; entry {tuple(bad.tolist())} is {arr[tuple(bad)]}")
    return arr


def _tensor9(name: str, value: ArrayLike, n: int) -> NDArray[np.float64]:
    """(n, 2, 2) or (n, 3, 3) tensors -> (n, 9) rows ``xx xy xz yx yy yz zx zy zz``.

    2x2 tensors are padded with zeros (in-plane components only). Nine components is the
    layout ParaView recognises as a (full) tensor.
    """
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[0] != n or arr.shape[1:] not in ((2, 2), (3, 3)):
        raise ValueError(f"{name} must have shape ({n}, 2, 2) or ({n}, 3, 3), got {arr.shape}")
    arr = _float_array(name, arr, arr.shape)
    out = np.zeros((n, 3, 3), dtype=np.float64)
    out[:, : arr.shape[1], : arr.shape[2]] = arr
    return out.reshape(n, 9)


def _extra_fields(
    kind: str, fields: Mapping[str, ArrayLike] | None, n: int, reserved: Iterable[str]
) -> dict[str, NDArray]:
    """Validate user arrays: one row per point/cell, 1 or 2 dims; 2 columns padded to 3."""
    out: dict[str, NDArray] = {}
    if fields is None:
        return out
    if not isinstance(fields, Mapping):
        raise ValueError(f"{kind} must be a mapping of name -> array, got {type(fields).__name__}")
    reserved = set(reserved)
    for name, value in fields.items():
        if not isinstance(name, str) or not name:
            raise ValueError(f"{kind}: field names must be non-empty strings, got {name!r}")
        if name in reserved:
            raise ValueError(f"{kind}[{name!r}] clashes with a built-in array of the same name")
        arr = np.asarray(value)
        if arr.dtype.kind not in "biuf":
            raise ValueError(f"{kind}[{name!r}] must be numeric, got dtype {arr.dtype}")
        if arr.ndim not in (1, 2) or arr.shape[0] != n:
            raise ValueError(
                f"{kind}[{name!r}] must have shape ({n},) or ({n}, c), got {arr.shape}"
            )
        if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
            raise ValueError(f"{kind}[{name!r}] must be finite")
        if arr.dtype.kind == "b":
            arr = arr.astype(np.int8)
        if arr.ndim == 2 and arr.shape[1] == 2:
            arr = _pad3(arr.astype(np.float64))
        out[name] = np.ascontiguousarray(arr)
    return out


def _check_name(kind: str, value: str) -> str:
    if not isinstance(value, str) or not _NAME.match(value):
        raise ValueError(
            f"{kind} must be a plain name (letters, digits, '_', '-', '.'; no folders), "
            f"got {value!r}"
        )
    return value


# -- building meshes -----------------------------------------------------------------------
def spring_roles(
    n_springs: int, *, sources: ArrayLike = (), targets: ArrayLike = ()
) -> NDArray[np.int32]:
    """Per-spring role code: 0 hidden, 1 source, 2 target.

    Parameters
    ----------
    n_springs : int
        Number of springs.
    sources, targets : sequence of int
        Spring indices; a spring may not be both.

    Returns
    -------
    (n_springs,) int32 array, for ``network_mesh(..., fields={"role": roles})``.
    """
    roles = np.full(int(n_springs), ROLE_HIDDEN, dtype=np.int32)
    for name, idx, code in (("sources", sources, ROLE_SOURCE), ("targets", targets, ROLE_TARGET)):
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        if np.any((idx < 0) | (idx >= n_springs)):
            raise ValueError(f"{name} holds a spring index outside 0..{n_springs - 1}: {idx}")
        roles[idx] = code
    both = np.intersect1d(np.asarray(sources, dtype=np.int64), np.asarray(targets, dtype=np.int64))
    if both.size:
        raise ValueError(f"springs {both.tolist()} are both sources and targets")
    return roles


def network_mesh(
    net: SpringNetwork,
    x: ArrayLike | None = None,
    *,
    fields: Mapping[str, ArrayLike] | None = None,
    point_fields: Mapping[str, ArrayLike] | None = None,
) -> meshio.Mesh:
    """A spring network as a meshio mesh of VTK line cells.

    Parameters
    ----------
    net : SpringNetwork
        The network; its ``positions`` are the reference configuration (the mesh points).
    x : (n_nodes, 2) float array, optional
        Deformed positions (default: ``net.positions``, zero displacement).
    fields : mapping of str to (n_springs,) or (n_springs, c) array, optional
        Extra cell arrays, e.g. ``{"role": spring_roles(...)}``. Two-column arrays are padded
        to three columns (vectors in ParaView).
    point_fields : mapping of str to (n_nodes,) or (n_nodes, c) array, optional
        Extra point arrays, same rules.

    Returns
    -------
    meshio.Mesh
        Points ``(n_nodes, 3)`` (reference positions, z = 0); one ``"line"`` cell block
        ``(n_springs, 2)``; cell data ``strain`` (``r/L - 1``), ``stiffness``,
        ``rest_length``, ``length`` (``r`` at ``x``), ``force`` (tension ``k (r - L)``);
        point data ``displacement`` ``(n_nodes, 3)`` = ``x - net.positions``, z = 0.
    """
    import meshio

    x = net.positions if x is None else _float_array("x", x, (net.n_nodes, 2))
    lengths = net.lengths(x)
    cell_data = {
        "strain": lengths / net.rest_length - 1.0,
        "stiffness": np.array(net.stiffness),
        "rest_length": np.array(net.rest_length),
        "length": lengths,
        "force": net.stiffness * (lengths - net.rest_length),
    }
    cell_data.update(_extra_fields("fields", fields, net.n_springs, cell_data))
    point_data = {"displacement": _pad3(x - net.positions)}
    point_data.update(_extra_fields("point_fields", point_fields, net.n_nodes, point_data))
    return meshio.Mesh(
        _pad3(np.array(net.positions)),
        [("line", np.array(net.springs, dtype=np.int64))],
        point_data=point_data,
        cell_data={name: [arr] for name, arr in cell_data.items()},
    )


def continuum_mesh(
    points: ArrayLike,
    triangles: ArrayLike,
    displacement: ArrayLike,
    strain: ArrayLike | None = None,
    stress: ArrayLike | None = None,
    *,
    cell_fields: Mapping[str, ArrayLike] | None = None,
    point_fields: Mapping[str, ArrayLike] | None = None,
) -> meshio.Mesh:
    """A 2D continuum as a meshio mesh of linear triangles.

    Parameters
    ----------
    points : (n_points, 2) float array
        Reference vertex positions (length units).
    triangles : (n_triangles, 3) int array
        Vertex indices of each triangle.
    displacement : (n_points, 2) float array
        Displacement at the vertices (length units).
    strain, stress : (n_triangles, 2, 2) or (n_triangles, 3, 3) float array, optional
        Per-triangle strain (1) and stress (force/length^2 in 2D) tensors. Written as
        9-component cell arrays ``xx xy xz yx yy yz zx zy zz``; 2x2 input leaves the
        out-of-plane entries 0 (pass 3x3 to export e.g. the plane-strain ``sigma_zz``).
    cell_fields, point_fields : mapping of str to array, optional
        Extra arrays with one row per triangle or per point (two columns padded to three).

    Returns
    -------
    meshio.Mesh
        Points ``(n_points, 3)``, one ``"triangle"`` block, point data ``displacement``
        ``(n_points, 3)``, cell data ``strain``/``stress`` ``(n_triangles, 9)`` when given.
    """
    import meshio

    pts = _float_array("points", points, (None, 2))
    tri_raw = np.asarray(triangles)
    if tri_raw.ndim != 2 or tri_raw.shape[1] != 3:
        raise ValueError(f"triangles must have shape (n, 3), got {tri_raw.shape}")
    if tri_raw.size and not np.issubdtype(tri_raw.dtype, np.integer):
        raise ValueError(f"triangles must hold integer vertex indices, got dtype {tri_raw.dtype}")
    tri = tri_raw.astype(np.int64)
    n_pts, n_tri = pts.shape[0], tri.shape[0]
    if tri.size and (tri.min() < 0 or tri.max() >= n_pts):
        raise ValueError(f"triangles hold a vertex index outside 0..{n_pts - 1}")
    disp = _float_array("displacement", displacement, (n_pts, 2))
    cell_data: dict[str, NDArray] = {}
    if strain is not None:
        cell_data["strain"] = _tensor9("strain", strain, n_tri)
    if stress is not None:
        cell_data["stress"] = _tensor9("stress", stress, n_tri)
    cell_data.update(_extra_fields("cell_fields", cell_fields, n_tri, ("strain", "stress")))
    point_data = {"displacement": _pad3(disp)}
    point_data.update(_extra_fields("point_fields", point_fields, n_pts, point_data))
    return meshio.Mesh(
        _pad3(pts),
        [("triangle", tri)],
        point_data=point_data,
        cell_data={name: [arr] for name, arr in cell_data.items()},
    )


# -- writing -------------------------------------------------------------------------------
def default_mesh_dir(scene: str, root: str | os.PathLike[str] = ".") -> Path:
    """Default destination of a scene's meshes: ``<root>/meshes/<scene>/`` (not created)."""
    return Path(root) / "meshes" / _check_name("scene", scene)


def _mesh_path(path: str | os.PathLike[str]) -> tuple[Path, str]:
    dest = Path(path)
    if dest.suffix == "":
        dest = dest.with_name(dest.name + ".vtu")
    fmt = FORMATS.get(dest.suffix.lower())
    if fmt is None:
        raise ValueError(
            f"path {str(path)!r}: unsupported suffix {dest.suffix!r}; "
            f"use one of {', '.join(FORMATS)} (no suffix means .vtu)"
        )
    return dest, fmt


def write_mesh(mesh: meshio.Mesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` to ``path`` atomically and return the path written.

    Parameters
    ----------
    mesh : meshio.Mesh
        For example from :func:`network_mesh` or :func:`continuum_mesh`.
    path : str or os.PathLike
        Destination; ``.vtu`` (binary, zlib-compressed XML; the default when the name has no
        suffix) or ``.vtk`` (legacy). Other suffixes raise ``ValueError``. Parent folders
        are created.

    A failure while writing leaves no file at ``path`` (or the previous file untouched).
    """
    import meshio

    dest, fmt = _mesh_path(path)
    with atomic_path(dest) as tmp:
        meshio.write(tmp, mesh, file_format=fmt)
    return dest


def write_series(
    meshes: Iterable[meshio.Mesh],
    times: ArrayLike,
    folder: str | os.PathLike[str],
    stem: str,
) -> Path:
    """Write a time series: one VTU per frame and a ``<stem>.pvd`` index; return the index.

    Parameters
    ----------
    meshes : iterable of meshio.Mesh
        One mesh per frame (an iterator is fine: frames are written as they come).
    times : (n_frames,) float array
        Strictly increasing, finite frame times (any unit: seconds, epochs).
    folder : str or os.PathLike
        Destination folder, created if needed.
    stem : str
        Plain file stem; frames are ``<stem>_0000.vtu``, ``<stem>_0001.vtu``, ...

    Every file is written atomically and the index last, with frame names relative to the
    index. Frame files of an earlier ``<stem>`` series that the new index does not list are
    removed after the index is written. If a frame fails, the exception propagates and no
    new index is written.
    """
    stem = _check_name("stem", stem)
    t = _float_array("times", times, (None,))
    if t.size == 0:
        raise ValueError("times must hold at least one frame time")
    if np.any(np.diff(t) <= 0):
        i = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise ValueError(f"times must be strictly increasing; times[{i + 1}] <= times[{i}]")
    folder = Path(folder)
    width = max(4, len(str(t.size - 1)))
    names: list[str] = []
    for i, mesh in enumerate(meshes):
        if i >= t.size:
            raise ValueError(f"more meshes than times ({t.size})")
        name = f"{stem}_{i:0{width}d}.vtu"
        write_mesh(mesh, folder / name)
        names.append(name)
    if len(names) != t.size:
        raise ValueError(f"got {len(names)} meshes for {t.size} times")
    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
        "  <Collection>",
        *(
            f'    <DataSet timestep="{ti!r}" group="" part="0" file={quoteattr(name)}/>'
            for ti, name in zip(t.tolist(), names)
        ),
        "  </Collection>",
        "</VTKFile>",
        "",
    ]
    index = write_text_atomic(folder / f"{stem}.pvd", "\n".join(lines))
    keep = set(names)
    frame = re.compile(rf"^{re.escape(stem)}_\d+\.vtu$")
    for old in folder.iterdir():
        if frame.match(old.name) and old.name not in keep:
            old.unlink(missing_ok=True)
    return index


def time_history_series(
    net: SpringNetwork,
    times: ArrayLike,
    positions: ArrayLike,
    rest_length: ArrayLike,
    stiffness: ArrayLike,
    folder: str | os.PathLike[str],
    stem: str,
    *,
    sources: ArrayLike = (),
    targets: ArrayLike = (),
) -> Path:
    """A network learning in physical time as a PVD series: one frame per output time.

    Parameters
    ----------
    net : SpringNetwork
        The starting network (its positions are the reference configuration).
    times : (T,) float array
        Output times (physical time units), strictly increasing; the PVD time steps.
    positions : (T, n_nodes, 2) float array
        The moving network at each time (e.g. ``TimeHistory.positions``).
    rest_length, stiffness : (T, n_springs) float arrays
        The learning degrees of freedom at each time; each frame carries them, so the
        ``strain``, ``force`` and ``rest_length`` arrays follow the learning.
    folder, stem : as for :func:`write_series`
    sources, targets : spring indices for the ``role`` cell array.

    Returns
    -------
    pathlib.Path of the ``.pvd`` index.
    """
    x = np.asarray(positions, dtype=np.float64)
    L = np.asarray(rest_length, dtype=np.float64)
    k = np.asarray(stiffness, dtype=np.float64)
    T = np.size(times)
    if x.shape != (T, net.n_nodes, 2):
        raise ValueError(f"positions must have shape ({T}, {net.n_nodes}, 2), got {x.shape}")
    for name, arr in (("rest_length", L), ("stiffness", k)):
        if arr.shape != (T, net.n_springs):
            raise ValueError(f"{name} must have shape ({T}, {net.n_springs}), got {arr.shape}")
    roles = spring_roles(net.n_springs, sources=sources, targets=targets)
    frames = (
        network_mesh(net.with_rest_length(Li).with_stiffness(ki), xi, fields={"role": roles})
        for xi, Li, ki in zip(x, L, k)
    )
    return write_series(frames, times, folder, stem)


def body_history_series(
    points: ArrayLike,
    triangles: ArrayLike,
    times: ArrayLike,
    positions: ArrayLike,
    eigenstrain: ArrayLike,
    modulus: ArrayLike,
    folder: str | os.PathLike[str],
    stem: str,
) -> Path:
    """A body learning in physical time as a PVD series: one frame per output time.

    The continuum counterpart of :func:`time_history_series` (a learnable body's run of
    :func:`~continuum_vs_network.learning.physical_time.learn_in_time`).

    Parameters
    ----------
    points : (n_vertices, 2) float array
        Undeformed vertices (``body.mesh.p.T``, length units).
    triangles : (n_elements, 3) int array
        The elements' vertices (``body.mesh.t.T``).
    times : (T,) float array
        Output times, strictly increasing; the PVD time steps.
    positions : (T, n_vertices, 2) float array
        Deformed vertices at each time (``TimeHistory.positions``); the frames carry
        ``positions - points`` as the point array ``displacement``.
    eigenstrain : (T, n_elements, 3) float array
        Learned rest strain ``(xx, yy, xy)`` at each time (``TimeHistory.rest_length``):
        cell tensor ``eigenstrain``.
    modulus : (T, n_elements) float array
        Learned modulus scale at each time (``TimeHistory.stiffness``): cell ``modulus``.
    folder, stem : as for :func:`write_series`

    Returns
    -------
    pathlib.Path of the ``.pvd`` index.
    """
    p, tri, T = _float_array("points", points, (None, 2)), np.asarray(triangles), np.size(times)
    x = _float_array("positions", positions, (T, p.shape[0], 2))
    ne = tri.shape[0] if tri.ndim == 2 else -1
    eps = _float_array("eigenstrain", eigenstrain, (T, ne, 3))
    s = _float_array("modulus", modulus, (T, ne))
    e9 = np.zeros((T, ne, 9))  # ParaView tensors xx xy xz yx yy yz zx zy zz
    e9[..., [0, 4, 1, 3]] = eps[..., [0, 1, 2, 2]]
    frames = (
        continuum_mesh(p, tri, xi - p, cell_fields={"eigenstrain": e, "modulus": m})
        for xi, e, m in zip(x, e9, s)
    )
    return write_series(frames, times, folder, stem)


def read_series_index(path: str | os.PathLike[str]) -> list[tuple[float, Path]]:
    """The ``(time, frame path)`` pairs listed in a ``.pvd`` index, in file order."""
    path = Path(path)
    root = ET.parse(path).getroot()
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        raise ValueError(f"{path} is not a VTK Collection (.pvd) file")
    return [
        (float(ds.attrib["timestep"]), path.parent / ds.attrib["file"])
        for ds in root.iter("DataSet")
    ]
