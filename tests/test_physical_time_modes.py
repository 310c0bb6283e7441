"""The linear modes behind physical_time's relaxation times (scenes/units_time_modes.py)
and their report part (report/sections/physical_time/modes.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl
import scipy.sparse as sp
from physical_time_scenes import tiny_physical_time

from continuum_vs_network.learning.physical_time import network_relaxation_time
from continuum_vs_network.network.energy import hessian
from continuum_vs_network.network.viscous import Viscosity
from continuum_vs_network.scenes import units_time_modes as um
from continuum_vs_network.scenes.results.physical_time import TimeTaskResult
from continuum_vs_network.scenes.units_time import _body, _lattice_task

DRAG = Viscosity(drag=1.0)


def _task(n: int = 6, draw: int = 0):
    scene = tiny_physical_time(sizes=(n,), n_sources=1, n_targets=1)
    return _lattice_task(scene, n, draw)


def test_slowest_mode_matches_a_dense_eigensolve_with_and_without_a_constraint():
    net, task = _task()
    free = ~task.pinned.ravel()
    K = hessian(net.positions, net).tocsr()[free][:, free]
    rng = np.random.default_rng(1)
    C = sp.diags(rng.uniform(0.5, 2.0, K.shape[0])).tocsr()
    lam, phi = um.slowest_mode(K, C)
    dense = sl.eigh(K.toarray(), C.toarray(), eigvals_only=True)[0]
    assert lam == pytest.approx(dense, rel=1e-9)
    assert phi @ (C @ phi) == pytest.approx(1.0)
    G = sp.csr_matrix(rng.normal(size=(1, K.shape[0])))
    lam_c, phi_c = um.slowest_mode(K, C, G)
    Z = sl.null_space(G.toarray())
    dense_c = sl.eigh(Z.T @ K.toarray() @ Z, Z.T @ C.toarray() @ Z, eigvals_only=True)[0]
    assert lam_c == pytest.approx(dense_c, rel=1e-9)
    assert abs((G @ phi_c)[0]) < 1e-10
    assert lam_c > lam  # a constraint stiffens the slowest mode


def test_modal_sum_predicts_the_networks_measured_settling_time():
    """The dense modal sum of the linearised step settles when the integrated (nonlinear,
    backward Euler) network does, within 5 %; the slowest mode is its own time. Held end
    nodes at the task's step (strain 0.17); the default strain clamp (rods) at a tenth of
    it: a source held by its length only turns freely, so at 0.17 the nonlinear run
    settles ~15 % sooner than the linear modes (at 0.1x and 0.01x within 1 %)."""
    import dataclasses

    net, task = _task(6)
    modes = um.network_modes(net, task, DRAG, clamp="nodes")
    tau = network_relaxation_time(net, task, DRAG, clamp="nodes")
    assert modes["tau_modal"] == pytest.approx(tau, rel=0.05)
    assert modes["setting_time"] <= modes["tau_mode"] * (1 + 1e-12)
    assert modes["cancellation"] >= modes["setting_weight"] > 0
    assert modes["tau_mode_constraint"] > modes["tau_mode"]  # held end nodes stiffen
    assert modes["tau_mode_nodes"] == modes["tau_mode"]
    small = dataclasses.replace(task, source_strain=0.1 * task.source_strain)
    strain = um.network_modes(net, small, DRAG)
    assert strain["tau_modal"] == pytest.approx(network_relaxation_time(net, small, DRAG), rel=0.05)
    assert strain["tau_mode"] == strain["tau_mode_constraint"]  # as run: the constraint
    assert strain["tau_mode_nodes"] == pytest.approx(modes["tau_mode"], rel=1e-9)
    assert strain["setting_time"] <= strain["tau_mode"] * (1 + 1e-12)


def test_body_is_the_network_with_half_edges_and_drag_by_area():
    """The P1 body's stiffness is the Hessian with edge_weights' spring factors (to round-
    off), and its slowest-mode time that of the network with the same strain clamp, edges
    and lumped drag (within 1 %: consistent against lumped drag)."""
    pytest.importorskip("skfem")
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    net, task = _task(6)
    body, mtask = _body(net, task)
    factor, area = um.edge_weights(net)
    assert set(np.unique(factor)) == {0.5, 1.0}
    assert area.sum() == pytest.approx(5**2)  # the 6 x 6 lattice: (n - 1)^2 node areas
    H = hessian(net.positions, net.with_stiffness(net.stiffness * factor))
    assert abs(body.stiffness() - H).max() < 1e-12
    b = um.body_modes(body, mtask, lattice_damping(DRAG))
    n = um.network_modes(net, task, DRAG)
    assert b["tau_mode"] == pytest.approx(n["tau_mode_edges"], rel=0.01)
    assert math.isfinite(b["tau_modal"]) and 0 < b["displacement_share"] <= 1


def test_global_step_is_the_relaxation_scenes_slowest_mode():
    """The relaxation scene's drive: its slowest-mode time is 1 / lambda_min of the Hessian
    with both sides held (drag 1), as units_physics computes it."""
    net, _ = _task(6)
    g = um.global_step_share(net, DRAG)
    x = net.positions
    held = (x[:, 0] < x[:, 0].min() + 0.6) | (x[:, 0] > x[:, 0].max() - 0.6)
    free = np.repeat(~held, 2)
    H = hessian(x, net).toarray()[np.ix_(free, free)]
    assert g["tau_mode"] == pytest.approx(1.0 / np.linalg.eigvalsh(H)[0], rel=1e-9)
    assert 0 <= g["displacement_share"] <= 1


def _unit(n, draw, tau_net, tau_body, mode_net, mode_body, edges):
    modes = {
        "tau_mode": mode_net,
        "tau_mode_constraint": mode_net,
        "tau_mode_nodes": mode_net / 3,
        "tau_mode_edges": edges,
        "tau_modal": tau_net,
        "slow_weight": 0.02,
        "displacement_share": 0.1,
        "setting_time": mode_net,
        "setting_weight": 0.02,
        "cancellation": 5.0,
    }
    body = {**modes, "tau_mode": mode_body, "tau_modal": tau_body}
    none = np.empty(0)  # the task's arrays: not read by the findings
    return TimeTaskResult(
        n=n,
        draw=draw,
        n_nodes=n * n,
        sources=none,
        source_strain=none,
        targets=none,
        target_strain=none,
        pinned=none,
        network={"tau": tau_net, "tau_force": 1.0, "modes": modes},
        continuum={"tau": tau_body, "tau_force": 1.0, "modes": body},
    )


def test_report_findings_follow_their_rules():
    from continuum_vs_network.report.findings import NOT_REPRODUCED, REPRODUCED
    from continuum_vs_network.report.sections.physical_time.modes import _findings

    tasks = [
        _unit(8, 0, 60.0, 200.0, 50.0, 190.0, 190.0),
        _unit(8, 1, 20.0, 100.0, 50.0, 200.0, 200.0),  # tau / tau_mode 0.4 against 1.2
        _unit(16, 0, 200.0, 800.0, 200.0, 800.0, 800.0),
    ]
    agree, modal, spread, grows = _findings(tasks, ["network", "continuum"], True)
    assert agree.verdict == REPRODUCED and modal.verdict == REPRODUCED
    assert spread.verdict == REPRODUCED  # network N = 64: 1.2 / 0.4 = 3 > 2
    assert grows.verdict == REPRODUCED  # (200 / 50) over a factor 2 in n: p = 2
    tasks[2].continuum["modes"]["tau_mode"] = 1200.0  # 50 % off the matched network
    assert _findings(tasks, ["network", "continuum"], True)[0].verdict == NOT_REPRODUCED
    # a draw whose modes cancel at the target is shown apart, not judged
    tasks[1].network["tau"] = 40.0
    assert _findings(tasks, ["network", "continuum"], True)[1].verdict == NOT_REPRODUCED
    tasks[1].network["modes"]["cancellation"] = 500.0
    modal = _findings(tasks, ["network", "continuum"], True)[1]
    assert modal.verdict == REPRODUCED
    assert modal.measured["draws apart (sum of weights > 100)"] == 1
    assert modal.measured["largest |tau_modal / tau - 1| apart"] == pytest.approx(0.5)
