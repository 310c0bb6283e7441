"""Learning in physical time in the continuum: the same loop and rule objects as the
network (learn_in_time through the medium), its quasi-static limit is train(), and it
tends to that limit as the ratio of learning rate to relaxation rate goes to 0."""

from __future__ import annotations

import numpy as np
import pytest
from physical_time_scenes import tiny_physical_time

import continuum_vs_network as cvn
from continuum_vs_network.learning import CoupledLearning, ProspectiveConfiguration, stern_task
from continuum_vs_network.learning.physical_time import learn_in_time
from continuum_vs_network.network.viscous import Viscosity

BULK = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}
DRAG = Viscosity(drag=1.0)


@pytest.fixture(scope="module")
def body_task():
    pytest.importorskip("skfem")
    from continuum_vs_network.continuum.learnable import learnable_body
    from continuum_vs_network.continuum.material_task import MaterialTask
    from continuum_vs_network.continuum.materials import lattice_lame
    from continuum_vs_network.continuum.mesh import network_mesh

    net = cvn.triangular_lattice(7, 7)
    task = stern_task(net, 2, 1, np.random.default_rng(4), source_std=0.1, target_std=0.1)
    body = learnable_body(network_mesh(net), lattice_lame(1.0))
    return body, MaterialTask.from_network(net, task, body)


@pytest.fixture(scope="module")
def tau(body_task):
    from continuum_vs_network.continuum.damped_states import body_relaxation_time
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    return body_relaxation_time(*body_task, lattice_damping(DRAG))  # target strains to 1 %


@pytest.fixture(scope="module")
def tau_force(body_task):
    from continuum_vs_network.continuum.damped_states import body_relaxation_time
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    return body_relaxation_time(*body_task, lattice_damping(DRAG), measure="force")


RULES = [
    (ProspectiveConfiguration(0.4, **BULK), {}),
    (CoupledLearning(0.4, 0.1, **BULK), {"form": "twin"}),
]


MODULUS = {**BULK, "dof": "stiffness", "min_stiffness": 1e-3}


@pytest.mark.parametrize(
    ("rule", "opts"),
    [*RULES, (CoupledLearning(0.5, 0.1, **MODULUS), {"form": "twin"})],
    ids=["gpc", "gcl_twin", "gcl_modulus"],
)
def test_quasi_static_learning_in_time_is_train(body_task, rule, opts):
    """Every step an equilibrium, dt_learn = 1: one step of train() per step (the same
    rule object's update of the eigenstrain, from two independent code paths)."""
    body, task = body_task
    steps = 4
    qs = learn_in_time(
        body, task, rule, viscosity=DRAG, duration=steps, dt=1.0, n_outputs=steps,
        quasistatic=True, **opts,
    )  # fmt: skip
    h = cvn.train(body, task, rule, steps, progress=False)
    np.testing.assert_allclose(qs.error, h.error_initial[0], rtol=1e-8)
    np.testing.assert_allclose(qs.rest_length[-1], h.final[0].eigenstrain, atol=1e-12)
    np.testing.assert_allclose(qs.stiffness[-1], h.final[0].modulus, atol=1e-12)
    assert qs.error[-1] < qs.error[0]


@pytest.mark.parametrize(
    ("rule", "opts"),
    [*RULES, (CoupledLearning(0.4, 0.1, **BULK), {"form": "phases"})],
    ids=["gpc", "gcl_twin", "gcl_phases"],
)
def test_continuum_learning_in_time_tends_to_the_quasi_static_result(body_task, tau, rule, opts):
    """At a fixed learning step, the gap between the error histories of the run and of its
    quasi-static limit (relative to the quasi-static drop) shrinks as the ratio rho =
    alpha tau of learning rate to relaxation rate goes to 0 (drag -> 0 at fixed alpha)."""
    body, task = body_task
    dt_learn, T = 0.25, 2.5
    dt_qs = dt_learn
    if opts.get("form") == "phases":  # one step per phase, two phases per learning step
        opts, dt_qs = {**opts, "phase": dt_learn / 2}, dt_learn / 2
    qs = learn_in_time(
        body, task, rule, viscosity=DRAG, duration=T, dt=dt_qs, n_outputs=5,
        quasistatic=True, **opts,
    )  # fmt: skip
    drop = qs.error[0] - qs.error[-1]
    assert drop > 0
    gaps = []
    for c in (1.0, 1 / 16, 1 / 256):
        ratio = rule.alpha * c * tau  # tau is proportional to the drag
        m = round(2 / c)  # physical steps per learning step: dt = tau / 64
        kw = {"dt": dt_learn / m}
        if opts.get("form") != "phases":
            kw["learn_every"] = m
        run = learn_in_time(
            body, task, rule, viscosity=Viscosity(drag=c), duration=T, n_outputs=5,
            **{**opts, **kw},
        )  # fmt: skip
        assert run.dt_learn == pytest.approx(qs.dt_learn)
        np.testing.assert_allclose(run.times, qs.times)
        gaps.append((ratio, np.max(np.abs(run.error - qs.error)) / drop))
    g = [x for _, x in gaps]
    assert g[0] > 2.0 * g[1] > 4.0 * g[2], gaps
    assert g[-1] < 0.02, gaps


