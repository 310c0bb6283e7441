"""Learning concurrent with the dynamics: closed forms, the quasi-static limit, export and
the physical_time scene."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from physical_time_scenes import tiny_physical_time

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    ExactGradient,
    ProspectiveConfiguration,
    stern_task,
)
from continuum_vs_network.learning.physical_time import (
    learn_in_time,
    network_relaxation_time,
    settling_time,
)
from continuum_vs_network.network.dynamics import simulate_viscous
from continuum_vs_network.network.viscous import Viscosity
from continuum_vs_network.scenes.results import from_stored
from continuum_vs_network.scenes.results.physical_time import TimeRunResult, TimeTaskResult
from continuum_vs_network.scenes.units_time import critical_bracket, crossing_time, rebound

BULK = {"strain_reference": "initial", "learn_sources": False, "learn_targets": False}


@pytest.fixture(scope="module")
def small():
    net = cvn.triangular_lattice(5, 5)
    task = stern_task(net, 1, 1, np.random.default_rng(3))
    return net, task


@pytest.mark.parametrize("clamp, rtol", [("nodes", 1e-12), ("strain", 1e-7)])
def test_gpc_target_rest_length_relaxes_exponentially_onto_its_clamp(small, clamp, rtol):
    """A clamped spring keeps its length r, so L' = alpha k (r - L) gives
    L(t) = r + (L0 - r) exp(-alpha k t) exactly, whatever the dynamics of the rest: to
    rounding with held end nodes, to the rod's strain error (~ 1e-8, ROD_FACTOR = 1e6 and
    the solver's floored tolerance) with the default strain clamp."""
    net, task = small
    alpha, T = 0.3, 4.0
    rule = ProspectiveConfiguration(alpha, learn_targets=True)
    h = learn_in_time(
        net, task, rule, viscosity=Viscosity(drag=1.0), duration=T, dt=0.1, learn_every=3,
        clamp=clamp,
    )  # fmt: skip
    j = int(task.targets[0])
    r = float(task.desired_lengths(net, "initial")[0])
    L0 = net.rest_length[j]
    expected = r + (L0 - r) * np.exp(-alpha * net.stiffness[j] * h.times)
    # the rest length is updated every dt_learn = 0.3: compare at those times
    on_grid = np.isclose(np.round(h.times / h.dt_learn) * h.dt_learn, h.times)
    np.testing.assert_allclose(h.rest_length[on_grid, j], expected[on_grid], rtol=rtol)
    assert h.dt_learn == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("rule", "form"),
    [
        (ProspectiveConfiguration(0.2, **BULK), "continuous"),
        (CoupledLearning(0.2, 0.1, **BULK), "twin"),
    ],
    ids=["gpc", "gcl_twin"],
)
def test_learning_in_time_tends_to_the_quasi_static_limit(small, rule, form):
    """Same learning steps, drag c -> 0 (relaxation time ~ c, physical step ~ c): the
    learned rest lengths approach the quasi-static run, the gap shrinking ~ the ratio of
    learning rate to relaxation rate. With the default strain clamp (sources and nudged
    targets held by their lengths, as the continuum's) the lattice relaxes ~ 3x slower
    than with held end nodes (tau 143 against 50 at c = 1), so the approach needs one
    drag more (c = 1/64) and shrinks less evenly (each gap at least 1.5x the next)."""
    net, task = small
    dt_learn, T = 0.25, 3.0
    qs = learn_in_time(
        net,
        task,
        rule,
        viscosity=Viscosity(drag=1.0),
        duration=T,
        dt=dt_learn,
        form=form,
        quasistatic=True,
        n_outputs=5,
    )
    gaps = []
    for c in (1.0, 0.25, 1 / 16, 1 / 64):
        m = round(4 / c)  # physical steps per learning step: dt ~ c, dt_learn fixed
        run = learn_in_time(
            net,
            task,
            rule,
            viscosity=Viscosity(drag=c),
            duration=T,
            dt=dt_learn / m,
            learn_every=m,
            form=form,
            n_outputs=5,
        )
        assert run.dt_learn == pytest.approx(dt_learn)
        change = np.max(np.abs(qs.rest_length[-1] - net.rest_length))
        gaps.append(np.max(np.abs(run.rest_length[-1] - qs.rest_length[-1])) / change)
    assert all(a > 1.5 * b for a, b in itertools.pairwise(gaps)), gaps
    assert gaps[-1] < 0.05, gaps


