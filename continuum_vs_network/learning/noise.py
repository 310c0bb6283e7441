"""Past the paper: robustness of the learning rules to measurement noise (Sec. 5.3, 8).

The paper argues that prospective configuration should tolerate noisy measurements
better than coupled learning, whose update divides a difference of two nearby states by
the nudge ``eta``. :func:`noise_study` trains each rule with relative read-out noise
``sigma`` on every length the rule reads (``r -> r (1 + sigma xi)``, fresh ``xi ~ N(0,1)``
per reading); :func:`noise_table` tabulates the median final ``C/C0`` against ``sigma``.

The noise floor
---------------
Coupled learning's update ``(alpha / eta) k (r^C - r^F)`` carries a signal of order ``eta``
times the length error and a read-out noise of order ``sigma r``: learning stops where the
two meet, at a target strain error ``~ sigma / eta``, so the task error levels off at a
floor ``C_floor ~ c (sigma / eta)^2`` (at a fixed rate ``alpha``). :func:`noise_floor`
measures the floor of a run (the mean of ``C`` over the last quarter of its steps) and
:func:`floor_scaling` fits ``log C_floor = p log(sigma / eta) + log c`` over the runs the
noise limits (floor well above the noise-free run's final error, trial not diverged): the
reasoning above predicts ``p = 2``. Prospective configuration and the exact gradient have
no nudge: their floors scale like ``sigma^2``.

Strains are measured against the initial rest lengths (the convention in which the rules
learn; see :mod:`.rules`), sources and targets frozen (bulk learning).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..fits import power_law
from .history import History
from .metrics import final_values, normalised
from .rules import CoupledLearning, ExactGradient, ProspectiveConfiguration, Rule
from .tasks import paper_task, stern_task
from .train import train

__all__ = ["floor_scaling", "noise_floor", "noise_rules", "noise_study", "noise_table"]


def noise_rules(
    setup: str = "lattice", *, etas: Sequence[float] = (1e-3, 1e-2, 1e-1, 1.0)
) -> dict[str, Rule]:
    """GCL at several nudges, GPC and the exact gradient (sources and targets frozen),
    rates suited to ``setup``."""
    if setup == "lattice":
        alpha, floor = 0.5, 1e-3
    elif setup == "paper":
        alpha, floor = 1e-3, 0.1
    else:
        raise ValueError(f"setup must be 'lattice' or 'paper', got {setup!r}")
    # sources and targets frozen: the bulk must learn (see stern_rules)
    common = {
        "strain_reference": "initial",
        "min_rest_length": floor,
        "learn_sources": False,
        "learn_targets": False,
    }
    rules: dict[str, Rule] = {
        f"GCL eta={eta:g}": CoupledLearning(alpha, eta, **common) for eta in etas
    }
    rules["GPC"] = ProspectiveConfiguration(alpha, **common)
    rules["exact"] = ExactGradient(alpha, cost="length", **common)
    return rules


def _setup(setup: str):
    if setup == "paper":
        from ..network.builders import paper_network

        return paper_network, paper_task

    def network(rng: np.random.Generator):
        from ..network.builders import triangular_lattice

        return triangular_lattice(16, 16, noise=0.1, rng=rng)

    def task(net, rng: np.random.Generator):
        return stern_task(net, 4, 2, rng, candidates=np.ones(net.n_springs, dtype=bool))

    return network, task


def noise_study(
    sigmas: Sequence[float] = (0.0, 1e-4, 1e-3, 1e-2),
    *,
    setup: str = "lattice",
    rules: dict[str, Rule] | None = None,
    steps: int = 200,
    trials: int = 3,
    progress: bool = False,
) -> dict[tuple[str, float], History]:
    """Train every rule at every noise level; keys ``(rule name, sigma)``.

    Trial ``i`` uses seed ``i`` for network, task and noise, the same for every rule and
    sigma, so the columns of :func:`noise_table` differ only by the rule and the noise.
    """
    rules = rules or noise_rules(setup)
    network, task = _setup(setup)
    out = {}
    for name, rule in rules.items():
        for sigma in sigmas:
            out[name, float(sigma)] = train(
                network,
                task,
                rule,
                steps,
                seeds=range(trials),
                noise=float(sigma),
                progress=progress,
            )
    return out


def noise_table(
    histories: dict[tuple[str, float], History], *, quantity: str = "error_initial"
) -> list[dict[str, str]]:
    """One row per rule: median final ``C/C0`` (and the worst trial) for every sigma.

    Trials that stopped early (diverged) enter with their last measured value and are
    counted.
    """
    names = list(dict.fromkeys(name for name, _ in histories))
    sigmas = sorted({sigma for _, sigma in histories})
    rows = []
    for name in names:
        row = {"rule": name}
        for sigma in sigmas:
            h = histories.get((name, sigma))
            if h is None:
                continue
            # last measured value of every trial (a trial whose learning diverged stops
            # when its equilibrium can no longer be found; it is counted as stopped)
            final = final_values(normalised(getattr(h, quantity)))
            ok = final[np.isfinite(final)]
            text = f"{np.median(ok):.3g} (max {np.max(ok):.3g})" if ok.size else "-"
            stopped = int(np.sum(h.completed < h.steps))
            if stopped:
                text += f", {stopped}/{h.trials} stopped"
            row[f"sigma={sigma:g}"] = text
        rows.append(row)
    return rows


def noise_floor(
    values: NDArray, completed: NDArray, *, fraction: float = 0.25, statistic=np.mean
) -> NDArray:
    """The level a task error settles at: per trial, ``statistic`` (the mean; the median is
    robust to a run still descending) over the last ``fraction`` of the steps, (trials,);
    NaN for a trial that stopped early (diverged).

    Parameters
    ----------
    values : (trials, steps + 1) float array
        A task error history (``error_initial``, unscaled).
    completed : (trials,) int array
        Steps each trial completed.
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] < 2:
        raise ValueError(f"values must be (trials, steps + 1) with steps >= 1, got {v.shape}")
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    steps = v.shape[1] - 1
    first = steps - max(1, round(fraction * steps)) + 1
    out = np.full(v.shape[0], np.nan)
    for i in range(v.shape[0]):
        if completed[i] >= steps:
            out[i] = float(statistic(v[i, first:]))
    return out


