"""Learning in the continuum: the same rule objects on a finite-element material.

Physical facts checked: the P1 stiffness on a lattice's own triangles is the lattice
Hessian; linear elasticity makes ``E^C - E^F`` exactly the effective-stiffness quadratic
form, so coupled learning of the eigenstrain *is* the gradient of the effective-stiffness-
weighted cost at every nudge amplitude; the adjoint gradient matches finite differences;
one step of every rule lowers the error; histories and checkpoints round-trip a continuum.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")

import continuum_vs_network as cvn
from continuum_vs_network.continuum.learnable import learnable_body
from continuum_vs_network.continuum.learning_states import (
    cost_gradient,
    effective_stiffness,
)
from continuum_vs_network.continuum.material_task import MaterialTask
from continuum_vs_network.continuum.materials import (
    Material,
    _face_weights,
    lattice_lame,
)
from continuum_vs_network.continuum.mesh import network_faces, network_mesh
from continuum_vs_network.learning.history import History

EVERYWHERE = {"learn_sources": True, "learn_targets": True}  # defaults: bulk only


def _setup(order=1, *, kind="tensor", material=None, seed=0, refine=0):
    net = cvn.triangular_lattice(7, 7)
    rng = np.random.default_rng(seed)
    task = cvn.stern_task(net, 3, 2, rng, source_std=0.01, target_std=0.01)
    body = learnable_body(
        network_mesh(net, refine=refine), material or lattice_lame(1.0), order=order, kind=kind
    )
    mtask = MaterialTask.from_network(net, task, body)
    n = body.n_elements
    body = body.with_eigenstrain(0.01 * rng.standard_normal((n, 3)))
    body = body.with_modulus(1.0 + 0.5 * rng.random(n))
    return net, task, body, mtask, rng


def test_p1_stiffness_on_the_lattice_triangles_is_the_lattice_hessian():
    """Each equilateral P1 triangle with lam = mu = sqrt(3) k / 4 is three half-springs:
    the assembled stiffness is the Hessian of the unstressed lattice with its outline
    springs (one triangle each) at half stiffness."""
    net = cvn.triangular_lattice(9, 8, spacing=0.7, stiffness=2.5)
    body = learnable_body(network_mesh(net), lattice_lame(2.5), order=1)
    K = body.stiffness().toarray()
    w = _face_weights(net, network_faces(net))
    H = cvn.hessian(net.positions, net.with_stiffness(2.5 * w)).toarray()
    assert np.abs(K - H).max() <= 1e-14 * np.abs(H).max()


@pytest.mark.parametrize("order", [1, 2])
def test_clamped_minus_free_energy_is_the_effective_stiffness_form(order):
    _, _, body, mtask, rng = _setup(order)
    free = body.free_state(mtask)
    v = free.target_strain + rng.normal(0, 0.01, mtask.n_targets)
    clamped = body.clamped_state(mtask, v)
    KT = effective_stiffness(body, mtask)
    d = v - free.target_strain
    assert clamped.energy - free.energy == pytest.approx(0.5 * d @ KT @ d, rel=1e-9)
    np.testing.assert_allclose(clamped.target_strain, v, atol=1e-14)
    np.testing.assert_allclose(free.source_strain, mtask.source_strain, atol=1e-14)


@pytest.mark.parametrize(
    ("order", "kind", "material"),
    [
        (1, "tensor", None),
        (2, "tensor", Material.from_young(1.0, 0.3, plane="strain")),
        (1, "isotropic", Material.from_young(1.0, 0.3, plane="stress")),
        (2, "isotropic", None),
    ],
)
def test_coupled_learning_of_eigenstrain_is_the_weighted_gradient_at_every_eta(
    order, kind, material
):
    """GCL's eigenstrain update equals -alpha d/dtheta [d^T K_T d / 2] (the adjoint
    gradient with the targets' effective stiffness as weight) for every eta, not only as
    eta -> 0: the nudged minus free state is linear in the nudge and K_T does not depend
    on the eigenstrain."""
    _, _, body, mtask, _ = _setup(order, kind=kind, material=material)
    free = body.free_state(mtask)
    exact = -0.7 * cost_gradient(
        body, mtask, free, "eigenstrain", weight=effective_stiffness(body, mtask)
    )
    for eta in (1e-3, 0.1, 1.0, 3.0):
        step = cvn.CoupledLearning(0.7, eta, dof="eigenstrain", **EVERYWHERE).update(body, mtask)
        err = np.abs(step.raw - exact).max() / np.abs(exact).max()
        assert err < 1e-10, (eta, err)


def test_coupled_learning_of_modulus_is_affine_in_eta_and_the_full_gradient_at_eta_one():
    """For the modulus K_T depends on theta: GCL(eta) = -alpha [d^T K_T dS/ds + eta/2
    d^T dK_T/ds d], affine in eta; at eta = 1 it is the gradient of d^T K_T d / 2 (finite
    differences) and as eta -> 0 the gradient with K_T held fixed (adjoint)."""
    _, _, body, mtask, rng = _setup(1)
    alpha = 1.0

    def gcl(eta):
        rule = cvn.CoupledLearning(alpha, eta, dof="modulus", **EVERYWHERE)
        return rule.update(body, mtask).raw

    g1, g2, g3 = gcl(0.2), gcl(0.5), gcl(1.0)
    assert np.abs((g3 - g2) / 0.5 - (g2 - g1) / 0.3).max() < 1e-8 * np.abs(g1).max()
    free = body.free_state(mtask)
    KT = effective_stiffness(body, mtask)
    held = -alpha * cost_gradient(body, mtask, free, "modulus", weight=KT)
    g0 = g1 - 0.2 * (g2 - g1) / 0.3  # extrapolated to eta = 0
    assert np.abs(g0 - held).max() < 1e-8 * np.abs(held).max()

    def c_eff(s):
        b = body.with_modulus(s)
        d = b.free_state(mtask).target_strain - mtask.target_strain
        return 0.5 * d @ effective_stiffness(b, mtask) @ d

    h = 1e-6
    for e in rng.choice(body.n_elements, 6, replace=False):
        s = body.modulus.copy()
        s[e] += h
        up = c_eff(s)
        s[e] -= 2 * h
        fd = (up - c_eff(s)) / (2 * h) / body.area[e]
        assert -g3[e] / alpha == pytest.approx(fd, rel=1e-5, abs=1e-9 * np.abs(g3).max())


@pytest.mark.parametrize("dof", ["eigenstrain", "modulus"])
@pytest.mark.parametrize("order", [1, 2])
def test_exact_gradient_matches_finite_differences(dof, order):
    _, _, body, mtask, rng = _setup(order)
    rule = cvn.ExactGradient(1.0, dof=dof, **EVERYWHERE)
    grad = -rule.update(body, mtask).raw * (body.area if dof == "modulus" else body.area[:, None])
    theta = body.parameters(dof)
    flat = theta.ravel()
    h = 1e-6
    for i in rng.choice(flat.size, 6, replace=False):
        vals = []
        for sign in (1, -1):
            t = flat.copy()
            t[i] += sign * h
            b = body.with_parameters(dof, t.reshape(theta.shape))
            vals.append(mtask.error(b.free_state(mtask).target_strain))
        fd = (vals[0] - vals[1]) / (2 * h)
        assert grad.ravel()[i] == pytest.approx(fd, rel=1e-5, abs=1e-8 * np.abs(grad).max())


@pytest.mark.parametrize(
    "rule",
    [
        cvn.CoupledLearning(0.3, 0.1, dof="eigenstrain", **EVERYWHERE),
        cvn.ProspectiveConfiguration(0.1, dof="eigenstrain", **EVERYWHERE),
        cvn.ExactGradient(0.1, dof="eigenstrain", **EVERYWHERE),
        cvn.CoupledLearning(100.0, 0.1, dof="modulus", **EVERYWHERE),
        cvn.ExactGradient(100.0, dof="modulus", **EVERYWHERE),
    ],
    ids=lambda r: f"{r.name}-{r.dof}",
)
def test_one_small_step_lowers_the_error(rule):
    _, _, body, mtask, _ = _setup(1)
    before = mtask.error(body.free_state(mtask).target_strain)
    after_body = rule.update(body, mtask).apply(body)
    after = mtask.error(after_body.free_state(mtask).target_strain)
    assert after < before


def test_the_same_rule_object_trains_a_network_and_its_continuum():
    net, task, body, mtask, _ = _setup(1)
    body = body.with_eigenstrain(0.0).with_modulus(1.0)
    rule = cvn.CoupledLearning(0.5, 0.1, **EVERYWHERE)  # dof "rest_length" <-> eigenstrain
    h_net = cvn.train(net, task, rule, 30, progress=False)
    h_body = cvn.train(body, mtask, rule, 30, progress=False)
    for h in (h_net, h_body):
        assert h.completed[0] == 30
        assert h.error_initial[0, -1] < 1e-2 * h.error_initial[0, 0]
    # in linear response the lattice and its P1 continuum start from the same error
    assert h_body.error_initial[0, 0] == pytest.approx(h_net.error_initial[0, 0], rel=0.05)


def test_history_and_checkpoint_round_trip_a_continuum(tmp_path):
    _, _, body, mtask, _ = _setup(1)
    rule = cvn.CoupledLearning(0.5, 0.1, dof="modulus", min_stiffness=0.1, **EVERYWHERE)
    full = cvn.train(body, mtask, rule, 6, progress=False)
    ck = tmp_path / "ck.npz"
    cvn.train(body, mtask, rule, 6, progress=False, checkpoint=ck, checkpoint_every=3)
    resumed = cvn.train(body, mtask, rule, 6, progress=False, checkpoint=ck, checkpoint_every=3)
    np.testing.assert_array_equal(resumed.error_initial, full.error_initial)
    loaded = History.load(full.save(tmp_path / "h.npz"))
    np.testing.assert_array_equal(loaded.final[0].modulus, full.final[0].modulus)
    np.testing.assert_array_equal(loaded.tasks[0].target_a, mtask.target_a)


def test_frozen_targets_freeze_the_elements_the_target_springs_cross():
    net, task, body, mtask, _ = _setup(1)
    rule = cvn.CoupledLearning(0.5, 0.1, learn_sources=True, learn_targets=False)
    step = rule.update(body, mtask)
    frozen = body.elements_crossed(mtask.target_a, mtask.target_b)
    faces = network_faces(net)  # the mesh's elements, in order
    ends = net.springs[task.targets]
    touching = [np.flatnonzero(np.isin(faces, e).sum(axis=1) == 2) for e in ends]
    np.testing.assert_array_equal(frozen, np.unique(np.concatenate(touching)))
    assert np.all(step.delta[frozen] == 0.0)
    assert np.count_nonzero(np.any(step.delta != 0, axis=1)) > body.n_elements // 2


def test_bad_input_gives_one_clear_error():
    net, task, body, mtask, _ = _setup(1)
    with pytest.raises(ValueError, match="strain_reference='initial'"):
        cvn.CoupledLearning(0.1, 0.1, strain_reference="current").update(body, mtask)
    with pytest.raises(ValueError, match="SpringNetwork learns"):
        cvn.CoupledLearning(0.1, 0.1, dof="modulus", **EVERYWHERE).update(net, task)
    with pytest.raises(ValueError, match="MaterialTask"):
        cvn.CoupledLearning(0.1, 0.1, **EVERYWHERE).update(body, task)
    with pytest.raises(ValueError, match="modulus"):
        body.with_modulus(-1.0)
    with pytest.raises(cvn.LearningError, match="modulus"):
        cvn.ExactGradient(1e9, dof="modulus", **EVERYWHERE).update(body, mtask).apply(body)


# -- the continuum_learning scene ------------------------------------------------------------
_SCENE = """
name = "tiny_continuum_learning"
description = "test"
seed = 1
kind = "continuum_learning"