def test_gcl_phases_with_long_phases_learn_as_their_quasi_static_limit(small):
    net, task = small
    vis = Viscosity(drag=0.2)
    tau = network_relaxation_time(net, task, vis)  # the target strains settled to 1 %
    rule = CoupledLearning(0.1 / tau, 0.1, **BULK)  # alpha k dt_learn = 0.6 (6 tau cycles)
    kw = {"duration": 4 * 2 * 3 * tau + tau, "form": "phases", "phase": 3 * tau, "n_outputs": 4}
    run = learn_in_time(net, task, rule, viscosity=vis, dt=tau / 4, **kw)
    qs = learn_in_time(net, task, rule, viscosity=vis, dt=tau / 4, quasistatic=True, **kw)
    change = np.max(np.abs(qs.rest_length[-1] - net.rest_length))
    assert change > 0
    assert np.max(np.abs(run.rest_length[-1] - qs.rest_length[-1])) < 1e-2 * change
    assert run.error[-1] < run.error[0]


def test_relaxation_time_grows_with_drag(small):
    net, task = small
    for measure in ("target", "force"):
        t1 = network_relaxation_time(net, task, Viscosity(drag=1.0), measure=measure)
        t2 = network_relaxation_time(net, task, Viscosity(drag=2.0), measure=measure)
        assert t2 == pytest.approx(2 * t1, rel=0.02)  # overdamped: time proportional to drag


def test_settling_time_of_an_exponential_and_of_an_overshoot():
    """exp(-t / 3) settles to 1 % at 3 ln 100; a damped oscillation counts its last exit
    from the band, not its first entry."""
    t = np.linspace(0.0, 40.0, 40001)
    v = np.exp(-t / 3.0)[:, None] * np.array([[3.0, 4.0]])  # total change 5 toward 0
    tau = settling_time(t, v, [3.0, 4.0], [0.0, 0.0], 0.01)
    assert tau == pytest.approx(3.0 * np.log(100.0), rel=1e-5)
    w = np.exp(-t / 3.0) * np.cos(t)
    last = settling_time(t, w[:, None], [1.0], [0.0], 0.01)
    first = t[np.argmax(np.abs(w) <= 0.01)]
    assert last > first + 1.0 and np.all(np.abs(w[t > last]) <= 0.01 + 1e-12)
    assert abs(w[np.searchsorted(t, last) - 1]) > 0.01  # the last frame outside
    assert settling_time(t, v, [0.0, 0.0], [0.0, 0.0], 0.01) == 0.0
    assert settling_time(t[:100], v[:100], [3.0, 4.0], [0.0, 0.0], 0.01) == np.inf


def test_target_relaxation_time_is_when_the_targets_settle(small):
    """An independent finer run (400 steps per tau): at 0.9 tau the target strains are
    still more than 1 % of their change away from the clamped equilibrium, after 1.1 tau
    never again; the net force settles sooner (local modes dominate it)."""
    from continuum_vs_network.network.strain_clamp import rod_clamped

    net, task = small
    vis = Viscosity(drag=1.0)
    tau = network_relaxation_time(net, task, vis)
    clamps = task.source_clamps(net, "initial")
    rest = task.target_rest(net, "initial")
    rods = rod_clamped(net, clamps)  # the default clamp: the sources as rods, no node held
    tol = 100 * np.finfo(float).eps * 1e6 * net.force_scale / rods.force_scale
    run = simulate_viscous(rods, vis, dt=tau / 400, t_end=4 * tau, pinned=task.pinned, tol=tol)
    s = np.array([net.lengths(x)[task.targets] / rest for x in run.positions])
    end = simulate_viscous(rods, vis, dt=1e12, t_end=1e12, pinned=task.pinned, tol=tol).positions[
        -1
    ]
    s_end = net.lengths(end)[task.targets] / rest
    total = np.linalg.norm(s_end - net.lengths(net.positions)[task.targets] / rest)
    d = np.linalg.norm(s - s_end, axis=1) / total
    assert d[np.searchsorted(run.times, 0.9 * tau)] > 0.01
    assert np.all(d[run.times >= 1.1 * tau] < 0.01)
    assert tau > network_relaxation_time(net, task, vis, measure="force")


