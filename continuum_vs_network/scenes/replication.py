"""The paper's learning experiments (Sec. 7, Fig. 4-10, appendix A.2-A.3) as functions.

:func:`paper_experiments` lists the runs (each a rule with its settings and the paper's
claim about it); :func:`run` trains one of them on fresh paper networks (10 trials of 300
steps by default) and :func:`replicate` runs a list of them under one or more equilibrium
solvers. :func:`table` turns the histories into rows ``claim / measured / settings``;
:func:`markdown` prints them. The report draws its figures from the returned histories.

Settings the paper does not give, and the choices made here
-----------------------------------------------------------
* learning rates: GCL ``alpha = 1e-3``, ``eta = 0.1``; GPC ``alpha = 1e-3``; exact
  gradient ``alpha = 1`` (learning-``L`` strains) or ``10`` (initial-``L`` strains), about
  the largest stable rates in pilot runs (the paper gives none);
* the strain convention: both are run (``"current"``, the paper's literal ``S = r/L - 1``
  with the learning ``L`` for clamps and error; ``"initial"``, fixed clamp lengths). The
  paper's GPC text says its rods keep their length while ``L`` learns (Sec. 7.2), which
  is the ``"initial"`` clamp convention; its error (Fig. 6) is Eq. 26 with the learning
  ``L``, which every history records as ``error_current``;
* the rest-length floor (``min_rest_length``; without one, rest lengths reach 0 in some
  trials and those trials stop);
* the paper's relaxation (``method="paper"``, Adagrad, learning rate 0.1, rods of
  stiffness 1e10) never converges; it is run with a fixed budget of ``paper_iterations``
  Adagrad steps per state, warm-started from the previous state, and its last iterate
  (``EquilibriumError.state``) is used, as the paper's loop used it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..learning.history import History
from ..learning.metrics import length_error, rest_length_error, source_sweep, summary
from ..learning.rules import CoupledLearning, ExactGradient, ProspectiveConfiguration, Rule
from ..learning.states import Solver
from ..learning.tasks import paper_task
from ..learning.train import train

__all__ = [
    "Experiment",
    "exact_solver",
    "markdown",
    "paper_experiments",
    "paper_solver",
    "replicate",
    "run",
    "sweeps",
    "table",
    "verification",
]


@dataclass(frozen=True)
class Experiment:
    """One of the paper's runs.

    Attributes
    ----------
    name : str
        Short identifier (``"gcl"``, ``"gpc_frozen"``, ...).
    figures : str
        The paper's figures it reproduces.
    claim : str
        What the paper reports.
    rule : Rule
    """

    name: str
    figures: str
    claim: str
    rule: Rule


def exact_solver() -> Solver:
    """Exact equilibria: sparse Newton, exact clamps, factorisations reused."""
    return Solver()


def paper_solver(paper_iterations: int = 300) -> Solver:
    """The paper's relaxation: Adagrad (lr 0.1) with rods, a fixed budget per state."""
    return Solver(
        method="paper",
        clamp="rod",
        max_iter=paper_iterations,
        accept_unconverged=True,
        reuse=False,
        trust_region=False,
        retry_ramps=(),
    )


