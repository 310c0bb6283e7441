"""A trained network against its homogenised continuum."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn
from continuum_vs_network.continuum.materials import network_moduli
from continuum_vs_network.continuum.transmission import continuum_transmission
from continuum_vs_network.network.builders import triangular_lattice

pytest.importorskip("skfem")
learning = pytest.importorskip("continuum_vs_network.learning")
if not all(hasattr(learning, n) for n in ("train", "AllosteryTask", "CoupledLearning")):
    pytest.skip(
        "continuum_vs_network.learning has no train / AllosteryTask / CoupledLearning yet",
        allow_module_level=True,
    )


def test_trained_response_lives_in_the_microstructure_not_in_the_continuum():
    """Train a lattice (coupled learning on rest lengths) so that clamping a source spring
    gives a target spring 4 spacings away a strain 3 % above its untrained response. The
    network reaches it; the continuum with the trained network's homogenised (relaxed)
    moduli transmits almost exactly what the untrained continuum does, nowhere near the
    target: what was learned is not an elastic-continuum property."""
    net = triangular_lattice(10, 11)
    x = net.positions
    mid = 0.5 * (x[net.springs[:, 0]] + x[net.springs[:, 1]])
    flat = np.abs(x[net.springs[:, 1], 1] - x[net.springs[:, 0], 1]) < 1e-9
    src = int(np.argmin(np.hypot(*(mid - x.mean(axis=0)).T) + 1e3 * ~flat))
    same_row = np.abs(mid[:, 1] - mid[src, 1]) < 1e-9
    tgt = int(np.argmin(np.abs(np.hypot(*(mid - mid[src]).T) - 3.5) + 1e3 * ~(flat & same_row)))
    s_src, L0 = 0.05, net.rest_length

    probe = learning.AllosteryTask.create(net, [src], [s_src], [tgt], [0.0])
    untrained = cvn.relax(net, pinned=probe.pinned, clamped=probe.source_clamps(net, "initial"))
    s_untrained = float(net.strains(untrained.positions)[tgt])
    desired = s_untrained + 0.03
    task = learning.AllosteryTask.create(net, [src], [s_src], [tgt], [desired])
    kept = {}
    rule = learning.CoupledLearning(1.0, 0.5, strain_reference="initial")
    learning.train(
        net, task, rule, 40, progress=False, callback=lambda trial, step, n: kept.update(net=n)
    )
    trained = kept["net"]

    free = cvn.relax(trained, pinned=task.pinned)
    clamped = cvn.relax(trained, pinned=task.pinned, clamped=task.source_clamps(trained, "initial"))
    s_trained = trained.lengths(clamped.positions)[tgt] / L0[tgt] - 1
    assert s_trained == pytest.approx(desired, abs=1e-4)

    # the continuum of the trained network: its relaxed (pre-stressed) shape and moduli
    shaped = trained.with_positions(free.positions)
    material = network_moduli(shaped).material
    source_strain = L0[src] * (1 + s_src) / trained.rest_length[src] - 1
    cont_trained = continuum_transmission(shaped, src, source_strain, material=material)
    cont_plain = continuum_transmission(net, src, s_src)
    k = int(np.flatnonzero(cont_trained.springs == tgt)[0])
    r_free = trained.lengths(free.positions)[tgt]
    d_trained = cont_trained.strain[k] * r_free / L0[tgt]  # change of r_T / L0_T
    d_plain = cont_plain.strain[k]
    learned = desired - s_untrained
    assert abs(d_trained - d_plain) < 0.05 * learned
    assert abs(d_trained - desired) > 0.9 * learned
    # the plain continuum's transmitted strain is the untrained lattice's, to 30 %
    assert d_plain == pytest.approx(s_untrained, rel=0.3)
