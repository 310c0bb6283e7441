"""Learning stiffnesses in physical time: the adaptive rate in time, and coupling."""

from __future__ import annotations

import numpy as np
import pytest

from continuum_vs_network.learning.allostery import allostery_task
from continuum_vs_network.learning.physical_time import learn_in_time
from continuum_vs_network.learning.rates import Adaptive, RateState
from continuum_vs_network.learning.rules import CoupledLearning
from continuum_vs_network.learning.time_media import AdaptiveClock
from continuum_vs_network.network.builders import triangular_lattice
from continuum_vs_network.network.viscous import Viscosity
from continuum_vs_network.scenes.units_time_coupling import final_coupling


def test_clock_at_one_step_per_learning_step_is_adam():
    rng = np.random.default_rng(0)
    rate = Adaptive()
    clock = AdaptiveClock(rate, np.ones(5), 1.0, step_time=2.0)
    state = RateState.start(np.ones(5))
    for _ in range(4):
        line = rng.normal(size=5) * 1e-3
        want, state = rate.delta(line, 1.0, state)
        np.testing.assert_allclose(clock.delta(line, 2.0), want, rtol=1e-12)


def test_clock_half_steps_decay_like_one_step():
    # a constant line: m_hat / sqrt(v_hat) = 1 whatever the split, so two half steps move
    # as far as one step
    line = np.full(3, 2e-4)
    one = AdaptiveClock(Adaptive(), np.ones(3), 1.0, 1.0).delta(line, 1.0)
    half = AdaptiveClock(Adaptive(), np.ones(3), 1.0, 1.0)
    two = half.delta(line, 0.5) + half.delta(line, 0.5)
    np.testing.assert_allclose(two, one, rtol=1e-12)
    np.testing.assert_allclose(one, 0.05, rtol=1e-6)


def test_adaptive_rule_needs_step_time():
    net = triangular_lattice(6, 6)
    task = allostery_task(net, np.random.default_rng(1))
    with pytest.raises(ValueError, match="step_time"):
        learn_in_time(net, task, CoupledLearning(dof="stiffness"), viscosity=Viscosity(drag=1.0),
                      duration=2.0, dt=1.0)  # fmt: skip


def test_stiffness_learning_in_time_lowers_the_error_and_stays_coupled():
    net = triangular_lattice(8, 8)
    task = allostery_task(net, np.random.default_rng([0, 8]), ratio=0.3, distance=0.25)
    run = learn_in_time(
        net, task, CoupledLearning(dof="stiffness"), viscosity=Viscosity(drag=1.0),
        duration=60.0, dt=1.0, n_outputs=6, quasistatic=True, step_time=1.0,
    )  # fmt: skip
    assert run.error[-1] < 0.8 * run.error[0]
    c = final_coupling(net, task, run, "network")
    # unstressed at rest: k cannot prestress the targets, so the sources cause the change
    assert c["coupling"] == "coupled" and c["source_share"] > 0.99