def paper_experiments(
    *,
    strain_reference: str = "initial",
    solver: Solver | None = None,
    alpha_gcl: float = 1e-3,
    eta: float = 0.1,
    alpha_gpc: float = 1e-3,
    alpha_exact: float | None = None,
    floor: float = 0.1,
) -> tuple[Experiment, ...]:
    """The paper's learning runs with one strain convention and one solver.

    ``strain_reference`` defaults to ``"initial"`` as everywhere; the paper's literal
    convention is ``"current"`` (see the module docstring). Every spring learns, sources
    and targets included, as in the paper, except in the ``*_frozen`` runs (target frozen).

    Returns experiments named ``gcl`` (Fig. 4, A.2; all springs learn, no floor),
    ``gcl_floor`` (the same with a rest-length floor), ``gcl_frozen`` (target frozen,
    floor), ``gpc`` (Fig. 6-9, A.3), ``gpc_frozen`` (Fig. 10) and ``exact`` (the exact
    gradient of Eq. 26 with a floor: what the task allows) and ``exact_frozen`` (the same
    with the target frozen, the reference for ``gcl_frozen`` and ``gpc_frozen``).
    """
    solver = solver or exact_solver()
    if alpha_exact is None:  # about the largest stable rate in a pilot run of each convention
        alpha_exact = 1.0 if strain_reference == "current" else 10.0
    # the paper lets every spring learn (rules default to bulk learning)
    common = {
        "strain_reference": strain_reference,
        "solver": solver,
        "learn_sources": True,
        "learn_targets": True,
    }
    frozen = {**common, "learn_targets": False}
    return (
        Experiment(
            "gcl",
            "Fig. 4, A.2",
            "GCL lowers C by orders of magnitude; all trials but one converge to C = 0",
            CoupledLearning(alpha_gcl, eta, **common),
        ),
        Experiment(
            "gcl_floor",
            "Fig. 4",
            "(as gcl, with a rest-length floor)",
            CoupledLearning(alpha_gcl, eta, min_rest_length=floor, **common),
        ),
        Experiment(
            "gcl_frozen",
            "(none)",
            "(not in the paper: GCL with the target's L frozen and a floor)",
            CoupledLearning(alpha_gcl, eta, min_rest_length=floor, **frozen),
        ),
        Experiment(
            "gpc",
            "Fig. 6-9, A.3",
            "GPC: C rises on average (large spread); E^C and dE/dL descend; the target "
            "length error falls ~50 %; the target rest-length error converges to 0",
            ProspectiveConfiguration(alpha_gpc, min_rest_length=floor, **common),
        ),
        Experiment(
            "gpc_frozen",
            "Fig. 10",
            "GPC with the target frozen lowers C: the target strain moves 33 % of the way "
            "to the desired strain",
            ProspectiveConfiguration(alpha_gpc, min_rest_length=floor, **frozen),
        ),
        Experiment(
            "exact",
            "(reference)",
            "(not in the paper: gradient descent with the exact gradient of Eq. 26)",
            ExactGradient(alpha_exact, min_rest_length=floor, **common),
        ),
        Experiment(
            "exact_frozen",
            "(reference)",
            "(not in the paper: exact gradient of Eq. 26, target frozen, floor)",
            ExactGradient(alpha_exact, min_rest_length=floor, **frozen),
        ),
    )


def _network(rng: np.random.Generator):
    from ..network.builders import paper_network

    return paper_network(rng)


def run(
    experiment: Experiment,
    *,
    trials: int = 10,
    steps: int = 300,
    first_seed: int = 0,
    progress: bool = False,
    checkpoint: str | Path | None = None,
) -> History:
    """Train ``experiment`` on ``trials`` fresh paper networks (seeds ``first_seed, ...``).

    The same seeds give the same networks and tasks for every experiment, so runs compare
    trial by trial.
    """
    return train(
        _network,
        paper_task,
        experiment.rule,
        steps,
        seeds=range(first_seed, first_seed + trials),
        progress=progress,
        checkpoint=checkpoint,
    )


def replicate(
    experiments: Sequence[Experiment],
    *,
    trials: int = 10,
    steps: int = 300,
    directory: str | Path | None = None,
    progress: bool = False,
    tag: str = "",
) -> dict[str, History]:
    """Run every experiment; with ``directory``, save (and reuse) ``<tag><name>.npz``."""
    out: dict[str, History] = {}
    for exp in experiments:
        path = None if directory is None else Path(directory) / f"{tag}{exp.name}.npz"
        if path is not None and path.exists():
            out[exp.name] = History.load(path)
            continue
        history = run(exp, trials=trials, steps=steps, progress=progress)
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            history.save(path)
        out[exp.name] = history
    return out


