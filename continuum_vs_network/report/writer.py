"""The report writer: ``reports/<scene>/report.md`` with its figures, and the index.

:func:`write_report` reads a :class:`~continuum_vs_network.scenes.runner.SceneResult` (it
runs nothing) and writes a Markdown report with matplotlib figures and, when the scene asks
for images and off-screen rendering works, pyvista renders. Every file is written
atomically; figures of an earlier report that the new one does not use are removed.
:func:`write_index` writes ``reports/README.md`` listing every report found.

Sections by scene kind:

* learning: the paper's claim / measured here / settings table (paper task), error against
  iterations *and* against wall-clock seconds for every rule and solver, the paper's
  Figs. 4-10 and appendix figures drawn from this package's runs, source sweeps, the
  exact-gradient comparison, noise robustness, the equilibrium-solver comparison and the
  Stern-scale table;
* transmission: strain against distance in the network and the continuum, decay exponents,
  network against continuum strain;
* relaxation: relaxation time against size (network, continuum; slowest mode and measured),
  the decay of the displacement against time;
* stability: converged / residual / time / the error raised, for every case and method;
* solvers: residual against iterations and against seconds, the work-precision figure;
* every report: settings (the scene), renders, meshes written, provenance.
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..io.atomic import write_text_atomic
from .figures import COLORS, Panel, Series, heatmap, plot_panels

__all__ = ["write_index", "write_report"]

_META = "report.json"


class _Doc:
    """Markdown lines and the files written for one report."""

    def __init__(self, folder: Path, dpi: int) -> None:
        self.folder = folder
        self.dpi = dpi
        self.lines: list[str] = []
        self.files: list[Path] = []

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def heading(self, text: str, level: int = 2) -> None:
        self.lines.extend(["", "#" * level + " " + text, ""])

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
        if self.lines and self.lines[-1] != "":
            self.lines.append("")
        self.lines.append("| " + " | ".join(headers) + " |")
        self.lines.append("|" + "---|" * len(headers))
        for row in rows:
            self.lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in row) + " |")
        self.lines.append("")

    def figure(self, name: str, panels: Sequence[Panel], caption: str, **kw: Any) -> None:
        path = plot_panels(panels, self.folder / f"fig_{name}.png", dpi=self.dpi, **kw)
        self.image(path, caption)

    def image(self, path: Path, caption: str) -> None:
        self.files.append(path)
        self.lines.extend(["", f"![{caption}]({path.name})", "", f"*{caption}*", ""])


# -- numbers ---------------------------------------------------------------------------------
def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fn(*args, **kw)


def _stats(a: NDArray) -> dict[str, NDArray]:
    """Per-column median, quartiles, mean, std over rows (trials), NaN-aware."""
    a = np.asarray(a, dtype=float)
    return {
        "median": _quiet(np.nanmedian, a, axis=0),
        "q25": _quiet(np.nanpercentile, a, 25, axis=0),
        "q75": _quiet(np.nanpercentile, a, 75, axis=0),
        "mean": _quiet(np.nanmean, a, axis=0),
        "std": _quiet(np.nanstd, a, axis=0),
    }


def _normalised(values: NDArray) -> NDArray:
    v = np.asarray(values, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return v / v[:, :1]


def _g(x: float, digits: int = 3) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


def _summary_text(values: NDArray, completed: NDArray | None = None) -> str:
    from ..learning.metrics import summary

    s = summary(values, completed)
    if not s.get("n"):
        return "no finite value"
    text = f"{_g(s['median'])} [{_g(s['q25'])}, {_g(s['q75'])}]"
    if s.get("missing"):
        text += f" ({s['missing']} missing)"
    return text


# -- settings and provenance ---------------------------------------------------------------
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def scene_toml(scene_dict: dict[str, Any]) -> str:
    """The scene as TOML text (every key, defaults included; unset keys left out)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in scene_dict.items() if not isinstance(v, dict)]
    for table, values in scene_dict.items():
        if isinstance(values, dict):
            lines.append(f"\n[{table}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in values.items() if v is not None]
    return "\n".join(lines)


def _provenance(doc: _Doc, result) -> None:
    p = result.provenance
    doc.heading("Provenance")
    doc.table(
        ["item", "value"],
        [
            ["package version", p.version],
            ["git commit", f"`{p.commit}`"],
            ["python / numpy / scipy", f"{p.python} / {p.numpy} / {p.scipy}"],
            ["platform", p.platform],
            ["command", f"`{p.command}`"],
            [
                "seeds",
                ", ".join(map(str, p.seeds))
                if len(p.seeds) <= 12
                else f"{p.seeds[0]} ... {p.seeds[-1]} ({len(p.seeds)})",
            ],
            ["started", p.started],
            ["wall time of the completing run", f"{p.wall_seconds:.1f} s"],
            ["compute time (sum over units)", f"{p.compute_seconds:.1f} s"],
            ["units (reused from an earlier run)", f"{p.units} ({p.reused})"],
            ["worker processes", str(p.workers)],
            ["scene file", f"`{_short_source(result.scene.source)}`"],
        ],
    )


def _short_source(source: str) -> str:
    parts = Path(source).parts
    if "continuum_vs_network" in parts:
        i = len(parts) - 1 - parts[::-1].index("continuum_vs_network")
        return "/".join(parts[i:])
    return source


# -- learning --------------------------------------------------------------------------------
def _learning(doc: _Doc, result) -> None:
    from ..learning.metrics import length_error, rest_length_error

    scene = result.scene
    L = scene.learning
    solvers = scene.solver.methods if scene.solver is not None else ("newton",)
    H = result.histories

    def h(solver: str, rule: str, i: int = 0):
        return H[f"{solver}/{rule}/noise{i}"]

    first = solvers[0]
    doc.add(
        f"{L.trials} trials x {L.steps} learning steps for each of "
        f"{', '.join(f'`{r}`' for r in L.rules)}; equilibria by "
        f"{' and '.join(_SOLVER_NAMES[s] for s in solvers)}; strain convention "
        f"`{L.reference}`."
    )
    stopped = [
        (f"{s}/{r}", int(np.sum(h(s, r).completed < L.steps))) for s in solvers for r in L.rules
    ]
    if any(n for _, n in stopped):
        doc.add(
            "",
            "Trials that stopped early (a rest length would reach 0 without a floor, or "
            "an equilibrium was lost): "
            + ", ".join(f"{k}: {n}" for k, n in stopped if n)
            + ". Their curves end there.",
        )

    if scene.task.kind == "paper":
        from ..learning.replication import table
        from ..scenes.units_learning import experiments

        doc.heading("The paper's claims and what this package measures")
        doc.add(
            "Medians over trials of final-over-initial ratios, quartiles in brackets "
            "(`C/C0` is Eq. 26)."
        )
        for solver in solvers:
            rows = table(
                {r: h(solver, r) for r in L.rules}, experiments(scene, solver), solver_name=solver
            )
            doc.add("", f"**{_SOLVER_NAMES[solver]}**", "")
            if rows:
                doc.table(list(rows[0]), [list(r.values()) for r in rows])
    else:
        from ..learning.stern import stern_table

        doc.heading("Stern-scale allostery")
        for solver in solvers:
            rows = stern_table({(scene.network.n_nodes, r): h(solver, r) for r in L.rules})
            if rows:
                doc.table(list(rows[0]), [list(r.values()) for r in rows])
        doc.add(
            f"{scene.task.n_sources} sources, {scene.task.n_targets} targets; `C/C0` is "
            "the final over the initial task error (median [quartiles])."
        )

    doc.heading("Error against iterations and against wall-clock time")
    panels = []
    for solver in solvers:
        step_series, time_series = [], []
        for j, rule in enumerate(L.rules):
            hist = h(solver, rule)
            st = _stats(_normalised(hist.error))
            steps = np.arange(hist.steps + 1)
            secs = _quiet(np.nanmedian, hist.seconds, axis=0)
            color = COLORS[j % len(COLORS)]
            step_series.append(Series(steps, st["median"], rule, st["q25"], st["q75"], color=color))
            time_series.append(Series(secs, st["median"], rule, st["q25"], st["q75"], color=color))
        name = _SHORT_NAMES[solver]
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
        "Task error (Eq. 26, normalised by its initial value) against "
        "learning steps and against wall-clock seconds; line: median over trials, band: "
        "quartiles.",
    )

    if scene.task.kind == "paper":
        _paper_figures(doc, scene, h, first, length_error, rest_length_error)
    if L.sweeps:
        _sweeps(doc, result, first)
    if L.compare_gradient:
        _gradient(doc, result, h)
    if len(L.noise) > 1:
        _noise(doc, result, h, first)
    if len(solvers) > 1:
        _solver_comparison(doc, result, h, solvers)
    _trials_appendix(doc, scene, h, first)


