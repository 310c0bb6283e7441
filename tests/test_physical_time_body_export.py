"""PVD export of a body learning in physical time: one frame per output time, the last
frame the run's final field, and the physical_time scene writing the continuum's series."""

from __future__ import annotations

import numpy as np
import pytest
from physical_time_scenes import tiny_physical_time

import continuum_vs_network as cvn
from continuum_vs_network.learning import ProspectiveConfiguration, stern_task
from continuum_vs_network.learning.physical_time import learn_in_time
from continuum_vs_network.network.viscous import Viscosity

BULK = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}


@pytest.fixture(scope="module")
def body_task():
    pytest.importorskip("skfem")
    pytest.importorskip("meshio")
    from continuum_vs_network.continuum.learnable import learnable_body
    from continuum_vs_network.continuum.material_task import MaterialTask
    from continuum_vs_network.continuum.materials import lattice_lame
    from continuum_vs_network.continuum.mesh import network_mesh

    net = cvn.triangular_lattice(6, 6)
    task = stern_task(net, 2, 1, np.random.default_rng(4), source_std=0.1, target_std=0.1)
    body = learnable_body(network_mesh(net), lattice_lame(1.0))
    return body, MaterialTask.from_network(net, task, body)


def test_body_series_has_one_frame_per_output_and_ends_at_the_final_field(body_task, tmp_path):
    """GPC at equilibrium steps: the moving body after the last step is the clamped
    equilibrium of the body learned one step before (computed here independently with
    clamped_state); the last frame's displacement, eigenstrain and modulus are it."""
    import meshio

    from continuum_vs_network.io.export import body_history_series, read_series_index

    body, task = body_task
    rule = ProspectiveConfiguration(0.4, **BULK)
    h = learn_in_time(body, task, rule, viscosity=Viscosity(drag=1.0), duration=5.0, dt=1.0,
                      n_outputs=5, quasistatic=True)  # fmt: skip
    points, triangles = body.body.mesh.p.T, body.body.mesh.t.T
    index = body_history_series(
        points, triangles, h.times, h.positions, h.rest_length, h.stiffness, tmp_path, "run"
    )
    frames = read_series_index(index)
    assert [t for t, _ in frames] == pytest.approx(h.times.tolist())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.pvd"] + [
        f"run_{i:04d}.vtu" for i in range(h.times.size)
    ]
    before = body.with_eigenstrain(h.rest_length[-2])
    u = before.clamped_state(task, task.target_strain).u
    final = before.vertex_positions(u) - points
    assert np.max(np.abs(final)) > 1e-3  # the field moved
    last = meshio.read(frames[-1][1])
    np.testing.assert_allclose(last.point_data["displacement"][:, :2], final, atol=1e-12)
    np.testing.assert_allclose(last.point_data["displacement"][:, 2], 0.0)
    eps = last.cell_data["eigenstrain"][0].reshape(-1, 3, 3)
    np.testing.assert_allclose(eps[:, 0, 0], h.rest_length[-1][:, 0])
    np.testing.assert_allclose(eps[:, 1, 1], h.rest_length[-1][:, 1])
    np.testing.assert_allclose(eps[:, 0, 1], h.rest_length[-1][:, 2])
    np.testing.assert_allclose(last.cell_data["modulus"][0], h.stiffness[-1])
    first = meshio.read(frames[0][1])
    np.testing.assert_allclose(first.point_data["displacement"][:, :2], h.positions[0] - points)


def test_bad_body_series_input_is_named(body_task, tmp_path):
    from continuum_vs_network.io.export import body_history_series

    body, task = body_task
    h = learn_in_time(body, task, ProspectiveConfiguration(0.4, **BULK),
                      viscosity=Viscosity(drag=1.0), duration=2.0, dt=1.0, n_outputs=2)  # fmt: skip
    p, t = body.body.mesh.p.T, body.body.mesh.t.T
    args = [h.times, h.positions, h.rest_length, h.stiffness]
    for i, name in enumerate(("positions", "eigenstrain", "modulus")):
        bad = list(args)
        bad[i + 1] = bad[i + 1][:-1]
        with pytest.raises(ValueError, match=name):
            body_history_series(p, t, *bad, tmp_path, "bad")
    with pytest.raises(ValueError, match="times must be strictly increasing"):
        body_history_series(p, t, h.times[::-1], *args[1:], tmp_path, "bad")
    assert not any(tmp_path.iterdir())  # nothing half-written


def test_physical_time_scene_exports_the_continuum_series(tmp_path):
    """A continuum physical_time scene with [export] series = true writes the body's
    series: the scene's frame count, the last frame the run's last output."""
    pytest.importorskip("meshio")

    import meshio

    from continuum_vs_network.io.export import read_series_index
    from continuum_vs_network.scenes.meshes import export_meshes
    from continuum_vs_network.scenes.results import from_stored
    from continuum_vs_network.scenes.results.physical_time import TimeRunResult
    from continuum_vs_network.scenes.runner import run_scene

    scene = tiny_physical_time(
        "ptb", rules=["gpc"], media=["continuum"], ratios=[1.0], bisections=0,
        arm_stiffness=0.5, arm_dashpot=2.0, frames=4, series=True,
    )  # fmt: skip
    result = run_scene(scene, tmp_path / "results")
    (unit,) = [
        from_stored(u, TimeRunResult)
        for k, u in result.select("physical_time/").items()
        if not k.endswith("/task")
    ]
    a = unit.fields
    written = export_meshes(result, tmp_path / "meshes")
    (index,) = [p for p in written if p.name == "gpc_n5_continuum_physical_time.pvd"]
    frames = read_series_index(index)
    assert len(frames) == 4
    assert [t for t, _ in frames] == pytest.approx(a["series/times"].tolist())
    last = meshio.read(frames[-1][1])
    np.testing.assert_allclose(
        last.point_data["displacement"][:, :2], a["series/x"][-1] - a["body/points"]
    )
    assert a["series/times"][-1] == pytest.approx(unit.runs[0]["duration"])