def sweeps(
    history: History,
    *,
    span: float = 5.0,
    points: int = 11,
    solver: Solver | None = None,
) -> tuple[NDArray, NDArray]:
    """Source sweeps of every trained network (Fig. 5, A.2 B, A.3 E).

    Source strains ``S_s + linspace(-span, span, points)`` (kept above -0.9) are applied
    to each trial's final network. Returns ``(strains, target)``: (trials, points) source
    strains and (trials, points) target strains (first target); NaN rows for trials
    whose sweep could not be solved.
    """
    ref = history.settings.get("strain_reference", "current")
    solver = solver or exact_solver()
    n = history.trials
    strains = np.full((n, points), np.nan)
    target = np.full((n, points), np.nan)
    from ..network.equilibrium import EquilibriumError

    for i in range(n):
        task = history.tasks[i]
        s = np.maximum(task.source_strain[0] + np.linspace(-span, span, points), -0.9)
        strains[i] = s
        try:
            target[i] = source_sweep(
                history.final[i], task, s, strain_reference=ref, solver=solver
            )[:, 0]
        except EquilibriumError:
            continue
    return strains, target


def _ratio(values: NDArray, history: History) -> dict:
    return summary(values, history.completed)


def _fmt(s: dict) -> str:
    if not s.get("n"):
        return "no trial measured"
    text = f"{s['median']:.3g} [{s['q25']:.3g}, {s['q75']:.3g}]"
    if s.get("missing"):
        text += f" ({s['missing']} trials without a value)"
    return text


def table(
    histories: dict[str, History], experiments: Sequence[Experiment], *, solver_name: str = ""
) -> list[dict[str, str]]:
    """Rows ``figure / paper's claim / measured / settings`` for the report.

    Measured values are medians over trials of final-over-initial ratios, with the
    quartiles in brackets: ``C/C0`` for Eq. 26 with the learning ``L``
    (``error_current``) and with the initial ``L`` (``error_initial``); for GPC also the
    clamped energy, ``|dE/dL|``, the length error (Fig. 8) and the rest-length error
    (Fig. 9).
    """
    rows = []
    for exp in experiments:
        if exp.name not in histories:
            continue
        h = histories[exp.name]
        stopped = int(np.sum(h.completed < h.steps))
        measured = [
            f"C/C0 (Eq. 26, learning L) = {_fmt(_ratio(h.error_current, h))}",
            f"C/C0 (Eq. 26, initial L) = {_fmt(_ratio(h.error_initial, h))}",
        ]
        if exp.name.startswith("gpc"):
            e = h.energy_clamped
            g = h.energy_gradient_clamped
            measured += [
                f"E^C/E^C_0 = {_fmt(summary(e, np.minimum(h.completed, h.steps - 1)))}",
                f"|dE/dL|/|dE/dL|_0 = {_fmt(summary(g, np.minimum(h.completed, h.steps - 1)))}",
                f"length error (Fig. 8) = {_fmt(_ratio(length_error(h), h))}",
                f"rest-length error (Fig. 9) = {_fmt(_ratio(rest_length_error(h), h))}",
            ]
        if exp.name == "gpc_frozen":
            # distance of the target strain from the desired one, final over initial
            d = np.stack(
                [
                    np.abs(h.target_strain[i, :, 0] - h.tasks[i].target_strain[0])
                    for i in range(h.trials)
                ]
            )
            measured.append(f"|S - S_T| / |S0 - S_T| = {_fmt(_ratio(d, h))}")
        settings = {k: v for k, v in h.settings.items() if not k.startswith("solver.")}
        rows.append(
            {
                "experiment": exp.name,
                "figures": exp.figures,
                "claim": exp.claim,
                "measured": "; ".join(measured),
                "trials": f"{h.trials} ({stopped} stopped early; their last values are used)",
                "settings": ", ".join(
                    f"{k}={settings[k]}"
                    for k in (
                        "rule",
                        "strain_reference",
                        "alpha",
                        "eta",
                        "learn_targets",
                        "min_rest_length",
                        "steps",
                    )
                    if k in settings
                )
                + (f", solver={solver_name}" if solver_name else ""),
            }
        )
    return rows


