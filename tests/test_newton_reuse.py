"""The sparse Newton's reuse step: projected CG preconditioned by an earlier factorisation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from pulled_lattices import pulled_apart

from continuum_vs_network.linalg import spd as spd_module
from continuum_vs_network.linalg.kkt import Factor, factor_spd, range_space, range_space_solve
from continuum_vs_network.network import hessian_ladder as ladder
from continuum_vs_network.network import newton as nw
from continuum_vs_network.network import reuse
from continuum_vs_network.network.builders import triangular_lattice
from continuum_vs_network.network.checks import lowest_curvature
from continuum_vs_network.network.constraints import Problem
from continuum_vs_network.network.lagrangian import lagrangian_blocks, pattern_for
from continuum_vs_network.network.stopping import Trace


def _problem_and_two_points():
    rng = np.random.default_rng(4)
    net = triangular_lattice(18, 18, noise=0.1, rng=rng)
    net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
    clamped = {40: float(net.clamp_length(40, 0.3)), 200: float(net.clamp_length(200, -0.2))}
    problem = Problem.build(net, clamped=clamped)
    x0 = problem.start(net.positions)
    x1 = x0 + 0.02 * rng.standard_normal(x0.shape) * problem.free  # a later Newton iterate
    return problem, x0, x1


def _w(problem, pattern, x, lam):
    return pattern.assemble(
        lagrangian_blocks(problem, x, lam, float(np.max(problem.net.stiffness)))
    )


def test_projected_cg_step_equals_the_exact_kkt_step():
    """Preconditioned by W at another point, the step solves the current KKT system: it
    agrees with a fresh factorisation's range-space step and meets A step = -viol."""
    problem, x0, x1 = _problem_and_two_points()
    net = problem.net
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    coords = pattern.coords
    lam = np.array([0.3, -0.2])
    old = factor_spd(_w(problem, pattern, x0, lam), ordered=pattern.ordered)
    W = _w(problem, pattern, x1, lam)
    grad = problem.gradient(x1).ravel()[coords]
    A = problem.clamp_jacobian(x1, coords)
    viol = problem.clamp_violation(x1)
    step, mult = reuse.projected_pcg(W, old, grad, A, viol, rtol=1e-10, max_iter=200)
    exact, exact_mult = range_space(factor_spd(W, ordered=pattern.ordered), A).solve(-grad, -viol)
    np.testing.assert_allclose(A @ step, -viol, atol=1e-12)
    np.testing.assert_allclose(step, exact, atol=1e-8 * np.abs(exact).max())
    np.testing.assert_allclose(mult, exact_mult, rtol=1e-7)


def test_a_float32_factors_newton_step_is_refined_to_the_forcing_tolerance(monkeypatch):
    """A rough banded factor is float32 (``approximate``): on a lattice of stiffness over
    four decades its direct KKT step misses the force balance by more than 1e-6 of the
    force, while Newton's step from it (projected CG on the factorised matrix, preconditioned
    by it) meets the forcing tolerance 1e-8 and the clamps to round-off. (Float32 from
    any size here, ``ROUGH_BANDED_MIN`` lowered.)"""
    monkeypatch.setattr(spd_module, "ROUGH_BANDED_MIN", 0)
    rng = np.random.default_rng(3)
    net = triangular_lattice(18, 18, noise=0.1, rng=rng)
    net = net.with_stiffness(10.0 ** rng.uniform(-2, 2, net.n_springs))
    clamped = {40: float(net.clamp_length(40, 0.3)), 200: float(net.clamp_length(200, -0.2))}
    problem = Problem.build(net, clamped=clamped)
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    x = net.positions  # stress-free: W > 0
    coords = pattern.coords
    W = _w(problem, pattern, x, np.zeros(2))
    rough = factor_spd(W, ordered=pattern.ordered, rough=True)
    assert rough.approximate and not factor_spd(W, ordered=pattern.ordered).approximate
    grad = rng.standard_normal(W.shape[0])  # any force: the step is linear in it
    A = problem.clamp_jacobian(x, coords)
    viol = problem.clamp_violation(x)
    force = np.linalg.norm(grad)

    def imbalance(step, lam):
        return np.linalg.norm(grad + W @ step + A.T @ lam) / force

    direct = nw._kkt_step(rough, grad, A, viol, 2)
    step, lam = nw._fresh_step(rough, W, grad, A, viol, 1e-8, True)
    assert imbalance(*direct) > 1e-6
    assert imbalance(step, lam) <= 1e-8
    np.testing.assert_allclose(A @ step, -viol, atol=1e-12 * np.abs(viol).max())


