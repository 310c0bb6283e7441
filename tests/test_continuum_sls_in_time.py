"""A standard linear solid (Maxwell arms) learning in physical time in the continuum: the
held-step stress relaxation closed form, relaxation times against the mapped network, the
quasi-static limit is train() step for step, and the gap to it closes as the ratio -> 0."""

from __future__ import annotations

import math

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import CoupledLearning, ProspectiveConfiguration, stern_task
from continuum_vs_network.learning.physical_time import learn_in_time, network_relaxation_time
from continuum_vs_network.network.viscous import Viscosity

BULK = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}
K2, G2 = 0.5, 2.0  # arm stiffness and dashpot (the lattice's k = 1): arm time 4
SLS = Viscosity(drag=1.0, arm_stiffness=K2, arm_dashpot=G2)


def _sls(c: float) -> Viscosity:
    """Every damping coefficient times ``c`` (every time constant times ``c``)."""
    return Viscosity(drag=c, arm_stiffness=K2, arm_dashpot=c * G2)


@pytest.fixture(scope="module")
def lattice_task():
    net = cvn.triangular_lattice(7, 7)
    return net, stern_task(net, 2, 1, np.random.default_rng(4), source_std=0.1, target_std=0.1)


@pytest.fixture(scope="module")
def body_task(lattice_task):
    pytest.importorskip("skfem")
    from continuum_vs_network.continuum.learnable import learnable_body
    from continuum_vs_network.continuum.material_task import MaterialTask
    from continuum_vs_network.continuum.materials import lattice_lame
    from continuum_vs_network.continuum.mesh import network_mesh

    net, task = lattice_task
    body = learnable_body(network_mesh(net), lattice_lame(1.0))
    return body, MaterialTask.from_network(net, task, body)


def test_held_step_relaxes_the_arm_stress_with_the_closed_form(body_task):
    """The clamps stepped to their long-time equilibrium and held, arms relaxed at the old
    state: with arm moduli proportional to the body's (the lattice mapping, beta = k2 / k)
    the displacement stays at the elastic equilibrium of the long-time modulus at every
    step, and the arm energy relaxes as E_inf beta exp(-2 t / tau2), backward Euler's
    (1 + dt / tau2)^(-2 n) exactly, converging at first order."""
    from continuum_vs_network.continuum.damped_states import DampedStepper
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    body, task = body_task
    damping = lattice_damping(SLS)
    u_eq, arm_eq = DampedStepper(body, task, damping, math.inf).step(body, np.zeros(body.n_dofs))
    assert arm_eq is None  # at equilibrium the arms are relaxed: no state, no force
    e_inf = 0.5 * u_eq @ (body.stiffness() @ u_eq)
    beta, tau2 = K2 / 1.0, G2 / K2
    errors = []
    for m in (10, 20, 40):
        stepper = DampedStepper(body, task, damping, tau2 / m)
        ops = stepper.arm.operators
        u, arm = u_eq, np.zeros(ops.n_internal)
        for _ in range(m):
            u, arm = stepper.step(body, u, arm=arm)
            np.testing.assert_allclose(u, u_eq, atol=1e-12)
        r = ops.strain @ u - arm
        ratio = 0.5 * r @ (ops.stiffness @ r) / e_inf
        assert ratio == pytest.approx(beta * (1 + 1 / m) ** (-2 * m), rel=1e-9)
        errors.append(abs(ratio - beta * math.exp(-2.0)))
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(2.0, rel=0.1)


def test_sls_relaxation_times_of_body_and_network_agree(lattice_task, body_task):
    """After the source step the continuum with the mapped arms settles its target strains
    on the lattice's time (within 10 %, as with drag alone), and a slow arm (tau2 = 40) or
    a fast stiff one (tau2 = 0.2) changes that time by the same factor in both media
    (within 6 %): faster while the slow arm still stiffens, slower with the fast one. The
    lattice's sources are held by their end nodes here: with strain clamps (rods) its
    slowest mode carries ~5 % of this target's change against the body's ~0.1 %, and its
    target settles ~24x later (271 against 11), whatever the arms."""
    from continuum_vs_network.continuum.damped_states import body_relaxation_time
    from continuum_vs_network.continuum.viscoelastic import lattice_damping

    net, task = lattice_task
    times = {}
    for name, vis in (
        ("drag", Viscosity(drag=1.0)),
        ("slow", Viscosity(drag=1.0, arm_stiffness=K2, arm_dashpot=20.0)),
        ("fast", Viscosity(drag=1.0, arm_stiffness=1.0, arm_dashpot=0.2)),
    ):
        tb = body_relaxation_time(*body_task, lattice_damping(vis))
        tn = network_relaxation_time(net, task, vis, clamp="nodes")
        assert 0.9 < tb / tn < 1.1, (name, tb, tn)
        times[name] = (tb, tn)
    for name in ("slow", "fast"):
        fb = times[name][0] / times["drag"][0]
        fn = times[name][1] / times["drag"][1]
        assert fb == pytest.approx(fn, rel=0.06), (name, fb, fn)
    assert times["slow"][0] < 0.85 * times["drag"][0] < times["fast"][0]


RULES = [
    (ProspectiveConfiguration(0.4, **BULK), {}),
    (CoupledLearning(0.4, 0.1, **BULK), {"form": "twin"}),
]
IDS = ["gpc", "gcl_twin"]