def markdown(rows: Sequence[dict[str, str]]) -> str:
    """A Markdown table of :func:`table` rows."""
    if not rows:
        return ""
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        lines.append("| " + " | ".join(str(row[k]).replace("|", "/") for k in keys) + " |")
    return "\n".join(lines)


def verification(
    *,
    trials: int = 10,
    etas: Sequence[float] = (1e-1, 1e-2, 1e-3, 1e-4),
    fd_step: float = 1e-5,
) -> dict[str, NDArray]:
    """Coupled learning against the exact gradient on ``trials`` paper networks.

    Returns arrays (trials, len(etas)) ``rel_initial`` / ``cos_initial``: relative error
    and cosine of ``GCL / alpha`` against ``-K L0^2 dC/dL`` (strains against the initial
    ``L``, where ``C`` is a length cost; ``K`` is the target's effective stiffness);
    ``rel_frozen`` / ``cos_strain``: with strains against the learning ``L``, against
    the gradient of the frozen-reference length cost (:func:`~..learning.sensitivity.gcl_limit`)
    and the cosine with ``-dC/dL`` of Eq. 26 itself; and ``fd`` (trials,): the median
    relative error of the exact gradient of Eq. 26 (learning ``L``) against central
    finite differences with step ``fd_step * mean(L)``.
    """
    from ..learning.metrics import cosine, relative_error
    from ..learning.sensitivity import Sensitivity, cost_gradient, gcl_limit
    from ..learning.states import Tracker
    from ..network.equilibrium import relax

    out = {
        k: np.full((trials, len(etas)), np.nan)
        for k in ("rel_initial", "cos_initial", "rel_frozen", "cos_strain")
    }
    out["fd"] = np.full(trials, np.nan)
    for i in range(trials):
        rng = np.random.default_rng(np.random.SeedSequence(i).spawn(2)[0])
        net = _network(rng)
        task = paper_task(net, rng)
        for j, eta in enumerate(etas):
            for ref in ("initial", "current"):
                step = CoupledLearning(
                    1.0, eta, strain_reference=ref, learn_sources=True, learn_targets=True
                ).update(net, task)
                if ref == "initial":
                    sens = Sensitivity(net, task.pinned, task.source_clamps(net, ref), step.free)
                    K = 1.0 / sens.compliance(task.targets)[0, 0]
                    grad = cost_gradient(
                        net, task, step.free, strain_reference=ref, sensitivity=sens
                    )
                    reference = -K * task.target_rest_length[0] ** 2 * grad
                    out["rel_initial"][i, j] = relative_error(step.raw, reference)
                    out["cos_initial"][i, j] = cosine(step.raw, reference)
                else:
                    limit, _ = gcl_limit(net, task, step.free, strain_reference=ref)
                    out["rel_frozen"][i, j] = relative_error(step.raw, limit)
                    grad = cost_gradient(net, task, step.free, strain_reference=ref)
                    out["cos_strain"][i, j] = cosine(step.raw, -grad)
        free = Tracker().solve(net, task.pinned, task.source_clamps(net, "current"), None)
        grad = cost_gradient(net, task, free, strain_reference="current")
        h = fd_step * float(np.mean(net.rest_length))

        def error(L, net=net, task=task, free=free):
            n = net.with_rest_length(L)
            eq = relax(
                n,
                pinned=task.pinned,
                clamped=task.source_clamps(n, "current"),
                x0=free.positions,
                tol=1e-13,
            )
            return task.error(n, eq.positions, "current")

        fd = np.array(
            [
                (error(net.rest_length + h * e) - error(net.rest_length - h * e)) / (2 * h)
                for e in np.eye(net.n_springs)
            ]
        )
        out["fd"][i] = np.median(np.abs(grad - fd) / np.max(np.abs(fd)))
    return out