def test_a_banded_factor_preconditions_in_float32_and_the_step_stays_exact(monkeypatch):
    """The banded Cholesky's preconditioner is the factor rounded to float32: it differs
    from the float64 solve by 1e-9..1e-5 relative (so it is rounded, and close); projected
    CG with it still meets A step = -viol to round-off and reaches the exact KKT step to
    1e-10 (it stalled at 2e-9 while the Schur complement was symmetrised: A Z is not
    symmetric to round-off with a float32 Z). (Float32 from any size here,
    ``ROUGH_BANDED_MIN`` lowered.)"""
    monkeypatch.setattr(spd_module, "ROUGH_BANDED_MIN", 0)
    problem, x0, x1 = _problem_and_two_points()
    net = problem.net
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    assert pattern.band_positions is not None  # band order: the banded Cholesky is used
    coords = pattern.coords
    lam = np.array([0.3, -0.2])
    old = factor_spd(_w(problem, pattern, x0, lam), ordered=pattern.ordered)
    b = np.random.default_rng(0).standard_normal(old.n)
    exact_solve = old.solve(b)
    gap = np.linalg.norm(old.precondition(b) - exact_solve) / np.linalg.norm(exact_solve)
    assert 1e-9 < gap < 1e-5
    W = _w(problem, pattern, x1, lam)
    grad = problem.gradient(x1).ravel()[coords]
    A = problem.clamp_jacobian(x1, coords)
    viol = problem.clamp_violation(x1)
    step, _ = reuse.projected_pcg(W, old, grad, A, viol, rtol=1e-12, max_iter=200)
    exact, _ = range_space(factor_spd(W, ordered=pattern.ordered), A).solve(-grad, -viol)
    np.testing.assert_allclose(A @ step, -viol, atol=1e-13)
    np.testing.assert_allclose(step, exact, rtol=0, atol=1e-10 * np.abs(exact).max())


def test_projected_cg_refuses_negative_curvature_and_a_short_budget():
    problem, x0, x1 = _problem_and_two_points()
    net = problem.net
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    coords = pattern.coords
    lam = np.zeros(2)
    old = factor_spd(_w(problem, pattern, x0, lam), ordered=pattern.ordered)
    W = _w(problem, pattern, x1, lam)
    grad = problem.gradient(x1).ravel()[coords]
    A = problem.clamp_jacobian(x1, coords)
    viol = problem.clamp_violation(x1)
    with pytest.raises(reuse.SolveFailed, match="no convergence"):
        reuse.projected_pcg(W, old, grad, A, viol, rtol=1e-14, max_iter=1)
    negative = W - 2.0 * float(W.diagonal().max()) * sp.identity(W.shape[0], format="csr")
    with pytest.raises(reuse.NegativeCurvature, match="negative curvature") as met:
        reuse.projected_pcg(negative, old, grad, A, viol, rtol=1e-10, max_iter=50)
    d = met.value.direction  # a witness: negative curvature, in the clamps' null space
    assert d @ (negative @ d) < 0.0
    assert np.linalg.norm(A @ d) <= 1e-10 * np.linalg.norm(A.toarray()) * np.linalg.norm(d)


