"""Learning scenes: the paper's claims (or the Stern-scale table), error against steps and
seconds, the paper's figures from this package's runs, the studies and the renders.

This module writes the section in order; its parts: :mod:`.checks` (the paper's claims judged
by rule, whether the stored states are equilibria, how the checks word conventions, labels and
captions), :mod:`.coupling` (coupling of every trained network), :mod:`.noise` (the read-out
noise floor), :mod:`.paper` (the paper scene in its own setting), :mod:`.studies` (source
sweeps, the exact gradient, read-out noise, solvers compared).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ...document import (
    SHORT_NAMES,
    SOLVER_NAMES,
    Document,
    normalised,
    quiet,
    stats,
)
from ...figures import COLORS, Panel, Series
from ..renders import learning_renders
from .checks import (
    CONVENTION_TEXT,
    claims,
    curve_caption,
    error_label,
)
from .coupling import coupling
from .noise import noise_floor
from .studies import gradient, noise, solver_comparison, sweeps


def section(doc: Document, result) -> None:
    """The learning section: claims or Stern table, error figures, studies, renders."""
    from ....learning.metrics import length_error, rest_length_error
    from ....scenes.units_learning import run_names

    scene = result.scene
    L = scene.learning
    solvers = scene.solver.methods if scene.solver is not None else ("newton",)
    H = result.histories
    names = run_names(scene)
    ref = L.strain_reference

    def h(solver: str, rule: str, i: int = 0):
        return H[f"{solver}/{rule}/noise{i}"]

    first = solvers[0]
    doc.add(
        f"{L.trials} trials x {L.steps} learning steps for each of "
        f"{', '.join(f'`{r}`' for r in names)}; states by "
        f"{' and '.join(SOLVER_NAMES[s] for s in solvers)}; strain convention "
        f"{CONVENTION_TEXT[ref]}; C below is Eq. 26 in that convention unless a column "
        "says otherwise."
    )
    stopped = [
        (f"{s}/{r}/noise{i}", h(s, r, i).stop_causes())
        for s in solvers
        for r in names
        for i in range(len(L.noise))
    ]
    if any(causes for _, causes in stopped):
        doc.add(
            "",
            "Trials that stopped early, with the causes read off their stop reasons: "
            + "; ".join(
                f"{k}: {sum(causes.values())} ("
                + ", ".join(f"{cause}: {n}" for cause, n in causes.items())
                + ")"
                for k, causes in stopped
                if causes
            )
            + ". The error-vs-step figure holds them at their last measured value; the "
            "paper's mean figures end at the last step every trial measured.",
        )

    feas: dict = {}
    if scene.task.kind == "paper":
        if L.paper_setting:
            from .paper import feasibility, setting_table

            setting_table(doc, h, first, names)
        notes = claims(doc, result, h, solvers)
        if L.paper_setting:
            feas = feasibility(doc, result, h, first, names[0])
    else:
        notes = {}
        from ....scenes.stern import stern_table

        doc.heading("Stern-scale allostery")
        for solver in solvers:
            rows = stern_table({(scene.network.n_nodes, r): h(solver, r) for r in names})
            if rows:
                doc.table(list(rows[0]), [list(r.values()) for r in rows])
        what = (
            "summed error of the task and its rest example (sources at zero strain, targets "
            "asked to stay at their untrained strains: `[task] anchored`)"
            if scene.task.anchored
            else "task error"
        )
        doc.add(
            f"{scene.task.n_sources} sources, {scene.task.n_targets} targets; `C/C0` is "
            f"the final over the initial {what}, {error_label(ref)} (median "
            "[quartiles]). Whether a low C/C0 is learned or trivial: next section."
        )
    coupling(doc, result, h, solvers, names, notes=notes)
    if scene.task.kind == "paper" and L.paper_setting:
        from .paper import explanations

        explanations(doc, result, h, first, feas)

    doc.heading("Error against iterations and against wall-clock time")
    panels, held = [], []
    for solver in solvers:
        step_series, time_series = [], []
        for j, rule in enumerate(names):
            hist = h(solver, rule)
            st = stats(held_at_last(hist, normalised(hist.task_error(ref))))
            held.append((f"{solver}/{rule}" if len(solvers) > 1 else rule, hist))
            steps = np.arange(hist.steps + 1)
            secs = quiet(np.nanmedian, hist.seconds, axis=0)
            color = COLORS[j % len(COLORS)]
            step_series.append(Series(steps, st["median"], rule, st["q25"], st["q75"], color=color))
            time_series.append(Series(secs, st["median"], rule, st["q25"], st["q75"], color=color))
        name = SHORT_NAMES[solver]
        panels += [
            Panel(
                step_series,
                f"{name}: error vs learning step",
                "learning step",
                "C / C0 (median, quartiles)",
                yscale="log",
                hlines=(1.0,),
            ),
            Panel(
                time_series,
                f"{name}: error vs wall-clock time",
                "seconds (median trial)",
                "C / C0",
                xscale="log",
                yscale="log",
                hlines=(1.0,),
            ),
        ]
    doc.figure(
        "error",
        panels,
        f"Task error {error_label(ref)}, normalised by its initial value, against "
        "learning steps and against wall-clock seconds; line: median over trials, band: "
        "quartiles. " + _held_note(held),
    )

    if scene.task.kind == "paper":
        _paper_figures(doc, scene, h, first, length_error, rest_length_error)
    if L.sweeps:
        sweeps(doc, result, first)
    if L.compare_gradient:
        gradient(doc, result, h)
    if len(L.noise) > 1 and L.etas:
        noise_floor(doc, result, h, first, names)
    elif len(L.noise) > 1:
        noise(doc, result, h, first)
    if len(solvers) > 1:
        solver_comparison(doc, result, h, solvers)
    _trials_appendix(doc, scene, h, first)
    if scene.report.images or scene.export is not None:
        learning_renders(doc, result)


def held_at_last(hist, values: NDArray) -> NDArray:
    """``values`` (trials, steps + 1) with each trial that stopped held at its last
    measured value (:func:`~continuum_vs_network.learning.metrics.final_values`, the
    tables' final value) from its last measurement
    (:func:`~continuum_vs_network.report.verdicts.claims.last_measured`) on, so that a median
    over trials at every step is over all of them."""
    from ....learning.metrics import final_values
    from ...verdicts.claims import last_measured

    out = np.array(values, dtype=np.float64)
    last = np.minimum(last_measured(hist), out.shape[1] - 1)
    final = final_values(out, hist.completed)
    for i in range(out.shape[0]):
        if np.isfinite(final[i]):
            out[i, last[i] :] = final[i]
    return out


def _held_note(runs) -> str:
    """Caption sentence: how many trials of each run stopped early (held at their last
    measured value in the median)."""
    from ...verdicts.claims import last_measured

    stopped = [(name, int(np.sum(last_measured(h) < h.steps)), h.trials) for name, h in runs]
    parts = [f"{name} {n} of {trials}" for name, n, trials in stopped if n]
    if not parts:
        return f"Every trial ran all {runs[0][1].steps if runs else 0} steps."
    return (
        "A trial that stopped is held at its last measured value (its final value in the "
        f"tables); trials that stopped before step {runs[0][1].steps}: " + ", ".join(parts) + "."
    )


def _common_steps(hist) -> int:
    """Last measurement index every trial reached (curves over trials stop there): the
    smallest :func:`~continuum_vs_network.report.verdicts.claims.last_measured` (a trial that lost
    its equilibrium at step ``completed`` has no measurement there)."""
    from ...verdicts.claims import last_measured

    return int(np.min(last_measured(hist))) if hist.trials else 0


def _ends_note(hist) -> str:
    """Caption sentence when trials stopped early (else empty)."""
    last = _common_steps(hist)
    if last >= hist.steps:
        return ""
    return (
        f" The curves end at step {last}, the last step all {hist.trials} trials measured "
        "(a mean over the trials still running would jump)."
    )


#: a mean over trials is "carried by a few trials" when it exceeds the median this many times
MEAN_OVER_MEDIAN = 10.0


def _final_ratios(hist, values: NDArray) -> NDArray:
    from ....learning.metrics import final_values

    return final_values(normalised(values), hist.completed)


def mean_note(final: NDArray) -> str:
    """Caption sentence when the mean of the trials' final values exceeds
    :data:`MEAN_OVER_MEDIAN` x their median: which trials carry it (else empty)."""
    x = np.asarray(final, dtype=float)
    x = x[np.isfinite(x)]
    if not x.size:
        return ""
    mean, med = float(np.mean(x)), float(np.median(x))
    if not mean > MEAN_OVER_MEDIAN * abs(med):
        return ""
    big = x[x > MEAN_OVER_MEDIAN * abs(med)]
    return (
        f" The final mean ({mean:.3g}) is {mean / med if med else float('inf'):.3g} x the "
        f"median ({med:.3g}): it is carried by {big.size} of {x.size} trials whose final "
        f"value exceeds {MEAN_OVER_MEDIAN:g} x the median (largest {big.max():.3g})."
    )


def _mean_panel(hist, title: str, values: NDArray, ylabel: str, *, truncate: bool = True) -> Panel:
    """Mean (with one standard deviation) and median over trials; with ``truncate`` the
    curves end at the last step every trial measured (else ``values`` must hold stopped
    trials at their last value, :func:`held_at_last`)."""
    st = stats(normalised(values))
    steps = np.arange(values.shape[1])
    if truncate:
        beyond = steps > _common_steps(hist)  # fewer trials there: another population
        for v in st.values():
            v[beyond[: v.shape[0]]] = np.nan
    return Panel(
        [
            Series(
                steps,
                st["mean"],
                "mean (as the paper)",
                st["mean"] - st["std"],
                st["mean"] + st["std"],
            ),
            Series(steps, st["median"], "median", style="--"),
        ],
        title,
        "learning step",
        ylabel,
        yscale="log",
        hlines=(1.0,),
    )


def _paper_figures(doc: Document, scene, h, solver: str, length_error, rest_length_error) -> None:
    rules = scene.learning.rules
    doc.heading("The paper's figures from this package's runs")
    doc.add(
        "Means over trials with one standard deviation (the paper plots the mean) and "
        "medians; on a log axis the band is drawn where mean - std > 0."
    )
    for rule, fig in (
        ("gcl", "Fig. 4"),
        ("gcl_notebook", "Fig. 4 (notebook's sign)"),
        ("gcl_floor", "Fig. 4 (with a floor)"),
        ("gpc", "Fig. 6"),
        ("gpc_frozen", "Fig. 10"),
    ):
        if rule in rules:
            hist = h(solver, rule)
            # the paper's metric (Eq. 26 as printed, learning L): the one its claims are
            # judged on, whatever the run's convention
            values = hist.error_current
            held = held_at_last(hist, values)  # stopped trials at their last value
            doc.figure(
                f"{rule}_mean",
                [_mean_panel(hist, f"{fig}: {rule}", held, "C / C0 (learning L)", truncate=False)],
                f"{fig}: normalised error of {rule}, {error_label('current')}, the metric "
                f"of the paper's claims ({hist.trials} trials, {hist.steps} steps). "
                + _held_note([(rule, hist)])
                + mean_note(_final_ratios(hist, values)),
                ncols=1,
            )
    if "gpc" in rules:
        hist = h(solver, "gpc")
        steps = np.arange(hist.steps)
        doc.figure(
            "gpc_energy",
            [
                Panel(
                    [Series(steps, hist.energy_clamped[0], "trial 0")],
                    "Fig. 7a: clamped energy E^C",
                    "learning step",
                    "E^C",
                    yscale="log",
                ),
                Panel(
                    [Series(steps, hist.energy_gradient_clamped[0], "trial 0")],
                    "Fig. 7b: |dE^C/dL|",
                    "learning step",
                    "|dE/dL|",
                    yscale="log",
                ),
            ],
            "Fig. 7 (trial 0): "
            + curve_caption("the clamped energy E^C", hist.energy_clamped[0])
            + "; "
            + curve_caption("|dE^C/dL|", hist.energy_gradient_clamped[0])
            + ".",
        )
        doc.figure(
            "gpc_lengths",
            [
                _mean_panel(
                    hist,
                    "Fig. 8: target length error",
                    length_error(hist),
                    "sum |r_T - l_T| / initial",
                ),
                _mean_panel(
                    hist,
                    "Fig. 9: target rest-length error",
                    rest_length_error(hist),
                    "sum |L_T - l_T| / initial",
                ),
            ],
            "Fig. 8-9: distance of the target's free length (8) and rest length (9) from the "
            "length that gives the desired strain, normalised." + _ends_note(hist),
        )
        trials = [
            Series(steps, hist.energy_clamped[i], f"trial {i}", width=1.0)
            for i in range(hist.trials)
        ]
        le, rle = length_error(hist), rest_length_error(hist)
        s1 = np.arange(hist.steps + 1)
        doc.figure(
            "gpc_appendix",
            [
                Panel(
                    trials,
                    "A.3 B: E^C of every trial",
                    "learning step",
                    "E^C",
                    yscale="log",
                    legend=False,
                ),
                Panel(
                    [Series(s1, le[i], width=1.0) for i in range(hist.trials)],
                    "A.3 C: length error, unscaled",
                    "learning step",
                    "sum |r_T - l_T|",
                    yscale="log",
                    legend=False,
                ),
                Panel(
                    [Series(s1, rle[i], width=1.0) for i in range(hist.trials)],
                    "A.3 D: rest-length error, unscaled",
                    "learning step",
                    "sum |L_T - l_T|",
                    yscale="log",
                    legend=False,
                ),
            ],
            "Appendix A.3 B-D: every GPC trial.",
            ncols=3,
        )


def _trials_appendix(doc: Document, scene, h, solver: str) -> None:
    from ....scenes.units_learning import run_names

    panels = []
    for rule in run_names(scene):
        hist = h(solver, rule)
        steps = np.arange(hist.steps + 1)
        err = hist.task_error(hist.strain_reference)
        panels.append(
            Panel(
                [Series(steps, err[i], width=1.0) for i in range(hist.trials)],
                f"{rule}: C of every trial",
                "learning step",
                error_label(hist.strain_reference),
                yscale="log",
                legend=False,
            )
        )
    doc.heading("Appendix: the unscaled error of every trial")
    doc.figure(
        "trials",
        panels,
        "Unscaled task error of every trial (appendix A.2 A, A.3 A).",
        ncols=min(3, len(panels)),
    )