def test_continuum_gcl_oscillates_or_diverges_far_past_the_relaxation_rate(
    body_task, tau, tau_force
):
    """The same rule far above the relaxation rate (alpha k tau_force = 30, alpha k tau
    more): free and nudged phases too short to relax even the net force make GCL diverge
    (a quasi-static run with the same steps converges)."""
    from continuum_vs_network.learning.rules import LearningError

    body, task = body_task
    assert tau > tau_force  # the targets settle later than the net force: rho > 30
    alpha = 30.0 / tau_force
    rule = CoupledLearning(alpha, 0.1, **BULK)
    dt = 0.1 / alpha
    kw = {"form": "phases", "phase": dt, "n_outputs": 20}
    qs = learn_in_time(body, task, rule, viscosity=DRAG, duration=5 / alpha, dt=dt,
                       quasistatic=True, **kw)  # fmt: skip
    assert qs.error[-1] < qs.error[0]
    try:
        run = learn_in_time(body, task, rule, viscosity=DRAG, duration=2 * tau_force, dt=dt, **kw)
    except (LearningError, FloatingPointError):
        return
    e = run.error / run.error[0]
    assert np.max(e / np.minimum.accumulate(e)) > 100


def test_body_relaxation_time_matches_the_lattice_within_a_factor(body_task, tau, tau_force):
    """The continuum on the lattice's triangles with the mapped drag relaxes after the
    source step on the lattice's time scale, by either criterion (net force to 1 %, target
    strains settled to 1 %), and both times are proportional to the drag (a linear
    overdamped body)."""
    net = cvn.triangular_lattice(7, 7)
    task = stern_task(net, 2, 1, np.random.default_rng(4), source_std=0.1, target_std=0.1)
    from continuum_vs_network.learning.physical_time import network_relaxation_time

    t_net = network_relaxation_time(net, task, DRAG, measure="force")
    assert 0.5 < tau_force / t_net < 2.0, (tau_force, t_net)
    # the target criterion against held end nodes: with the default strain clamp the
    # lattice's slowest mode (tau_mode 129, the body's 142) carries ~ 5 % of this target's
    # change against the body's ~ 0.1 %, so the lattice's target settles ~ 25x later (271)
    t_net_target = network_relaxation_time(net, task, DRAG, clamp="nodes")
    assert 0.5 < tau / t_net_target < 2.0, (tau, t_net_target)
    from continuum_vs_network.continuum.damped_states import body_relaxation_time
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    damping = lattice_damping(Viscosity(drag=2.0))
    assert body_relaxation_time(*body_task, damping) == pytest.approx(2 * tau, rel=0.02)
    t2 = body_relaxation_time(*body_task, damping, measure="force")
    assert t2 == pytest.approx(2 * tau_force, rel=0.02)


def test_bad_continuum_input_is_named(body_task):
    body, task = body_task
    rule = CoupledLearning(0.4, 0.1, strain_reference="current")
    with pytest.raises(ValueError, match="strain_reference='initial'"):
        learn_in_time(body, task, rule, viscosity=DRAG, duration=1.0, dt=0.1)
    with pytest.raises(ValueError, match="explicit learning step too long"):
        learn_in_time(body, task, CoupledLearning(50.0, 0.1, **BULK), viscosity=DRAG,
                      duration=1.0, dt=1.0)  # fmt: skip


def test_continuum_scene_bisects_the_critical_ratio(tmp_path):
    """A physical_time scene with the continuum medium: the critical ratio lies between
    the last ratio run (grid or bisection) before it and the first past it, and the report
    names the continuum rows."""
    pytest.importorskip("matplotlib")

    from continuum_vs_network.report.writer import write_report
    from continuum_vs_network.scenes.results import from_stored
    from continuum_vs_network.scenes.results.physical_time import TimeRunResult
    from continuum_vs_network.scenes.runner import run_scene
    from continuum_vs_network.scenes.units_time import OSCILLATION, SLOWDOWN

    scene = tiny_physical_time(
        "ptc", sizes=[6], rules=["gcl"], media=["continuum"], ratios=[0.3, 100.0],
        bisections=3, relaxation_times=1.5, learning_times=3.0,
    )  # fmt: skip
    result = run_scene(scene, tmp_path / "results")
    (m,) = [
        from_stored(u, TimeRunResult)
        for k, u in result.select("physical_time/").items()
        if not k.endswith("/task")
    ]
    assert m.medium == "continuum" and m.tau > 0
    assert len(m.bisection) == 3
    rows = sorted(m.runs + m.bisection, key=lambda r: r["ratio"])
    past = [r["slowdown"] >= SLOWDOWN or r["rebound"] >= OSCILLATION for r in rows]
    # the bracket rule: lo the largest ratio run not past, hi the next; all above hi past
    j = max(i for i, p in enumerate(past) if not p)
    assert (m.critical_low, m.critical_high) == (rows[j]["ratio"], rows[j + 1]["ratio"])
    assert all(past[j + 1 :])
    assert m.critical_low < m.critical_ratio < m.critical_high
    assert m.critical_high / m.critical_low < (100 / 0.3) ** (1 / 8) * 1.0001
    text = write_report(result, tmp_path / "report", render=False).read_text()
    assert "GCL, twin continua" in text