def test_cg_is_given_up_only_when_its_rate_cannot_reach_the_tolerance_in_budget():
    """After 4 iterations: no reduction from the start -> hopeless; 13.4 -> 9.46 (the slow
    start of a run measured at N = 1e4 that then converged in 18) -> keep going; a rate
    that needs more than 3x the budget -> hopeless; before 4 iterations -> never."""
    hopeless = reuse._hopeless
    assert hopeless(37.9, 88.8, 1.0, 4, 42)
    assert not hopeless(13.4, 9.46, 1.0, 4, 42)
    assert hopeless(13.4, 13.0, 1.0, 4, 42)  # rate 0.0076 per iteration: 340 needed
    assert not hopeless(37.9, 187.0, 1.0, 3, 42)


def test_cg_without_clamps_gives_up_a_hopeless_solve_early():
    """Plain CG (no clamps) stops as soon as its rate cannot reach the tolerance, not at
    the end of its budget: a diagonal of condition 1e8 with an identity preconditioner
    cannot get from 1 to 1e-12 in 3 x 40 iterations; a good preconditioner solves it."""
    W = sp.diags(np.logspace(0.0, 8.0, 400), format="csr")
    b = np.random.default_rng(3).normal(size=400)
    products = []

    class Counted:  # W, counting its products
        shape = W.shape

        def __matmul__(self, v):
            products.append(1)
            return W @ v

    identity = Factor(lambda v: np.array(v, dtype=float), 400)
    with pytest.raises(reuse.SolveFailed, match="no convergence"):
        reuse.pcg(Counted(), identity, rtol=1e-12, max_iter=40).solve(b)
    assert 5 <= len(products) <= 15  # the initial residual, then 4-14 of the 40 iterations
    near = Factor(lambda v: v / (1.01 * W.diagonal()), 400)
    x = reuse.pcg(W, near, rtol=1e-12, max_iter=40).solve(b)
    assert np.linalg.norm(W @ x - b) <= 1e-12 * np.linalg.norm(b)


def test_batched_range_space_solve_equals_two_solves():
    problem, x0, _ = _problem_and_two_points()
    net = problem.net
    pattern = pattern_for(net.springs, net.n_nodes, problem.free, net.positions)
    coords = pattern.coords
    factor = factor_spd(_w(problem, pattern, x0, np.zeros(2)), ordered=pattern.ordered)
    A = problem.clamp_jacobian(x0, coords)
    b, c = problem.gradient(x0).ravel()[coords], np.array([0.01, -0.02])
    _, (x, y) = range_space_solve(factor, A, b, c)
    x_ref, y_ref = range_space(factor, A).solve(b, c)
    np.testing.assert_allclose(A @ x, c, atol=1e-13)
    np.testing.assert_allclose(x, x_ref, rtol=1e-10, atol=1e-12 * np.abs(x_ref).max())
    np.testing.assert_allclose(y, y_ref, rtol=1e-10)


def test_band_order_and_banded_cholesky_follow_superlus_path(monkeypatch):
    """A prestressed lattice pulled to strain 2 (indefinite Hessians, shifts estimated
    from directions of negative curvature) relaxes with the banded Cholesky in band order
    as with SuperLU in nested-dissection order: the same equilibrium to round-off, in as
    many iterations give or take one (the directions conjugate gradients meet, and the
    shifts estimated from them, depend on the preconditioner: 9 and 8 here)."""
    import continuum_vs_network as cvn
    from continuum_vs_network.linalg import spd
    from continuum_vs_network.network import lagrangian

    def build():  # a new springs array each time: a pattern of its own
        rng = np.random.default_rng(0)
        net = triangular_lattice(32, 32, noise=0.1, rng=rng)
        return net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))

    net = build()
    pattern = pattern_for(net.springs, net.n_nodes, ~cvn.default_pins(net), net.positions)
    assert pattern.band_positions is not None  # the band order is in use at this size
    clamp = {1457: float(net.clamp_length(1457, 2.0))}  # the spring nearest the centre
    banded = cvn.relax(net, clamped=clamp)
    monkeypatch.setattr(spd, "banded_pays", lambda n, width: False)
    monkeypatch.setattr(lagrangian, "banded_pays", lambda n, width: False)
    net = build()
    superlu = cvn.relax(net, clamped=clamp)
    assert abs(banded.iterations - superlu.iterations) <= 1
    assert min(banded.iterations, superlu.iterations) > 5
    np.testing.assert_allclose(banded.positions, superlu.positions, atol=1e-9)


