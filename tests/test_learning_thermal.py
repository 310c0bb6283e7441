"""Thermal noise: harmonic Boltzmann draws (equipartition), the GCL update's thermal
noise (std proportional to sqrt(T) / eta), training at a temperature."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.learning import CoupledLearning, stern_task, train
from continuum_vs_network.learning.thermal import thermal_sample
from continuum_vs_network.network.builders import triangular_lattice


@pytest.fixture(scope="module")
def lattice():
    rng = np.random.default_rng(1)
    net = triangular_lattice(5, 5, noise=0.1, rng=rng)
    return net, stern_task(net, 2, 1, rng)


def test_draws_obey_equipartition_and_keep_pins(lattice):
    net, task = lattice
    clamps = task.source_clamps(net)
    eq = cvn.relax(net, pinned=task.pinned, clamped=clamps)
    T = 1e-6
    xs = thermal_sample(net, task.pinned, clamps, eq, T, np.random.default_rng(0), size=2000)
    # <E - E*> = T d / 2, d = free coordinates minus clamps (harmonic, to O(T^2))
    d = int((~task.pinned).sum()) - len(clamps)
    mean = np.mean([cvn.energy(x, net) for x in xs]) - eq.energy
    assert mean / (T * d / 2) == pytest.approx(1.0, abs=0.03)
    assert np.all(xs[:, task.pinned] == eq.positions[task.pinned])
    # clamps hold to first order: the clamp length moves by O(T), not O(sqrt(T))
    r = net.lengths(xs[0])[task.sources]
    assert np.max(np.abs(r - np.array(list(clamps.values())))) < 10 * T
    assert np.array_equal(thermal_sample(net, task.pinned, clamps, eq, 0.0, None), eq.positions)


def test_gcl_thermal_update_noise_scales_as_sqrt_t_over_eta(lattice):
    net, task = lattice
    stds = {}
    for T, eta in ((1e-8, 0.1), (1e-8, 0.01), (1e-6, 0.1)):
        rule = CoupledLearning(1.0, eta)
        exact = rule.update(net, task).raw
        rng = np.random.default_rng(0)
        draws = [rule.update(net, task, temperature=T, rng=rng).raw - exact for _ in range(60)]
        stds[T, eta] = float(np.sqrt(np.mean(np.square(draws))))
    assert stds[1e-8, 0.01] / stds[1e-8, 0.1] == pytest.approx(10.0, rel=0.25)
    assert stds[1e-6, 0.1] / stds[1e-8, 0.1] == pytest.approx(10.0, rel=0.25)


def test_training_at_a_temperature_has_a_floor_that_grows_with_t(lattice):
    net, task = lattice
    floors = []
    for T in (0.0, 1e-6):
        h = train(net, task, CoupledLearning(0.5, 0.1), 100, temperature=T, progress=False)
        assert h.completed[0] == 100
        floors.append(np.median(h.error_initial[0, -20:] / h.error_initial[0, 0]))
    assert floors[1] > 10 * floors[0]
    assert h.settings["temperature"] == 1e-6
    with pytest.raises(ValueError, match="rng"):
        CoupledLearning(0.5, 0.1).update(net, task, temperature=1e-6)
    with pytest.raises(ValueError, match="temperature"):
        train(net, task, CoupledLearning(0.5, 0.1), 1, temperature=-1.0, progress=False)
