"""A lattice with one spring pulled apart by its pinned nodes (bench_jaxmd's problem; the
benchmarks import it from here)."""

from __future__ import annotations

import numpy as np

import continuum_vs_network as cvn
from continuum_vs_network.network.builders import triangular_lattice


def pulled_apart(side: int, strain: float, seed: int = 0):
    """A stress-free noisy ``side`` x ``side`` lattice (noise drawn with ``seed``) whose
    spring nearest the centre is stretched by ``strain`` by moving its two nodes apart and
    pinning them there (plus the default pins): ``(net, pins, x0)``."""
    net = triangular_lattice(side, side, noise=0.1, rng=np.random.default_rng(seed))
    mid = net.positions[net.springs].mean(axis=1)
    c = int(np.argmin(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1)))
    a, b = net.springs[c]
    x0 = net.positions.copy()
    grow = strain * (x0[b] - x0[a])
    x0[a] -= 0.5 * grow
    x0[b] += 0.5 * grow
    pins = cvn.default_pins(net, avoid=[c])
    pins[[a, b]] = True
    return net, pins, x0