def test_the_newton_loop_keeps_one_factorisation_alive(superlu_lifetimes):
    """Each SuperLU factorisation of a relax is made after the one before it is released
    (at 1e6 nodes one takes 3-5 GB): a lattice pulled to strain 2 refactorises often."""
    import continuum_vs_network as cvn

    rng = np.random.default_rng(0)
    net = triangular_lattice(24, 24, noise=0.1, rng=rng)
    net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
    eq = cvn.relax(net, clamped={700: float(net.clamp_length(700, 2.0))})
    assert eq.converged and superlu_lifetimes.made > 3
    assert superlu_lifetimes.most == 1


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_start_that_needs_a_shift_ends_certified_by_the_loops_own_factorisation(
    seed, monkeypatch
):
    """A prestressed 20x20 lattice pulled to strain 5 starts indefinite (Levenberg shifts);
    once the shift has decayed to 0 the exact Hessian is factorised in the loop, so Newton
    returns a certified minimum (relax then needs no second-order factorisation of its own;
    before, these runs ended on a reused shifted factorisation, uncertified)."""
    rng = np.random.default_rng(seed)
    net = triangular_lattice(20, 20, noise=0.1, rng=rng)
    net = net.with_rest_length(net.rest_length * rng.uniform(0.9, 1.1, net.n_springs))
    mid = net.positions[net.springs].mean(axis=1)
    c = int(np.argmin(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1)))
    problem = Problem.build(net, clamped={c: float(net.clamp_length(c, 5.0))})
    stop = problem.stop_rule(1e-10, max_iter=200, max_seconds=60.0)
    shifts = []
    factorise = nw.factor_positive_model

    def recorded(*args, **kwargs):
        out = factorise(*args, **kwargs)
        shifts.append(out.shift)
        return out

    monkeypatch.setattr(nw, "factor_positive_model", recorded)
    outcome = nw.newton(problem, problem.start(net.positions), stop, Trace())
    assert outcome.converged and outcome.certified
    assert shifts[0] > 0.0 and shifts[-1] == 0.0
    assert lowest_curvature(problem, outcome.x) >= 0.0  # the independent check agrees


