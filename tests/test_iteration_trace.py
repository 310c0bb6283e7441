"""Every method records the true iteration number of each residual it traces."""

from __future__ import annotations

import numpy as np
import pytest

import continuum_vs_network as cvn


@pytest.mark.parametrize("method", ["newton", "fire", "lbfgs"])
@pytest.mark.parametrize("ramp", [1, 3])
def test_last_record_is_the_reported_iteration_count(method, ramp):
    net = cvn.triangular_lattice(6, 6)
    eq = cvn.relax(net, clamped={0: 1.3 * float(net.rest_length[0])}, method=method, ramp=ramp)
    it = eq.iteration_trace
    assert it.shape == eq.residual_trace.shape == eq.seconds_trace.shape
    assert it[0] == 0 and it[-1] == eq.iterations
    assert np.all(np.diff(it) >= 0)
    if method == "newton":  # every iteration recorded, stages counted on
        assert it.size == eq.iterations + ramp
    else:  # a record every tenth iteration: far fewer records than iterations
        assert eq.iterations > 30 and it.size < eq.iterations / 3
