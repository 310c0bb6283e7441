"""Synthetic learning histories for the tests of how reports judge stored runs."""

from __future__ import annotations

import numpy as np

from continuum_vs_network.learning.history import History
from continuum_vs_network.learning.tasks import stern_task
from continuum_vs_network.scenes.stern import stern_network


def paper_task():
    """A 64-node Stern network and a 4-source, 1-target task on it: ``(net, task)``."""
    rng = np.random.default_rng(0)
    net = stern_network(64, rng)
    every = np.ones(net.n_springs, dtype=bool)
    return net, stern_task(net, 4, 1, rng, candidates=every, source_std=0.1, target_std=0.1)


def history(err, *, completed=None, reference="current", data=None) -> History:
    """A history of ``err`` (trials, steps + 1) as ``error_current``; ``data`` adds or
    replaces arrays (``error_initial`` is NaN unless given)."""
    net, task = paper_task()
    n = err.shape[0]
    arrays = {"error_current": err, "error_initial": np.full_like(err, np.nan), **(data or {})}
    return History(
        steps=err.shape[1] - 1,
        seeds=np.arange(n),
        completed=np.full(n, err.shape[1] - 1) if completed is None else np.asarray(completed),
        stop_reason=("",) * n,
        settings={"strain_reference": reference},
        data=arrays,
        initial=(net,) * n,
        final=(net,) * n,
        tasks=(task,) * n,
    )


def stopped(err: np.ndarray, completed) -> np.ndarray:
    """``err`` with NaN after each trial's ``completed`` step (a trial that stopped)."""
    err = err.copy()
    for i, c in enumerate(completed):
        err[i, c + 1 :] = np.nan
    return err
