"""Past the paper: robustness of the learning rules to measurement noise (Sec. 5.3, 8).

The paper argues that prospective configuration should tolerate noisy measurements
better than coupled learning, whose update divides a difference of two nearby states by
the nudge ``eta``. :func:`noise_study` trains each rule with relative read-out noise
``sigma`` on every length the rule reads (``r -> r (1 + sigma xi)``, fresh ``xi ~ N(0,1)``
per reading) and records the final task error; :func:`noise_table` tabulates the median
final ``C/C0`` against ``sigma``.

Two set-ups (``setup``): ``"lattice"``, a noisy triangular lattice of about 256 nodes with
a Stern-style task (4 sources, 2 targets, strains of order 10 %), and ``"paper"``, the
paper's network and task. Strains are measured against the initial rest lengths in both
(a well-defined target geometry; see :mod:`.rules`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .history import History
from .metrics import final_values, normalised
from .rules import CoupledLearning, ProspectiveConfiguration, Rule
from .tasks import paper_task, stern_task
from .train import train

__all__ = ["noise_rules", "noise_study", "noise_table"]


def noise_rules(
    setup: str = "lattice", *, etas: Sequence[float] = (0.01, 0.1, 1.0)
) -> dict[str, Rule]:
    """GCL at several nudges and GPC (sources and targets frozen), rates suited to ``setup``."""
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