def test_bad_input_is_named(small):
    net, task = small
    vis = Viscosity()
    with pytest.raises(ValueError, match="quasi-static"):
        learn_in_time(net, task, ExactGradient(0.1), viscosity=vis, duration=1.0, dt=0.1)
    with pytest.raises(ValueError, match="form"):
        learn_in_time(
            net, task, ProspectiveConfiguration(0.1), viscosity=vis, duration=1, dt=0.1, form="twin"
        )
    with pytest.raises(ValueError, match="phase"):
        learn_in_time(
            net, task, CoupledLearning(0.1, 0.1), viscosity=vis, duration=1, dt=0.1, form="phases"
        )
    with pytest.raises(ValueError, match="explicit learning step"):
        learn_in_time(net, task, CoupledLearning(5.0, 0.1), viscosity=vis, duration=1, dt=1.0)


def test_study_measures():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert crossing_time(t, np.array([1.0, 0.6, 0.2, 0.1]), 0.4) == pytest.approx(1.5)
    assert crossing_time(t, np.array([1.0, 0.9, 0.8, 0.7]), 0.5) == np.inf
    assert rebound(np.array([1.0, 0.5, 0.7, 0.2, 0.3])) == pytest.approx(1.5)
    assert rebound(np.array([1.0, 0.1, 1e-5, 2e-3, 1e-3])) == pytest.approx(200)  # overshoot
    assert rebound(np.array([1.0, 1e-8, 1e-7])) == 1.0  # below the floor
    # the running minimum is floored at 1e-6: 3.5e-9 -> 1.16e-6 is no rebound of 335
    assert rebound(np.array([1.0, 3.5e-9, 1.16e-6])) == pytest.approx(1.16)
    # a rebound the quasi-static run shares (same times) is the learning step's: not past
    e = np.array([1.0, 0.1, 0.01, 0.05, 0.2, 0.1])
    qs = np.array([1.0, 0.1, 0.005, 0.06, 0.3, 0.1])
    assert rebound(e) == pytest.approx(20.0)
    assert rebound(e, qs) == 1.0
    # one that climbs above the quasi-static error is the dynamics'
    qs_calm = np.array([1.0, 0.1, 0.005, 0.003, 0.002, 0.001])
    assert rebound(e, qs_calm) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="reference"):
        rebound(e, qs[:-1])
    assert rebound(np.array([1.0, 0.5, 0.25])) == 1.0
    ratios = [1.0, 10.0, 100.0, 1000.0]
    assert critical_bracket(ratios, [False] * 4) == (1000.0, np.inf, 0)  # none past
    assert critical_bracket(ratios, [True] * 4) == (0.0, 1.0, 0)  # the smallest already past
    assert critical_bracket(ratios, [False, False, True, True]) == (10.0, 100.0, 0)
    # non-monotone: 10 past but 100 not; the bracket is above the last ratio not past
    assert critical_bracket(ratios, [False, True, False, True]) == (100.0, 1000.0, 1)
    # order of the ratios run does not matter (bisection points are appended)
    assert critical_bracket([1000.0, 1.0, 31.6, 10.0], [True, False, True, False]) == (
        10.0,
        31.6,
        0,
    )
    with pytest.raises(ValueError, match="one length"):
        critical_bracket(ratios, [True])


def test_time_history_series_has_one_frame_per_output(small, tmp_path):
    pytest.importorskip("meshio")
    from continuum_vs_network.io.export import read_series_index, time_history_series

    net, task = small
    h = learn_in_time(
        net,
        task,
        ProspectiveConfiguration(0.2, **BULK),
        viscosity=Viscosity(),
        duration=2.0,
        dt=0.1,
        n_outputs=5,
    )
    index = time_history_series(
        net,
        h.times,
        h.positions,
        h.rest_length,
        h.stiffness,
        tmp_path,
        "run",
        sources=task.sources,
        targets=task.targets,
    )
    frames = read_series_index(index)
    assert [t for t, _ in frames] == pytest.approx(h.times.tolist())
    import meshio

    last = meshio.read(frames[-1][1])
    np.testing.assert_allclose(last.cell_data["rest_length"][0], h.rest_length[-1])
    np.testing.assert_allclose(
        last.point_data["displacement"][:, :2], h.positions[-1] - net.positions
    )
    with pytest.raises(ValueError, match="positions"):
        time_history_series(
            net, h.times, h.positions[:-1], h.rest_length, h.stiffness, tmp_path, "bad"
        )