[network]
builder = "triangular"
size = 8

[task]
kind = "stern"
n_sources = 3
n_targets = 2
source_std = 0.01
target_std = 0.01

[learning]
rules = {rules}
steps = 40
strain_reference = "initial"
alpha_gcl = 0.5
alpha_exact = 0.5

[continuum]
refine = 1
order = 1

[export]
networks = true
continuum = true
"""


def test_continuum_learning_scene_reports_both_media_with_findings(tmp_path):
    import json

    from continuum_vs_network.report import write_report
    from continuum_vs_network.scenes import load_scene, run_scene
    from continuum_vs_network.scenes.meshes import export_meshes

    path = tmp_path / "tiny.toml"
    path.write_text(_SCENE.format(rules='["gcl", "exact"]'))
    result = run_scene(load_scene(path), tmp_path / "result", progress=False)
    net = result.units["continuum_learning/network/gcl"]
    h = result.units["continuum_learning/refine0/gcl"]
    # same lattice, same task, one rule object: the two media start from nearly one error
    assert h.arrays["error"][0] == pytest.approx(net.arrays["error"][0], rel=0.05)
    assert h.arrays["coarse"].shape == net.arrays["coarse"].shape
    meshes = export_meshes(result, tmp_path / "meshes")
    assert {p.name for p in meshes} >= {"learned_network_gcl.vtu", "learned_refine1_exact.vtu"}
    write_report(result, tmp_path / "report", meshes=meshes, render=False)
    findings = json.loads((tmp_path / "report" / "report.json").read_text())["findings"]
    claims = {f["claim"]: f for f in findings}
    same = claims["coupled learning and the exact gradient learn the same continuum field"]
    assert same["measured"]["relative difference"] < 1e-2
    # a decoupled run's field is prestress: then the agreement is not evidence (not comparable)
    from continuum_vs_network.learning.coupling import DECOUPLED_BELOW

    shares = [same["measured"]["share gcl"], same["measured"]["share exact"]]
    decoupled = min(shares) < DECOUPLED_BELOW
    assert same["verdict"] == ("not comparable" if decoupled else "reproduced")
    assert any("1 -> 1" in c for c in claims)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (_SCENE.format(rules='["gcl_floor"]'), "not a continuum_learning rule"),
        (_SCENE.format(rules='["gcl"]').replace("size = 8", ""), "size"),
        (
            _SCENE.format(rules='["gcl"]').replace('"initial"', '"current"'),
            "strain_reference",
        ),
    ],
)
def test_continuum_learning_scene_rejects_bad_settings(tmp_path, text, match):
    from continuum_vs_network.scenes import load_scene
    from continuum_vs_network.scenes.schema import SceneError

    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SceneError, match=match):
        load_scene(path)
