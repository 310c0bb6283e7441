"""Past the paper: Stern-scale allostery (N >= 512 nodes, 10 sources, 3 targets).

Stern et al. (2021) trained networks of 512 and 1024 nodes with 10 source and 3 target
springs. :func:`stern_network` builds such a network (a noisy triangular lattice, a
diluted lattice or a jammed packing, stress-free, ``k = 1`` or ``1/L``),
:func:`stern_rules` the three rules with matched settings and :func:`stern_study` trains
each rule on the same networks and tasks and returns a table of error reduction and wall
time per step, and the histories.

Strains here are measured against the initial rest lengths (``strain_reference=
"initial"``): the desired output is a fixed geometry, and coupled learning then descends
the task error (see :mod:`..learning.rules`). Learning rates are chosen so that the three rules take
comparable steps: coupled learning's update is ``-alpha K dC_len`` (``K`` the targets'
effective stiffness, of order ``k``), so the exact gradient uses the same ``alpha`` on
the length cost.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..learning.history import History
from ..learning.metrics import first_below, summary
from ..learning.rules import CoupledLearning, ExactGradient, ProspectiveConfiguration, Rule
from ..learning.states import Solver
from ..learning.tasks import stern_task
from ..learning.train import train
from ..network.model import SpringNetwork

__all__ = ["stern_network", "stern_rules", "stern_study", "stern_table"]


def stern_network(
    n_nodes: int,
    rng: np.random.Generator,
    *,
    kind: str = "lattice",
    noise: float = 0.1,
) -> SpringNetwork:
    """A stress-free network of about ``n_nodes`` nodes for Stern-scale tasks.

    ``kind``: ``"lattice"`` (a near-square triangular lattice with position noise
    ``noise`` of the spacing, ``k = 1``), ``"diluted"`` (the same with 20 % of the springs
    removed, kept rigid) or ``"jammed"`` (the contact network of a jammed packing,
    ``k = 1/L``; somewhat fewer nodes than asked, rattlers removed).
    """
    from ..network import builders, jammed

    if kind in ("lattice", "diluted"):
        nx = max(2, round(math.sqrt(n_nodes)))
        ny = max(2, round(n_nodes / nx))
        if kind == "lattice":
            return builders.triangular_lattice(nx, ny, noise=noise, rng=rng)
        return builders.diluted_lattice(nx, ny, 0.2, rng, noise=noise)
    if kind == "jammed":
        return jammed.jammed_network(n_nodes, rng)
    raise ValueError(f"kind must be 'lattice', 'diluted' or 'jammed', got {kind!r}")


def stern_rules(
    *,
    alpha: float = 0.5,
    eta: float = 0.1,
    alpha_gpc: float = 0.5,
    solver: Solver | None = None,
    learn_sources: bool = False,
    learn_targets: bool = False,
) -> dict[str, Rule]:
    """Coupled learning, prospective configuration and the exact gradient (length cost).

    Sources and targets do not learn by default, so that the bulk must learn to transmit
    the strain: a source that relaxes its own rest length to its clamp length stops
    straining the network, and a target that changes its own rest length meets the task
    locally (both rules then converge at the target's own rate ``alpha k``). ``alpha =
    0.5`` is about the fastest stable rate for GCL on these lattices (``k = 1``).
    """
    common = {
        "strain_reference": "initial",
        "solver": solver or Solver(),
        "learn_sources": learn_sources,
        "learn_targets": learn_targets,
        "min_rest_length": 1e-3,
    }
    return {
        "GCL": CoupledLearning(alpha, eta, **common),
        "GPC": ProspectiveConfiguration(alpha_gpc, **common),
        "exact": ExactGradient(alpha, cost="length", **common),
    }


def stern_study(
    sizes: Sequence[int] = (512, 1024),
    *,
    rules: dict[str, Rule] | None = None,
    steps: int = 200,
    trials: int = 3,
    kind: str = "lattice",
    n_sources: int = 10,
    n_targets: int = 3,
    progress: bool = False,
) -> dict[tuple[int, str], History]:
    """Train every rule on ``trials`` networks of every size; returns the histories.

    Trial ``i`` of size ``n`` uses seed ``i`` for network and task, the same for every
    rule. Keys are ``(n, rule name)``.
    """
    rules = rules or stern_rules()
    out = {}
    for n in sizes:

        def network(rng: np.random.Generator, n: int = n) -> SpringNetwork:
            return stern_network(n, rng, kind=kind)

        def task(net: SpringNetwork, rng: np.random.Generator):
            every = np.ones(net.n_springs, dtype=bool)
            return stern_task(net, n_sources, n_targets, rng, candidates=every)

        for name, rule in rules.items():
            out[n, name] = train(network, task, rule, steps, seeds=range(trials), progress=progress)
    return out


def stern_table(
    histories: dict[tuple[int, str], History], *, level: float = 1e-3
) -> list[dict[str, str]]:
    """Rows: size, rule, final C/C0 (median [quartiles]), steps and wall-clock seconds
    until ``C/C0 <= level`` (median over the trials that got there), seconds per step and
    factorisations per step."""
    rows = []
    for (n, name), h in histories.items():
        error = h.task_error(h.strain_reference)
        s = summary(error, h.completed)
        done = np.maximum(h.completed, 1)
        per_step = [h.seconds[i, min(h.completed[i], h.steps)] / done[i] for i in range(h.trials)]
        learn = [
            (
                h.seconds[i, min(h.completed[i], h.steps)]
                - h.measure_seconds[i, min(h.completed[i], h.steps)]
            )
            / done[i]
            for i in range(h.trials)
        ]
        fact = [
            h.factorisations[i, min(h.completed[i], h.steps)] / done[i] for i in range(h.trials)
        ]
        reach_steps, reach_seconds = [], []
        for i in range(h.trials):
            ratio = error[i] / error[i, 0]
            t = first_below(ratio, level)
            if t is not None:
                reach_steps.append(t)
                reach_seconds.append(h.seconds[i, t])
        reached = (
            f"{np.median(reach_steps):.0f} steps, {np.median(reach_seconds):.3g} s "
            f"({len(reach_steps)}/{h.trials})"
            if reach_steps
            else f"- (0/{h.trials})"
        )
        rows.append(
            {
                "N": str(h.initial[0].n_nodes),
                "asked N": str(n),
                "rule": name,
                "steps": str(h.steps),
                "C/C0": (
                    f"{s['median']:.3g} [{s['q25']:.3g}, {s['q75']:.3g}]" if s.get("n") else "-"
                ),
                f"to C/C0 <= {level:g}": reached,
                "s/step": f"{np.median(per_step):.3g}",
                "s/step (learning only)": f"{np.median(learn):.3g}",
                "factorisations/step": f"{np.median(fact):.2f}",
                "stopped": str(int(np.sum(h.completed < h.steps))),
            }
        )
    return rows