@pytest.mark.parametrize(("rule", "opts"), RULES, ids=IDS)
def test_sls_learning_with_equilibrium_steps_is_train(body_task, rule, opts):
    """With arms, every step an equilibrium (quasistatic=True), or every step a backward
    Euler step 1e9 times longer than every time constant (the arms' eliminated stiffness
    ~ V / dt and drag / dt ~ 1e-9 of the elastic one): learning in time is train() step for
    step."""
    body, task = body_task
    steps = 4
    runs = [
        learn_in_time(body, task, rule, viscosity=SLS, duration=steps, dt=1.0, n_outputs=steps,
                      quasistatic=True, **opts),
        learn_in_time(body, task, rule, viscosity=_sls(1e-9), duration=steps, dt=1.0,
                      n_outputs=steps, **opts),
    ]  # fmt: skip
    h = cvn.train(body, task, rule, steps, progress=False)
    for run, tol in zip(runs, (1e-12, 1e-7)):
        np.testing.assert_allclose(run.error, h.error_initial[0], rtol=max(tol, 1e-8))
        np.testing.assert_allclose(run.rest_length[-1], h.final[0].eigenstrain, atol=tol)
    assert runs[0].error[-1] < runs[0].error[0]


@pytest.mark.parametrize(("rule", "opts"), RULES, ids=IDS)
def test_sls_learning_in_time_tends_to_the_quasi_static_result(body_task, rule, opts):
    """At a fixed learning step, the gap between the error histories of the SLS run and
    of its quasi-static limit (relative to the quasi-static drop) shrinks as every damping
    coefficient (drag and arm dashpot, so every relaxation time) goes to 0 at fixed alpha."""
    body, task = body_task
    dt_learn, T = 0.25, 2.5
    qs = learn_in_time(body, task, rule, viscosity=SLS, duration=T, dt=dt_learn, n_outputs=5,
                       quasistatic=True, **opts)  # fmt: skip
    drop = qs.error[0] - qs.error[-1]
    assert drop > 0
    gaps = []
    for c in (1.0, 1 / 16, 1 / 256):
        m = round(2 / c)
        run = learn_in_time(body, task, rule, viscosity=_sls(c), duration=T, dt=dt_learn / m,
                            learn_every=m, n_outputs=5, **opts)  # fmt: skip
        np.testing.assert_allclose(run.times, qs.times)
        gaps.append(float(np.max(np.abs(run.error - qs.error)) / drop))
    assert gaps[0] > 2.0 * gaps[1] > 4.0 * gaps[2], gaps
    assert gaps[-1] < 0.02, gaps


def test_sls_copies_carry_their_own_arms(body_task):
    """The twin copies (free and nudged) hold different internal strains: the nudged copy's
    targets are held elsewhere, so its arms relax towards another state."""
    from continuum_vs_network.learning.time_media import BodyTime

    body, task = body_task
    rule = CoupledLearning(0.4, 0.1, **BULK)
    media = BodyTime(body, task, rule, SLS, 0.5, False, 1e-10)
    free = media.copy(body, None)
    nudged = media.copy(body, task.target_strain, start=free)
    for _ in range(3):
        media.advance(body, free, None)
        media.advance(body, nudged, task.target_strain)
    assert free.arm is not nudged.arm
    assert np.max(np.abs(free.arm - nudged.arm)) > 1e-4 * np.max(np.abs(free.arm))


def test_bad_arm_input_is_named(body_task):
    from continuum_vs_network.continuum.damped_states import DampedStepper
    from continuum_vs_network.continuum.viscoelastic import Damping, lattice_damping

    body, task = body_task
    stepper = DampedStepper(body, task, lattice_damping(SLS), 0.1)
    with pytest.raises(ValueError, match="arm must be"):
        stepper.step(body, np.zeros(body.n_dofs))
    with pytest.raises(ValueError, match="arm must be"):
        stepper.step(body, np.zeros(body.n_dofs), arm=np.zeros(3))
    with pytest.raises(ValueError, match=r"damping: .*Rayleigh"):
        DampedStepper(body, task, Damping(drag=1.0, rayleigh_mass=1.0), 0.1)
    with pytest.raises(ValueError, match="dt must be > 0"):
        DampedStepper(body, task, lattice_damping(SLS), float("nan"))
    with pytest.raises(ValueError, match="dt must be finite"):
        learn_in_time(body, task, ProspectiveConfiguration(0.4, **BULK), viscosity=SLS,
                      duration=1.0, dt=-1.0)  # fmt: skip


def test_stiff_fast_arm_is_stable_and_acts_as_its_dashpot(body_task):
    """An arm 1e7 times faster than the step (k2 = 1e8, gamma2 = 0.3, dt = 0.05): backward
    Euler stays stable and the arm acts as its dashpot alone (a spring dashpot gamma2, the
    Kelvin-Voigt network), so learning in time matches the Kelvin-Voigt run (relative
    error of order tau2 / dt)."""
    body, task = body_task
    rule = CoupledLearning(0.4, 0.1, **BULK)
    kw = {"duration": 2.0, "dt": 0.05, "n_outputs": 8, "form": "twin"}
    arm = learn_in_time(body, task, rule, viscosity=Viscosity(drag=1.0, arm_stiffness=1e8,
                        arm_dashpot=0.3), **kw)  # fmt: skip
    kv = learn_in_time(body, task, rule, viscosity=Viscosity(drag=1.0, dashpot=0.3), **kw)
    drag = learn_in_time(body, task, rule, viscosity=Viscosity(drag=1.0), **kw)
    np.testing.assert_allclose(arm.error, kv.error, rtol=1e-5)
    np.testing.assert_allclose(arm.positions, kv.positions, atol=1e-7)
    assert np.max(np.abs(drag.error - kv.error)) > 1e-3 * kv.error[0]  # the dashpot matters
    assert arm.factorisations == 1  # eigenstrain learning: one factorisation per run