def test_physical_time_scene_runs_and_judges(tmp_path):
    pytest.importorskip("matplotlib")
    from continuum_vs_network.report.writer import write_report
    from continuum_vs_network.scenes.runner import run_scene

    scene = tiny_physical_time(
        sizes=[5, 6], n_sources=1, rules=["gpc"], ratios=[0.3, 3.0], relaxation_times=1.0,
        learning_times=3.0, draws=[2, 1],
    )  # fmt: skip
    result = run_scene(scene, tmp_path / "results")
    units = result.select("physical_time/")
    assert sorted(units) == [
        "physical_time/n5/d0/gpc",
        "physical_time/n5/d0/task",
        "physical_time/n5/d1/gpc",
        "physical_time/n5/d1/task",
        "physical_time/n6/d0/gpc",
        "physical_time/n6/d0/task",
    ]
    runs = {k: from_stored(u, TimeRunResult) for k, u in units.items() if not k.endswith("/task")}
    for u in runs.values():
        assert u.tau > 0
        for r in u.runs:
            # at the smallest ratio the run is quasi-static to a few percent
            if r["ratio"] == 0.3:
                assert abs(r["error_at_qs_end"] - r["error_qs_end"]) < 0.05
    # two draws of one size: two tasks on the same lattice, each with its own tau
    d0, d1 = (from_stored(units[f"physical_time/n5/d{d}/task"], TimeTaskResult) for d in (0, 1))
    assert not (np.array_equal(d0.sources, d1.sources) and np.array_equal(d0.targets, d1.targets))
    assert runs["physical_time/n5/d1/gpc"].tau == d1.network["tau"] > 0
    path = write_report(result, tmp_path / "report", render=False)
    text = path.read_text()
    assert "N = 25: 2, N = 36: 1" in text and "Fewer draws at N = 36" in text
    assert "speed of learning cannot be addressed" in text
    assert "physical_time_speed" in text
    # the oscillation rule and the trend rule are stated; two sizes give no robust trend
    assert "above the quasi-static" in text and "QS rebound" in text
    assert "no robust trend" in text


def test_draws_key_is_checked_against_the_sizes():
    import tomllib

    from continuum_vs_network.scenes.schema import SceneError, parse_scene

    base = """
name = "pt"
description = "tiny"
kind = "physical_time"
[network]
builder = "triangular"
sizes = [5, 6]
[task]
kind = "stern"
[physical_time]
"""
    scene = parse_scene(tomllib.loads(base + "draws = [2, 1]\n"), "pt.toml")
    from continuum_vs_network.scenes.units_time import draws_per_size, plan_time

    assert draws_per_size(scene) == [2, 1]
    keys = [u.key for u in plan_time(scene)]
    assert keys.count("physical_time/n5/d1/task") == 1 and "physical_time/n6/d1/task" not in keys
    assert draws_per_size(parse_scene(tomllib.loads(base + "draws = [3]\n"), "pt.toml")) == [3, 3]
    with pytest.raises(SceneError, match=r"draws.*one per size"):
        parse_scene(tomllib.loads(base + "draws = [1, 2, 3]\n"), "pt.toml")
    with pytest.raises(SceneError, match="draws"):
        parse_scene(tomllib.loads(base + "draws = [0]\n"), "pt.toml")


@pytest.mark.parametrize("form", ["twin", "phases"])
def test_quasi_static_run_depends_on_alpha_only_through_the_learning_step(small, form):
    # the study shares one quasi-static run between ratios with the same alpha dt_learn:
    # step for step (times in units of 1 / alpha) its errors must not depend on alpha
    net, task = small
    runs = []
    for alpha in (0.05, 0.5):
        dt = 0.1 / alpha
        opts = {"phase": dt} if form == "phases" else {}
        h = learn_in_time(
            net, task, CoupledLearning(alpha, 0.1, **BULK), viscosity=Viscosity(),
            duration=4.0 / alpha, dt=dt, n_outputs=40, quasistatic=True, form=form, **opts,
        )  # fmt: skip
        runs.append(h)
    a, b = runs
    np.testing.assert_allclose(a.times * 0.05, b.times * 0.5)
    np.testing.assert_allclose(a.error, b.error, rtol=1e-6, atol=1e-12)
    assert a.error[-1] < 0.5 * a.error[0]  # it learned