_SHORT_NAMES = {
    "newton": "exact (Newton)",
    "paper": "paper's Adagrad",
    "fire": "FIRE",
    "lbfgs": "L-BFGS",
}
_SOLVER_NAMES = {
    "newton": "exact equilibria (Newton)",
    "paper": "the paper's relaxation (Adagrad, rods)",
    "fire": "FIRE",
    "lbfgs": "L-BFGS",
}


def _mean_panel(hist, title: str, values: NDArray, ylabel: str) -> Panel:
    st = _stats(_normalised(values))
    steps = np.arange(values.shape[1])
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


def _paper_figures(doc: _Doc, scene, h, solver: str, length_error, rest_length_error) -> None:
    rules = scene.learning.rules
    doc.heading("The paper's figures from this package's runs")
    doc.add(
        "Means over trials with one standard deviation (the paper plots the mean) and "
        "medians; on a log axis the band is drawn where mean - std > 0."
    )
    for rule, fig in (
        ("gcl", "Fig. 4"),
        ("gcl_floor", "Fig. 4 (with a floor)"),
        ("gpc", "Fig. 6"),
        ("gpc_frozen", "Fig. 10"),
    ):
        if rule in rules:
            hist = h(solver, rule)
            doc.figure(
                f"{rule}_mean",
                [_mean_panel(hist, f"{fig}: {rule}", hist.error, "C / C0")],
                f"{fig}: normalised error of {rule} ({hist.trials} trials).",
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
            "Fig. 7: GPC descends the clamped energy and its gradient (trial 0).",
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
            "length that gives the desired strain, normalised.",
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


def _trials_appendix(doc: _Doc, scene, h, solver: str) -> None:
    rules = scene.learning.rules
    panels = []
    for rule in rules:
        hist = h(solver, rule)
        steps = np.arange(hist.steps + 1)
        panels.append(
            Panel(
                [Series(steps, hist.error[i], width=1.0) for i in range(hist.trials)],
                f"{rule}: C of every trial",
                "learning step",
                "C (Eq. 26)",
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


def _sweeps(doc: _Doc, result, solver: str) -> None:
    doc.heading("Source sweeps (Fig. 5 and appendix B)")
    doc.add(
        "The trained network's target strain for other source strains (blue) against the "
        "trivial, decoupled response that stays at the desired strain (orange); the "
        "black dot is the trained point."
    )
    for rule in result.scene.learning.rules:
        u = result.units[f"sweeps/{solver}/{rule}"]
        a = u.arrays
        panels = []
        for i in range(a["source_strain"].shape[0]):
            s, t = a["source_strain"][i], a["target_strain"][i]
            panels.append(
                Panel(
                    [
                        Series(s, t, "network", marker="o"),
                        Series(s, np.full_like(s, a["desired"][i]), "decoupled", style="--"),
                        Series(
                            [a["task_source"][i]],
                            [a["desired"][i]],
                            "trained",
                            style="",
                            marker="o",
                            color="black",
                        ),
                    ],
                    f"{rule}, trial {i}",
                    "source strain",
                    "target strain",
                    legend=(i == 0),
                )
            )
        doc.figure(
            f"sweeps_{rule}",
            panels,
            f"Source sweeps of {rule} (every trial; Fig. 5 is trial 0).",
            ncols=5,
            panel_size=(2.8, 2.3),
        )


def _gradient(doc: _Doc, result, h) -> None:
    doc.heading("Comparison with the exact gradient")
    doc.add(
        "Cosine between each rule's learning step and the exact gradient step "
        "(`ExactGradient`, the same springs learning, exact equilibria) at every trial's "
        "initial and final network; 1 means the local rule moves the rest lengths exactly "
        "downhill on the task error."
    )
    rows = []
    for u in result.select("gradient/").values():
        c = u.arrays["cosine"]
        rows.append([u.meta["rule"], _cos_text(c[:, 0]), _cos_text(c[:, 1]), u.meta["cost"]])
    doc.table(
        [
            "rule",
            "cos at the initial network: median [min, max]",
            "cos at the final network",
            "cost",
        ],
        rows,
    )
    if "exact" in result.scene.learning.rules:
        solver = (result.scene.solver.methods if result.scene.solver else ("newton",))[0]
        rows = [
            [r, _summary_text(h(solver, r).error, h(solver, r).completed)]
            for r in result.scene.learning.rules
        ]
        doc.add(
            "Final `C/C0` of every rule next to the exact gradient's (what the task allows "
            "with these steps):",
            "",
        )
        doc.table(["rule", "final C/C0 median [quartiles]"], rows)


def _cos_text(c: NDArray) -> str:
    ok = c[np.isfinite(c)]
    if not ok.size:
        return "-"
    return f"{np.median(ok):.3f} [{ok.min():.3f}, {ok.max():.3f}]"


def _noise(doc: _Doc, result, h, solver: str) -> None:
    from ..learning.metrics import final_values

    L = result.scene.learning
    doc.heading("Robustness to read-out noise")
    doc.add(
        "Every length a rule reads is `r (1 + noise xi)`, `xi ~ N(0, 1)`; the error is "
        "measured without noise."
    )
    series, rows = [], []
    levels = np.array(L.noise)
    positive = levels[levels > 0]
    x0 = positive.min() / 10 if positive.size else 1e-4
    xs = np.where(levels > 0, levels, x0)
    for j, rule in enumerate(L.rules):
        med, lo, hi, cells = [], [], [], []
        for i in range(len(L.noise)):
            hist = h(solver, rule, i)
            f = final_values(_normalised(hist.error), hist.completed)
            f = f[np.isfinite(f)]
            med.append(np.median(f) if f.size else np.nan)
            lo.append(np.quantile(f, 0.25) if f.size else np.nan)
            hi.append(np.quantile(f, 0.75) if f.size else np.nan)
            cells.append(_summary_text(hist.error, hist.completed))
        series.append(Series(xs, med, rule, lo, hi, marker="o", color=COLORS[j % 10]))
        rows.append([rule, *cells])
    doc.figure(
        "noise",
        [
            Panel(
                series,
                "final error against read-out noise",
                f"noise (0 drawn at {x0:g})",
                "final C / C0",
                xscale="log",
                yscale="log",
                hlines=(1.0,),
            )
        ],
        "Final normalised error (median, quartiles) against the read-out noise.",
        ncols=1,
    )
    doc.table(["rule", *[f"noise {n:g}" for n in L.noise]], rows)


def _solver_comparison(doc: _Doc, result, h, solvers: Sequence[str]) -> None:
    L = result.scene.learning
    doc.heading("Exact equilibria against the paper's relaxation")
    doc.add("The same networks and tasks (same seeds), trained with each equilibrium solver.")
    rows, panels = [], []
    for rule in L.rules:
        cells = []
        step_s, time_s = [], []
        for j, solver in enumerate(solvers):
            hist = h(solver, rule)
            done = np.maximum(hist.completed, 1)
            last = np.array(
                [hist.seconds[i, min(hist.completed[i], hist.steps)] for i in range(hist.trials)]
            )
            cells += [_summary_text(hist.error, hist.completed), _g(float(np.median(last / done)))]
            st = _stats(_normalised(hist.error))
            style = "-" if j == 0 else "--"
            step_s.append(
                Series(
                    np.arange(hist.steps + 1),
                    st["median"],
                    solver,
                    st["q25"],
                    st["q75"],
                    style=style,
                    color=COLORS[j],
                )
            )
            time_s.append(
                Series(
                    _quiet(np.nanmedian, hist.seconds, axis=0),
                    st["median"],
                    solver,
                    style=style,
                    color=COLORS[j],
                )
            )
        rows.append([rule, *cells])
        panels += [
            Panel(step_s, f"{rule}: vs step", "learning step", "C / C0", yscale="log"),
            Panel(time_s, f"{rule}: vs seconds", "seconds", "C / C0", xscale="log", yscale="log"),
        ]
    headers = ["rule"]
    for s in solvers:
        headers += [f"{s}: final C/C0", f"{s}: s/step"]
    doc.table(headers, rows)
    doc.figure(
        "solvers",
        panels,
        "Error against learning steps and wall-clock seconds with "
        "each equilibrium solver (median, quartiles).",
        ncols=2,
    )


def _learning_renders(doc: _Doc, result, render: bool, reason: str) -> None:
    units = result.select("fields/")
    if not units:
        return
    doc.heading("Renders")
    if not render:
        doc.add(f"Renders skipped: {reason}.")
        return
    from ..io.render import render_network
    from ..network.model import SpringNetwork

    # one trial (the first exported) per rule; every rule starts from the same network, so
    # the initial state is drawn once; one colour scale for every image
    todo = []
    for j, (key, u) in enumerate(units.items()):
        a = u.arrays
        if not u.meta["trials"]:
            continue
        k = u.meta["trials"][0]
        for stage in ("initial", "final") if j == 0 else ("final",):
            p = f"t{k}/{stage}/"
            if p + "x" in a:
                net = SpringNetwork(
                    a[p + "positions"], a[p + "springs"], a[p + "stiffness"], a[p + "rest_length"]
                )
                todo.append(
                    (
                        key.split("/")[-1],
                        k,
                        stage,
                        net,
                        a[p + "x"],
                        np.asarray(a[f"t{k}/sources"], dtype=int),
                        a[f"t{k}/targets"],
                    )
                )
    if not todo:
        return
    # colour limits from the first image (the initial network when drawn), every spring but
    # the sources (clamped, they would dominate); a trained network may strain far more
    _, _, _, net0, x0, src0, _ = todo[0]
    clim = float(np.max(np.abs(np.delete(net0.strains(x0), src0)))) or 1.0
    for rule, k, stage, net, x, src, tgt in todo:
        label = rule if stage == "final" else "every rule"
        name = f"render_{rule}_t{k}_final.png" if stage == "final" else f"render_t{k}_initial.png"
        path = doc.folder / name
        render_network(
            net,
            x,
            path,
            sources=src,
            targets=tgt,
            clim=clim,
            window_size=(560, 560),
            line_width=3.0 if net.n_springs < 200 else 1.5,
            title=f"{label}, trial {k}, {stage} free state",
        )
        doc.image(
            path,
            f"{label}, trial {k}: {stage} network in its free state, springs "
            f"coloured by strain (limits +-{clim:.3g} in every image: the largest strain of "
            f"the {todo[0][2]} network but its sources; larger strains saturate); green: "
            "source, orange: target.",
        )


# -- transmission --------------------------------------------------------------------------
def _transmission(doc: _Doc, result) -> None:
    scene = result.scene
    units = result.select("transmission/")
    cont = scene.continuum is not None
    doc.add(
        f"The spring nearest the centre of an n x n triangular lattice (spacing 1, k = 1) "
        f"is clamped at strain {scene.task.strain:g}; every other spring's strain is read "
        "against its distance from the source"
        + (
            ", in the network and in the finite-element continuum of the same shape "
            f"(P{scene.continuum.order}, {scene.continuum.refine} refinement(s), "
            f"{scene.continuum.material} material, two rigid patches of radius "
            f"{scene.continuum.patch_radius:g} L moved apart)."
            if cont
            else "."
        )
    )
    rows = []
    panels = []
    for u in units.values():
        m, a = u.meta, u.arrays
        row = [m["n"], m["n_nodes"], _g(m["network_exponent"]), _g(m["network_seconds"])]
        floor = 1e-9 * float(np.max(np.abs(a["network_strain"])))
        series = [
            Series(
                a["distance"],
                _above(np.abs(a["network_strain"]), floor),
                "network",
                style="",
                marker=".",
                alpha=0.5,
            )
        ]
        if cont:
            row += [
                _g(m["continuum_exponent"]),
                _g(m["correlation"], 4),
                _g(m["continuum_seconds"]),
            ]
            series.append(
                Series(
                    a["distance"],
                    _above(np.abs(a["continuum_strain"]), floor),
                    "continuum",
                    style="",
                    marker=".",
                    alpha=0.5,
                )
            )
        r = np.linspace(1.0, float(np.max(a["distance"])), 50)
        ref = np.nanmedian(np.abs(a["network_strain"])[np.abs(a["distance"] - 2) < 0.6])
        series.append(Series(r, ref * (r / 2.0) ** -2, "r^-2", style="--", color="0.3"))
        panels.append(
            Panel(
                series,
                f"n = {m['n']} (N = {m['n_nodes']})",
                "distance from the source",
                "|strain|",
                xscale="log",
                yscale="log",
            )
        )
        rows.append(row)
    headers = ["n", "N", "network decay exponent", "network s"]
    if cont:
        headers += ["continuum decay exponent", "correlation network/continuum", "continuum s"]
    doc.table(headers, rows)
    doc.add(
        "Strains below 1e-9 of the largest (round-off; springs that only rotate) are not "
        "drawn. Decay exponents are fitted to |strain| binned in distance between 2 "
        "spacings and 0.3 n (a force dipole in an infinite 2D body decays as r^-2); '-' "
        "where the lattice is too small for a fit.",
        "",
    )
    doc.figure(
        "transmission",
        panels,
        "Strain against distance from the source spring.",
        ncols=min(3, len(panels)),
    )
    if cont:
        last = list(units.values())[-1]
        a = last.arrays
        doc.figure(
            "transmission_scatter",
            [
                Panel(
                    [
                        Series(
                            a["network_strain"],
                            a["continuum_strain"],
                            "springs",
                            style="",
                            marker=".",
                            alpha=0.5,
                        )
                    ],
                    f"n = {last.meta['n']}: every spring",
                    "network strain",
                    "continuum chord strain",
                    diagonal=True,
                )
            ],
            "Network against continuum strain of every spring (largest lattice).",
            ncols=1,
        )


def _above(values: NDArray, floor: float) -> NDArray:
    return np.where(values > floor, values, np.nan)


def _side_by_side(doc: _Doc, result, prefix: str, render: bool, reason: str, what: str) -> None:
    units = [u for u in result.select(prefix).values() if "net/x" in u.arrays]
    if not units:
        return
    doc.heading("Renders")
    if not render:
        doc.add(f"Renders skipped: {reason}.")
        return
    from ..io.render import render_network, render_side_by_side
    from ..network.model import SpringNetwork

    u = units[-1]
    a = u.arrays
    net = SpringNetwork(
        a["net/positions"], a["net/springs"], a["net/stiffness"], a["net/rest_length"]
    )
    x = a["net/x"]
    sources = a["net/sources"] if "net/sources" in a else ()
    strain = net.strains(x)
    others = np.delete(strain, np.asarray(sources, int)) if len(sources) else strain
    # a point source: saturate the near field so the far field shows; a uniform step: no
    fraction = 0.3 if len(sources) else 1.0
    clim = fraction * float(np.max(np.abs(others))) or 1.0
    n = u.meta["n"]
    if "cont/points" in a:
        path = doc.folder / f"render_{what}_n{n}.png"
        render_side_by_side(
            net,
            x,
            a["cont/points"],
            a["cont/triangles"],
            a["cont/displacement"],
            a["cont/principal"],
            path,
            sources=sources,
            network_clim=clim,
            continuum_clim=clim,
            window_size=(1100, 560),
            titles=(f"network n = {n}", "continuum"),
            network_bar_title="spring strain",
            continuum_bar_title="principal strain",
        )
        doc.image(
            path,
            f"n = {n}: spring strain of the network (left) and the largest "
            f"principal strain of the continuum (right), same colour limits +-{clim:.3g} "
            + (
                "(0.3 of the largest spring strain, source excluded; the near field saturates)."
                if len(sources)
                else "(the largest spring strain)."
            ),
        )
    else:
        path = doc.folder / f"render_{what}_n{n}_network.png"
        render_network(
            net,
            x,
            path,
            sources=sources,
            clim=clim,
            window_size=(560, 560),
            title=f"network n = {n}",
        )
        doc.image(path, f"n = {n}: spring strain of the network.")


# -- relaxation ----------------------------------------------------------------------------
def _relaxation(doc: _Doc, result) -> None:
    scene = result.scene
    dyn = scene.dynamics
    cont = scene.continuum is not None
    units = list(result.select("relaxation/").values())
    doc.add(
        f"The left side of an n x n triangular lattice (k = 1, unit node masses "
        f"{'with' if dyn.inertia else 'without'} inertia, node drag c = {dyn.damping:g}) is "
        f"held and the right side stepped inwards by {dyn.step:g} of the width; the "
        f"relaxation time is when the displacement to the final state stays below "
        f"{dyn.fraction:g} of its start. The slowest-mode time is 1 / (smallest decay "
        "rate) of the linearised equations."
        + (
            " The continuum has the node drag smeared over the area per node "
            f"(P{scene.continuum.order}, {scene.continuum.refine} refinement(s), "
            f"{scene.continuum.material} material)."
            if cont
            else ""
        )
    )
    n = np.array([u.meta["n"] for u in units], dtype=float)
    rows = []
    for u in units:
        m = u.meta
        row = [
            m["n"],
            m["n_nodes"],
            _g(m["network_tau_mode"]),
            _g(m["network_tau"]),
            _g(m["network_seconds"]),
        ]
        if cont:
            row += [
                _g(m["continuum_tau_mode"]),
                _g(m["continuum_tau"]),
                _g(m["continuum_seconds"]),
                m["continuum_dofs"],
            ]
        rows.append(row)
    headers = ["n", "N", "network slowest-mode time", "network relaxation time", "network s"]
    if cont:
        headers += [
            "continuum slowest-mode time",
            "continuum relaxation time",
            "continuum s",
            "continuum DOFs",
        ]
    doc.table(headers, rows)
    series = []
    fits = []
    names = [
        ("network_tau_mode", "network, slowest mode", "-"),
        ("network_tau", "network, measured", ""),
    ]
    if cont:
        names += [
            ("continuum_tau_mode", "continuum, slowest mode", "--"),
            ("continuum_tau", "continuum, measured", ""),
        ]
    for j, (k, label, style) in enumerate(names):
        t = np.array([u.meta[k] for u in units], dtype=float)
        ok = np.isfinite(t) & (t > 0)
        if ok.sum() >= 2:
            slope = np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)[0]
            fits.append(f"{label}: tau ~ n^{slope:.2f}")
            label = f"{label} (n^{slope:.2f})"
        series.append(
            Series(
                n, t, label, style=style or "", marker="o" if not style else "s", color=COLORS[j]
            )
        )
    curves = []
    for j, u in enumerate(units):
        a = u.arrays
        d = a["network_deviation"]
        curves.append(
            Series(a["network_times"], d / d[0], f"network n={u.meta['n']}", color=COLORS[j % 10])
        )
        if cont:
            c = a["continuum_deviation"]
            curves.append(
                Series(
                    a["continuum_times"],
                    c / c[0],
                    f"continuum n={u.meta['n']}",
                    style="--",
                    color=COLORS[j % 10],
                )
            )
    doc.figure(
        "relaxation",
        [
            Panel(
                series,
                "relaxation time against size",
                "n (lattice side)",
                "time",
                xscale="log",
                yscale="log",
            ),
            Panel(
                curves,
                "displacement to the final state",
                "time",
                "max |u(t) - u(end)| / start",
                yscale="log",
                hlines=(dyn.fraction,),
            ),
        ],
        "Left: relaxation times against the lattice side n (overdamped diffusion predicts "
        "n^2). Right: the relaxing displacement against time for every size.",
    )
    if fits:
        doc.add("Fitted scaling: " + "; ".join(fits) + ".")


# -- stability -----------------------------------------------------------------------------
def _stability(doc: _Doc, result) -> None:
    from ..scenes.units_solvers import case_name, cases

    scene = result.scene
    methods = scene.solver.methods
    doc.add(
        f"A {scene.network.size} x {scene.network.size} triangular lattice (position noise) "
        "with one spring clamped: `stiff_r` has a random "
        f"{scene.network.stiff_fraction:g} of the springs r times stiffer (a soft spring "
        f"clamped at strain {scene.task.strain:g}); `rod_k` clamps with the paper's rod of "
        "stiffness k; `strain_s` clamps exactly at the extreme strain s. Tolerance "
        f"{scene.solver.tol:g} (relative to mean(k) mean(L)), budget "
        f"{scene.solver.max_seconds:g} s per solve. Residuals are relative to the force "
        "scale, clamp errors to the mean rest length. For `stiff_r` the force scale "
        "grows with r, so the same relative tolerance is a looser absolute one."
    )
    rows, names, values, text = [], [], [], []
    for kind, value in cases(scene):
        name = case_name(kind, value)
        names.append(name)
        vrow, trow = [], []
        for method in methods:
            m = result.units[f"stability/{name}/{method}"].meta
            rows.append(
                [
                    name,
                    method,
                    "yes" if m["converged"] else "no",
                    _g(m["residual"]),
                    _g(m["clamp_error"]),
                    _g(m["seconds"]),
                    m["iterations"],
                    m["error"][:120] or "",
                ]
            )
            r = m["residual"]
            vrow.append(
                math.log10(r) if np.isfinite(r) and r > 0 else (-16.0 if r == 0 else np.nan)
            )
            trow.append(("ok " if m["converged"] else "FAIL ") + _g(m["seconds"], 2) + " s")
        values.append(vrow)
        text.append(trow)
    path = heatmap(
        values,
        names,
        list(methods),
        doc.folder / "fig_stability.png",
        text=text,
        title="residual / force scale (log10); converged and time",
        colorbar="log10 residual / F",
        dpi=doc.dpi,
    )
    doc.image(
        path,
        "Every stiff and extreme case against every method: colour is the final "
        "residual, text says whether the tolerance was met and how long it took.",
    )
    doc.table(
        [
            "case",
            "method",
            "converged",
            "residual / F",
            "clamp error / L",
            "seconds",
            "iterations",
            "error raised",
        ],
        rows,
    )


# -- solvers -----------------------------------------------------------------------------------
def _time_to(residual: NDArray, seconds: NDArray, tol: float) -> float:
    best = np.minimum.accumulate(residual)
    hit = np.flatnonzero(best <= tol)
    return float(seconds[hit[0]]) if hit.size else math.nan


def _solvers(doc: _Doc, result) -> None:
    scene = result.scene
    methods = scene.solver.methods
    sizes = scene.network.sizes
    doc.add(
        f"The spring nearest the centre of an n x n triangular lattice clamped at strain "
        f"{scene.task.strain:g}, solved by every method to a residual of "
        f"{scene.solver.tol:g} times the force scale within {scene.solver.max_seconds:g} s. "
        "Every method records its residual after each iteration and the wall-clock time it "
        "was reached (a warm-up solve first, so imports are not timed)."
    )
    rows = []
    it_panels, t_panels = [], []
    for n in sizes:
        it_s, t_s = [], []
        for j, method in enumerate(methods):
            u = result.units[f"solvers/n{n}/{method}"]
            a, m = u.arrays, u.meta
            it = np.arange(a["residual"].size)
            it_s.append(Series(it, a["residual"], method, color=COLORS[j]))
            t_s.append(Series(a["seconds"], a["residual"], method, color=COLORS[j]))
            rows.append(
                [
                    n,
                    m["n_nodes"],
                    method,
                    "yes" if m["converged"] else "no",
                    m["iterations"],
                    _g(m["seconds"]),
                    _g(m["residual"]),
                    m["error"][:100],
                ]
            )
        N = result.units[f"solvers/n{n}/{methods[0]}"].meta["n_nodes"]
        it_panels.append(
            Panel(
                it_s,
                f"N = {N}: residual vs iterations",
                "iteration",
                "residual / F",
                xscale="log",
                yscale="log",
                hlines=(scene.solver.tol,),
            )
        )
        t_panels.append(
            Panel(
                t_s,
                f"N = {N}: residual vs wall-clock time",
                "seconds",
                "residual / F",
                xscale="log",
                yscale="log",
                hlines=(scene.solver.tol,),
            )
        )
    ncols = min(3, len(sizes))
    doc.figure(
        "solvers_iterations",
        it_panels,
        "Residual against iterations, every method and size (dotted: the tolerance).",
        ncols=ncols,
    )
    doc.figure("solvers_seconds", t_panels, "Residual against wall-clock seconds.", ncols=ncols)
    tols = np.logspace(-2, math.log10(scene.solver.tol), 9)
    wp, scale = [], []
    n_last = sizes[-1]
    nodes = [result.units[f"solvers/n{n}/{methods[0]}"].meta["n_nodes"] for n in sizes]
    for j, method in enumerate(methods):
        a = result.units[f"solvers/n{n_last}/{method}"].arrays
        times = [_time_to(a["residual"], a["seconds"], t) for t in tols]
        wp.append(Series(times, tols, method, marker="o", color=COLORS[j]))
        reach = []
        for n in sizes:
            b = result.units[f"solvers/n{n}/{method}"].arrays
            reach.append(_time_to(b["residual"], b["seconds"], scene.solver.tol))
        scale.append(Series(nodes, reach, method, marker="o", color=COLORS[j]))
    doc.figure(
        "work_precision",
        [
            Panel(
                wp,
                f"work-precision, N = {nodes[-1]}",
                "seconds to reach the residual",
                "residual / F reached",
                xscale="log",
                yscale="log",
            ),
            Panel(
                scale,
                f"time to reach {scene.solver.tol:g}",
                "N (nodes)",
                "seconds",
                xscale="log",
                yscale="log",
            ),
        ],
        "Work-precision: the wall-clock time each method needs for each residual (left, "
        "largest size; missing points were not reached within the budget) and the time to the "
        "tolerance against network size (right).",
    )
    doc.table(
        ["n", "N", "method", "converged", "iterations", "seconds", "residual / F", "message"], rows
    )


# -- public ----------------------------------------------------------------------------------
def write_report(
    result,
    folder: str | os.PathLike[str],
    *,
    meshes: Sequence[str | os.PathLike[str]] = (),
    render: bool | None = None,
) -> Path:
    """Write ``<folder>/report.md`` (and its figures) for a scene result; return its path.

    Parameters
    ----------
    result : SceneResult
        From :func:`~continuum_vs_network.scenes.run_scene` or ``load_result``.
    folder : path
        Destination, e.g. ``reports/<scene>``; created.
    meshes : sequence of paths
        Mesh files written for the scene (listed in the report).
    render : bool, optional
        Draw pyvista renders. Default: when the scene asks for images (``[report] images``)
        and :func:`~continuum_vs_network.io.render.rendering_available` says rendering
        works; otherwise the report says renders were skipped and why.
    """
    t0 = time.perf_counter()
    scene = result.scene
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    doc = _Doc(folder, scene.report.dpi)
    reason = "the scene does not ask for images ([report] images = false)"
    if render is None:
        render = scene.report.images
        if render:
            from ..io.render import rendering_available

            render, why = rendering_available()
            reason = f"no off-screen rendering backend ({why})"
    elif not render:
        reason = "rendering switched off for this run"
    from ..scenes.schema import builtin_names

    builtin = scene.name in builtin_names() and Path(scene.source).parent.name == "builtin"
    target = scene.name if builtin else _short_source(scene.source)
    doc.add(
        f"# {scene.name}",
        "",
        scene.description,
        "",
        f"Kind: `{scene.kind}`. Regenerate with `cvn run {target}`"
        + (" (a built-in scene; `cvn scenes` lists them)." if builtin else "."),
    )
    if scene.kind == "learning":
        _learning(doc, result)
        if scene.report.images or scene.export is not None:
            _learning_renders(doc, result, render, reason)
    elif scene.kind == "transmission":
        _transmission(doc, result)
        _side_by_side(doc, result, "transmission/", render, reason, "transmission")
    elif scene.kind == "relaxation":
        _relaxation(doc, result)
        _side_by_side(doc, result, "relaxation/", render, reason, "relaxation")
    elif scene.kind == "stability":
        _stability(doc, result)
    elif scene.kind == "continuum_learning":
        from .continuum_learning import continuum_learning_section

        continuum_learning_section(doc, result, render=render, reason=reason)
    else:
        _solvers(doc, result)
    if meshes:
        doc.heading("Meshes for ParaView")
        root = folder.resolve().parent.parent
        for m in meshes:
            p = Path(m).resolve()
            try:
                shown = p.relative_to(root)
            except ValueError:
                shown = p
            doc.add(f"- `{shown}`")
    doc.heading("Settings")
    doc.add("```toml", scene_toml(scene.to_dict()), "```")
    _provenance(doc, result)
    report = write_text_atomic(folder / "report.md", "\n".join(doc.lines).rstrip() + "\n")
    keep = {p.name for p in doc.files}
    for old in folder.glob("*.png"):
        if old.name not in keep:
            old.unlink(missing_ok=True)
    meta = {
        "name": scene.name,
        "kind": scene.kind,
        "description": scene.description,
        "default": scene.report.default,
        "wall_seconds": result.provenance.wall_seconds,
        "compute_seconds": result.provenance.compute_seconds,
        "report_seconds": time.perf_counter() - t0,
        "started": result.provenance.started,
        "commit": result.provenance.commit,
        "figures": sorted(keep),
    }
    write_text_atomic(folder / _META, json.dumps(meta, indent=1, sort_keys=True))
    return report


def write_index(root: str | os.PathLike[str], *, note: str | None = None) -> Path:
    """Write ``<root>/README.md`` listing every ``<root>/<scene>/report.md``; return its path.

    ``note`` (e.g. how long the last default run took) is kept in ``<root>/index.json`` and
    shown again by later calls without one.
    """
    root = Path(root)
    keep = root / "index.json"
    if note is not None:
        write_text_atomic(keep, json.dumps({"note": note}))
    elif keep.exists():
        note = json.loads(keep.read_text()).get("note", "")
    entries = []
    for meta_path in sorted(root.glob(f"*/{_META}")):
        if not (meta_path.parent / "report.md").exists():
            continue
        entries.append(json.loads(meta_path.read_text()))
    lines = [
        "# Reports",
        "",
        "Written by `cvn report` (the default set: `cvn report` with no argument) and "
        "`cvn run SCENE`; one folder per scene with `report.md` and its figures.",
        "",
    ]
    if note:
        lines += [note, ""]
    lines += [
        "| scene | kind | default | description | compute s | report s |",
        "|---|---|---|---|---|---|",
    ]
    for e in entries:
        lines.append(
            f"| [{e['name']}]({e['name']}/report.md) | {e['kind']} | "
            f"{'yes' if e['default'] else 'no'} | {e['description']} | "
            f"{e['compute_seconds']:.1f} | {e['report_seconds']:.1f} |"
        )
    return write_text_atomic(root / "README.md", "\n".join(lines) + "\n")