@pytest.mark.parametrize(("clamps", "seed"), [(1, 1), (1, 2), (2, 0), (2, 4)])
def test_no_factorisation_is_tried_that_a_known_direction_proves_indefinite(
    clamps, seed, monkeypatch
):
    """When conjugate gradients meet negative curvature along ``d``, Newton does not
    factorise a matrix ``M`` with ``d^T M d <= 0`` (the exact Hessian, or it with a larger
    augmentation: ``rho A^T A`` adds nothing along ``d``, ``A d = 0``): such a factorisation
    must fail. Before, the first one after CG's failure was the exact Hessian itself (1.7 s
    of 9.4 s at 1e5 nodes). Lattices of 24 x 24 pulled to strain 2 meet it."""
    import continuum_vs_network as cvn

    rng = np.random.default_rng(seed)
    net = triangular_lattice(24, 24, noise=0.1, rng=rng)
    if clamps == 2:
        net = net.with_stiffness(rng.uniform(0.5, 50, net.n_springs))
    mid = net.positions[net.springs].mean(axis=1)
    order = np.argsort(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1))
    clamped = {int(order[0]): float(net.clamp_length(int(order[0]), 2.0))}
    if clamps == 2:
        second = int(order[len(order) // 8])
        clamped[second] = float(net.clamp_length(second, -0.5))
    witness: list = []  # the direction of the last CG failure, until a factor is made
    curvatures: list[float] = []
    pcg, factor_spd, factor_or_curvature = (
        nw.projected_pcg,
        nw.factor_spd,
        ladder._factor_or_curvature,
    )

    def spy_pcg(*args, **kwargs):
        witness.clear()
        try:
            return pcg(*args, **kwargs)
        except reuse.NegativeCurvature as negative:
            witness.append(negative.direction)
            raise

    def checked(M):
        if witness:
            curvatures.append(float(witness[0] @ (M @ witness[0])) / float(witness[0] @ witness[0]))

    def spy_factor(M, **kwargs):
        checked(M)
        out = factor_spd(M, **kwargs)
        if out is not None:
            witness.clear()
        return out

    def spy_factor_or_curvature(M, pattern, sparse_solver="auto"):
        checked(M)
        return factor_or_curvature(M, pattern, sparse_solver)

    monkeypatch.setattr(nw, "projected_pcg", spy_pcg)
    monkeypatch.setattr(nw, "factor_spd", spy_factor)  # the clamp predictor's
    monkeypatch.setattr(ladder, "factor_spd", spy_factor)  # the ladder's
    monkeypatch.setattr(ladder, "_factor_or_curvature", spy_factor_or_curvature)
    eq = cvn.relax(net, clamped=clamped)
    assert eq.converged
    assert curvatures, "CG never met negative curvature: the case does not test the rule"
    assert min(curvatures) > 0.0


@pytest.mark.parametrize(("side", "strain"), [(50, 1.0), (64, 1.0)])
def test_the_end_game_makes_one_factorisation(side, strain, monkeypatch):
    """Below ``_FRESH_NEAR tol`` a fresh factorisation is made only when its step is
    expected to move little enough to certify the minimum (``_CERTIFY_MOVE``). On
    bench_relax's lattices (k in U(0.5, 50), clamps at ``strain`` and ``-strain / 4``) the
    step from a fresh factorisation at a residual of 7e-7 moved 4.9e-6 mean rest lengths:
    it certified nothing, and relax's second-order check factorised again. Counted here:
    every factorisation made once the residual is below ``_FRESH_NEAR tol``, the check's
    included."""
    import continuum_vs_network as cvn
    from continuum_vs_network.network import escapes
    from continuum_vs_network.network.stopping import StopRule

    rng = np.random.default_rng(0)
    net = triangular_lattice(side, side, noise=0.1, rng=rng)
    net = net.with_stiffness(rng.uniform(0.5, 50, net.n_springs))
    mid = net.positions[net.springs].mean(axis=1)
    order = np.argsort(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1))
    centre, second = int(order[0]), int(order[len(order) // 8])
    clamped = {
        centre: float(net.clamp_length(centre, strain)),
        second: float(net.clamp_length(second, -strain / 4)),
    }
    tol = 1e-10
    last = [np.inf]
    end_game = []
    imbalance, factorise, check = StopRule.imbalance, nw.factor_positive_model, lowest_curvature

    def recorded_imbalance(self, force, coords):
        last[0] = imbalance(self, force, coords)
        return last[0]

    def recorded_factorise(*args, **kwargs):
        if last[0] <= nw._FRESH_NEAR * tol:
            end_game.append("newton")
        return factorise(*args, **kwargs)

    def recorded_check(*args, **kwargs):
        end_game.append("check")
        return check(*args, **kwargs)

    monkeypatch.setattr(StopRule, "imbalance", recorded_imbalance)
    monkeypatch.setattr(nw, "factor_positive_model", recorded_factorise)
    monkeypatch.setattr(escapes, "lowest_curvature", recorded_check)
    eq = cvn.relax(net, clamped=clamped, tol=tol)
    assert eq.converged and eq.relative_residual <= tol
    assert len(end_game) == 1, end_game


def _ladders(monkeypatch, side: int = 20, strain: float = 3.0) -> list:
    """Newton on a ``side`` x ``side`` lattice whose central spring's nodes are pinned
    ``strain`` apart (:func:`pulled_apart`, bench_jaxmd's problem): the arguments and
    result of every :func:`~.hessian_ladder.factor_positive_model` call that met a
    direction of negative curvature, where the Ritz bound is computed."""
    net, pins, x0 = pulled_apart(side, strain)
    problem = Problem.build(net, pinned=pins)
    calls: list = []
    made, ritz = ladder.factor_positive_model, ladder.ritz_lowest
    bounded = [False]

    def recorded(*args, **kwargs):
        bounded[0] = False
        out = made(*args, **kwargs)
        if bounded[0]:
            calls.append((args, kwargs, out))
        return out

    def spy(*args, **kwargs):
        bounded[0] = True
        return ritz(*args, **kwargs)

    with monkeypatch.context() as spied:
        spied.setattr(nw, "factor_positive_model", recorded)
        spied.setattr(ladder, "ritz_lowest", spy)
        stop = problem.stop_rule(1e-10, max_iter=200, max_seconds=60.0)
        assert nw.newton(problem, problem.start(x0), stop, Trace()).converged
    assert calls, "no ladder met negative curvature: the case does not test the rule"
    return calls


def test_the_ritz_value_bounds_the_lowest_eigenvalue_and_finds_it_from_a_negative_direction(
    monkeypatch,
):
    """``ritz_lowest`` is a Rayleigh quotient over a Krylov space, so never below the lowest
    eigenvalue of ``W`` in the metric ``diag(scale)``; from a direction of negative
    curvature it reaches an eigenvalue that stands apart in a few steps."""
    (problem, pattern, x, lam, rho, _), _, _ = _ladders(monkeypatch)[0]
    W = ladder.assemble_hessian(pattern, lagrangian_blocks(problem, x, lam, rho))
    scale = ladder.marquardt_scale(W)
    root = 1.0 / np.sqrt(scale)
    vals, vecs = np.linalg.eigh(root[:, None] * W.toarray() * root[None, :])
    assert vals[0] < 0.0 and vals[1] - vals[0] > 0.1 * abs(vals[0])  # apart, negative
    rng = np.random.default_rng(1)
    negative = root * (vecs[:, 0] + 0.3 * rng.standard_normal(vals.size) / np.sqrt(vals.size))
    assert ladder.ritz_lowest(W, scale, negative, steps=10) == pytest.approx(vals[0], rel=1e-8)
    for steps in (1, 3, 10):
        start = rng.standard_normal(vals.size)
        assert ladder.ritz_lowest(W, scale, start, steps=steps) >= vals[0] - 1e-12
    unknown = sp.csr_matrix(np.full((2, 2), np.nan))
    assert ladder.ritz_lowest(unknown, np.ones(2), np.ones(2)) == np.inf
    assert ladder.ritz_lowest(W, scale, np.zeros(vals.size)) == np.inf


def test_the_ladder_skips_only_rungs_that_must_fail(monkeypatch):
    """Rungs below the Ritz bound are not factorised: the ladder ends at the same shift
    with the same factor after fewer factorisations, and each rung it skips fails when
    factorised. At strain 10 the first ladder (N = 4096, bench_jaxmd) went 0.0368 ->
    0.368 -> 3.68 -> 36.8, three failed factorisations (22 of 209 ms); now 36.8 at once."""
    made = ladder.factor_positive_model
    factorised: list = []
    factor = ladder.factor_spd

    def counted(M, **kwargs):
        out = factor(M, **kwargs)
        factorised.append((M, out is not None))
        return out

    calls = _ladders(monkeypatch)
    monkeypatch.setattr(ladder, "factor_spd", counted)
    skipped = 0
    for args, kwargs, out in calls:
        factorised.clear()
        with monkeypatch.context() as unbounded:
            unbounded.setattr(ladder, "ritz_lowest", lambda *a, **k: np.inf)
            plain = made(*args, **kwargs)
        rungs = [M for M, _ in factorised]
        factorised.clear()
        again = made(*args, **kwargs)
        assert again.shift == out.shift == plain.shift
        rhs = np.random.default_rng(0).standard_normal(plain.matrix.shape[0])
        np.testing.assert_array_equal(again.factor.solve(rhs), plain.factor.solve(rhs))
        kept = [M.data for M, _ in factorised]
        missing = [M for M in rungs if not any(np.array_equal(M.data, d) for d in kept)]
        assert len(rungs) - len(factorised) == len(missing)
        for M in missing:
            assert factor(M, rough=True, rung=True) is None
        skipped += len(missing)
    assert skipped >= 2