def floor_scaling(
    ratio: ArrayLike, floor: ArrayLike, clean: ArrayLike, *, margin: float = 10.0
) -> dict[str, float]:
    """Fit ``floor = c ratio^p`` over the points the noise limits.

    Parameters
    ----------
    ratio : (n,) float array
        ``sigma / eta`` (GCL) or ``sigma`` of every point (> 0).
    floor : (n,) float array
        Measured floors (NaN: diverged, left out).
    clean : (n,) float array
        The noise-free run's final error at the same nudge: a point enters the fit when
        its floor is above ``margin * clean`` (the noise, not the step budget, sets it).

    Returns
    -------
    dict
        ``p`` (the exponent), ``c`` (the prefactor ``exp(mean(log floor - p log ratio))``),
        ``n`` (points fitted), ``spread`` (max / min of ``floor / ratio^p`` over them).
        ``p`` and ``c`` are NaN with fewer than 3 points over at least a decade of ratio.
    """
    r, f, c = (np.asarray(a, dtype=np.float64).ravel() for a in (ratio, floor, clean))
    if not (r.shape == f.shape == c.shape):
        raise ValueError("ratio, floor and clean must have the same length")
    if np.any(r <= 0):
        raise ValueError("ratio must be > 0")
    use = np.isfinite(f) & (f > 0) & (f > margin * np.nan_to_num(c, nan=0.0))
    out = {"p": np.nan, "c": np.nan, "n": int(use.sum()), "spread": np.nan}
    if use.sum() < 3 or np.ptp(np.log10(r[use])) < 1.0:
        return out
    p = power_law(r[use], f[use]).exponent
    pre = f[use] / r[use] ** p
    out.update(p=p, c=float(np.exp(np.mean(np.log(pre)))), spread=float(pre.max() / pre.min()))
    return out
