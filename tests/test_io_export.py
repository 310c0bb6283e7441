"""meshio export: round trips, physical cell data, atomic writes, PVD time series."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from continuum_vs_network import SpringNetwork, triangular_lattice

meshio = pytest.importorskip("meshio")

from continuum_vs_network.io import export  # noqa: E402
from continuum_vs_network.io.export import (  # noqa: E402
    continuum_mesh,
    default_mesh_dir,
    network_mesh,
    read_series_index,
    spring_roles,
    write_mesh,
    write_series,
)


def _lattice(nx: int = 4, ny: int = 3, spacing: float = 1.0) -> SpringNetwork:
    """Triangular lattice, all springs at rest, stiffness graded from 1 to 1.5."""
    net = triangular_lattice(nx, ny, spacing=spacing)
    return net.with_stiffness(1.0 + 0.5 * np.arange(net.n_springs) / net.n_springs)


@pytest.fixture
def net() -> SpringNetwork:
    return _lattice()


def _unit_square_mesh(n: int = 3):
    xs, ys = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    pts = np.c_[xs.ravel(), ys.ravel()]
    tri = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tri += [(a, a + 1, a + n + 2), (a, a + n + 2, a + n + 1)]
    return pts, np.array(tri)


def _assert_same_mesh(read, written) -> None:
    np.testing.assert_array_equal(read.points, written.points)
    assert [c.type for c in read.cells] == [c.type for c in written.cells]
    for a, b in zip(read.cells, written.cells):
        np.testing.assert_array_equal(a.data, b.data)
    assert set(read.point_data) == set(written.point_data)
    for name, arr in written.point_data.items():
        np.testing.assert_array_equal(read.point_data[name], arr, err_msg=name)
        assert read.point_data[name].dtype == arr.dtype, name
    assert set(read.cell_data) == set(written.cell_data)
    for name, blocks in written.cell_data.items():
        for a, b in zip(read.cell_data[name], blocks):
            np.testing.assert_array_equal(a, b, err_msg=name)
            assert a.dtype == b.dtype, name


# -- network meshes -----------------------------------------------------------------------
def test_uniform_stretch_gives_uniform_strain_and_tension(net):
    """x = (1 + e) X: every spring has strain e, tension k L e, displacement e X."""
    e = 0.03
    mesh = network_mesh(net, (1 + e) * net.positions)
    strain = mesh.cell_data["strain"][0]
    np.testing.assert_allclose(strain, e, rtol=1e-12)
    np.testing.assert_allclose(mesh.cell_data["force"][0], net.stiffness * net.rest_length * e)
    np.testing.assert_allclose(mesh.cell_data["length"][0], (1 + e) * net.rest_length)
    disp = mesh.point_data["displacement"]
    assert disp.shape == (net.n_nodes, 3)
    np.testing.assert_allclose(disp[:, :2], e * net.positions)
    assert np.all(disp[:, 2] == 0)
    assert mesh.points.shape == (net.n_nodes, 3)
    np.testing.assert_array_equal(mesh.points[:, :2], net.positions)


def test_network_round_trip(net, tmp_path):
    rng = np.random.default_rng(1)
    x = net.positions + 0.1 * rng.standard_normal(net.positions.shape)
    roles = spring_roles(net.n_springs, sources=[0, 2], targets=[net.n_springs - 1])
    mesh = network_mesh(
        net,
        x,
        fields={"role": roles, "direction": rng.standard_normal((net.n_springs, 2))},
        point_fields={"pinned": np.arange(net.n_nodes) == 0},
    )
    path = write_mesh(mesh, tmp_path / "net.vtu")
    back = meshio.read(path)
    _assert_same_mesh(back, mesh)
    assert set(back.cell_data) >= {*export.NETWORK_CELL_FIELDS, "role", "direction"}
    np.testing.assert_array_equal(back.cell_data["role"][0][[0, 2, net.n_springs - 1]], [1, 1, 2])
    # the displacement read back, added to the points, gives the deformed positions
    np.testing.assert_allclose(back.points[:, :2] + back.point_data["displacement"][:, :2], x)
    assert back.cell_data["direction"][0].shape == (net.n_springs, 3)


def test_legacy_vtk_round_trip(net, tmp_path):
    mesh = network_mesh(net, 1.01 * net.positions)
    back = meshio.read(write_mesh(mesh, tmp_path / "net.vtk"))
    np.testing.assert_allclose(back.points, mesh.points)
    np.testing.assert_allclose(back.cell_data["strain"][0], mesh.cell_data["strain"][0])


def test_network_mesh_rejects_bad_input(net):
    with pytest.raises(ValueError, match="x must have shape"):
        network_mesh(net, net.positions[:-1])
    bad = np.array(net.positions)
    bad[1, 0] = np.nan
    with pytest.raises(ValueError, match="x must be finite"):
        network_mesh(net, bad)
    with pytest.raises(ValueError, match=r"fields\['role'\] must have shape"):
        network_mesh(net, fields={"role": np.zeros(net.n_springs + 1)})
    with pytest.raises(ValueError, match="clashes"):
        network_mesh(net, fields={"strain": np.zeros(net.n_springs)})
    with pytest.raises(ValueError, match="both sources and targets"):
        spring_roles(net.n_springs, sources=[1], targets=[1])
    with pytest.raises(ValueError, match="targets holds a spring index"):
        spring_roles(net.n_springs, targets=[net.n_springs])


# -- continuum meshes ---------------------------------------------------------------------
def test_continuum_round_trip_with_tensors(tmp_path):
    pts, tri = _unit_square_mesh()
    grad = np.array([[0.02, 0.01], [0.0, -0.01]])
    disp = pts @ grad.T  # affine displacement: constant strain sym(grad)
    eps = np.broadcast_to(0.5 * (grad + grad.T), (len(tri), 2, 2))
    lam, mu = 1.0, 0.7
    sigma = lam * np.trace(eps, axis1=1, axis2=2)[:, None, None] * np.eye(2) + 2 * mu * eps
    mesh = continuum_mesh(
        pts, tri, disp, eps, sigma, cell_fields={"area": np.full(len(tri), 1 / 18)}
    )
    back = meshio.read(write_mesh(mesh, tmp_path / "body.vtu"))
    _assert_same_mesh(back, mesh)
    strain = back.cell_data["strain"][0].reshape(-1, 3, 3)
    np.testing.assert_array_equal(strain[:, :2, :2], eps)
    assert np.all(strain[:, 2, :] == 0) and np.all(strain[:, :, 2] == 0)
    stress = back.cell_data["stress"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(stress[:, 0, 1], 2 * mu * eps[:, 0, 1])
    np.testing.assert_allclose(back.point_data["displacement"][:, :2], disp)
    assert back.cells[0].type == "triangle"


def test_continuum_accepts_3x3_and_rejects_bad_shapes():
    pts, tri = _unit_square_mesh(2)
    t3 = np.zeros((len(tri), 3, 3))
    t3[:, 2, 2] = 0.25  # plane-strain sigma_zz
    mesh = continuum_mesh(pts, tri, np.zeros_like(pts), stress=t3)
    np.testing.assert_array_equal(mesh.cell_data["stress"][0][:, 8], 0.25)
    assert "strain" not in mesh.cell_data
    with pytest.raises(ValueError, match="strain must have shape"):
        continuum_mesh(pts, tri, np.zeros_like(pts), np.zeros((len(tri), 2)))
    with pytest.raises(ValueError, match="displacement must have shape"):
        continuum_mesh(pts, tri, np.zeros((len(pts), 3)))
    with pytest.raises(ValueError, match="vertex index outside"):
        continuum_mesh(pts, tri + len(pts), np.zeros_like(pts))
    with pytest.raises(ValueError, match="triangles must hold integer"):
        continuum_mesh(pts, tri.astype(float), np.zeros_like(pts))


# -- atomic writes ------------------------------------------------------------------------
def test_write_mesh_paths(net, tmp_path):
    mesh = network_mesh(net)
    dest = write_mesh(mesh, tmp_path / "a" / "b" / "plain")
    assert dest == tmp_path / "a" / "b" / "plain.vtu" and dest.is_file()
    for bad in ("net.xdmf", "net.txt", "net.h5"):
        with pytest.raises(ValueError, match="unsupported suffix"):
            write_mesh(mesh, tmp_path / bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a"]


def test_failing_write_leaves_no_file(net, tmp_path, monkeypatch):
    mesh = network_mesh(net)

    def broken_write(path, *args, **kwargs):
        with open(path, "w") as handle:
            handle.write("<VTKFile half written")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken_write)
    with pytest.raises(OSError, match="disk full"):
        write_mesh(mesh, tmp_path / "out" / "net.vtu")
    assert list((tmp_path / "out").iterdir()) == []


def test_failing_overwrite_keeps_old_file(net, tmp_path, monkeypatch):
    dest = write_mesh(network_mesh(net), tmp_path / "net.vtu")
    before = dest.read_bytes()

    def broken_write(path, *args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(meshio, "write", broken_write)
    with pytest.raises(RuntimeError, match="boom"):
        write_mesh(network_mesh(net, 1.1 * net.positions), dest)
    assert dest.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["net.vtu"]


# -- time series --------------------------------------------------------------------------
def test_series_index_lists_frames_in_time_order(net, tmp_path):
    times = [0.0, 0.5, 1.25, 10.0]
    stretches = [0.0, 0.01, 0.02, 0.04]
    meshes = (network_mesh(net, (1 + e) * net.positions) for e in stretches)
    folder = tmp_path / "meshes" / "demo"
    index = write_series(meshes, times, folder, "relax")
    assert index == folder / "relax.pvd"
    root = ET.parse(index).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    sets = root.findall("./Collection/DataSet")
    assert [float(ds.get("timestep")) for ds in sets] == times
    assert [ds.get("file") for ds in sets] == [f"relax_{i:04d}.vtu" for i in range(4)]
    for (t, frame), e, t_want in zip(read_series_index(index), stretches, times):
        assert t == t_want
        np.testing.assert_allclose(meshio.read(frame).cell_data["strain"][0], e, atol=1e-14)
    # a shorter series under the same stem replaces the old one: no stale frames remain
    write_series([network_mesh(net)], [3.0], folder, "relax")
    assert sorted(p.name for p in folder.iterdir()) == ["relax.pvd", "relax_0000.vtu"]
    assert read_series_index(index) == [(3.0, folder / "relax_0000.vtu")]


def test_series_rejects_bad_times_and_counts(net, tmp_path):
    mesh = network_mesh(net)
    with pytest.raises(ValueError, match="strictly increasing"):
        write_series([mesh, mesh], [1.0, 1.0], tmp_path, "s")
    with pytest.raises(ValueError, match="got 1 meshes for 2 times"):
        write_series([mesh], [0.0, 1.0], tmp_path, "s")
    with pytest.raises(ValueError, match="more meshes than times"):
        write_series([mesh, mesh], [0.0], tmp_path, "s")
    assert not (tmp_path / "s.pvd").exists()
    with pytest.raises(ValueError, match="stem must be a plain name"):
        write_series([mesh], [0.0], tmp_path, "../up")


def test_failing_frame_writes_no_index(net, tmp_path, monkeypatch):
    real_write = meshio.write
    calls = []

    def flaky_write(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 2:
            raise OSError("killed mid-series")
        return real_write(path, *args, **kwargs)

    monkeypatch.setattr(meshio, "write", flaky_write)
    with pytest.raises(OSError, match="mid-series"):
        write_series([network_mesh(net)] * 3, [0.0, 1.0, 2.0], tmp_path, "s")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s_0000.vtu"]


def test_default_mesh_dir():
    assert str(default_mesh_dir("gcl", root="/data")) == "/data/meshes/gcl"
    for bad in ("", "..", "a/b", "a\\b"):
        with pytest.raises(ValueError, match="scene must be a plain name"):
            default_mesh_dir(bad)


def test_io_imports_nothing_heavy():
    code = (
        "import sys, continuum_vs_network.io, continuum_vs_network.io.export, "
        "continuum_vs_network.io.render\n"
        "heavy = {'meshio', 'pyvista', 'vtk', 'vtkmodules', 'matplotlib'} & set(sys.modules)\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
