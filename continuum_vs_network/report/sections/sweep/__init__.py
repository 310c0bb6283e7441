"""The section of a sweep: phase diagrams of the final error over the swept parameters.

:func:`section` reads a :class:`~continuum_vs_network.scenes.sweep.SweepResult` (it runs
nothing; :func:`~continuum_vs_network.report.writer.write_sweep_report` writes the report)
and adds

* the grid (every swept key and its values) and how it was run;
* for every swept parameter (the seed aside) the final error relative to the initial one
  against the parameter: medians and quartiles over every trial and every value of the
  parameters not on the axis, one line per value of another swept parameter;
* for two or more swept parameters a heat map of that median over the first two (one map
  per value of a third);
* a table per grid cell and the best and worst cells, chosen by the stated rule (lowest and
  highest median relative final error), with trials that stopped early counted, and the
  outcome of every trial (its error and the coupling verdict of
  :mod:`~continuum_vs_network.learning.coupling` together);
* when a GCL nudge amplitude ``learning.eta`` is swept: a finding on whether the final
  error depends on it (noise-free rows), by a stated rule.

Every number comes from the sweep's table; nothing is written by hand.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ...document import Document, fmt, quiet
from ...figures import Panel, Series, heatmap
from ...findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding

__all__ = ["ETA_FACTOR", "section"]

#: ``learning.eta`` "matters" when, at some other setting, the medians over its values
#: differ by more than this factor
ETA_FACTOR = 2.0

_ETA_RULE = (
    f"reproduced when the ratio <= {ETA_FACTOR:g}, not reproduced otherwise, over the trials "
    "whose trained network is not decoupled (learning.coupling); not comparable when every "
    "trial is decoupled: such a network met the task, if at all, by prestressing its targets"
)

_METRIC = "relative_error"
_YLABEL = "final / initial error"


def _label(v: Any) -> str:
    if isinstance(v, tuple | list):
        return _label(v[0]) if len(v) == 1 else "[" + ", ".join(map(_label, v)) + "]"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _column(rows: Sequence[dict], name: str) -> np.ndarray:
    return np.array([np.nan if r[name] is None else r[name] for r in rows], dtype=float)


def _quartiles(values: np.ndarray) -> tuple[float, float, float, int]:
    ok = values[np.isfinite(values)]
    if not ok.size:
        return math.nan, math.nan, math.nan, 0
    q = np.percentile(ok, [25, 50, 75])
    return float(q[1]), float(q[0]), float(q[2]), int(ok.size)


def _axis_values(rows: Sequence[dict], key: str) -> list:
    seen: list = []
    for r in rows:
        if r[key] not in seen:
            seen.append(r[key])
    try:
        return sorted(seen)
    except TypeError:
        return seen


def _logx(values: Sequence) -> bool:
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        return False
    v = np.asarray(values, dtype=float)
    return bool(np.all(v > 0) and v.max() / v.min() >= 10)


def _parameters(result) -> list[str]:
    """Swept columns with two or more values, the seed aside (seeds are replicates)."""
    out = []
    for col in result.swept:
        if col == "scene.seed":
            continue
        if len(_axis_values(result.rows, col)) >= 2:
            out.append(col)
    return out


def _runs(rows: Sequence[dict]) -> list[tuple[str, str]]:
    runs: list[tuple[str, str]] = []
    for r in rows:
        if (r["solver"], r["rule"]) not in runs:
            runs.append((r["solver"], r["rule"]))
    return runs


def _select(rows: Sequence[dict], **where: Any) -> list[dict]:
    return [r for r in rows if all(r[k] == v for k, v in where.items())]


def _line_panels(result, params: list[str]) -> list[Panel]:
    """Median and quartiles of the relative error against each parameter."""
    panels = []
    runs = _runs(result.rows)
    for p in params:
        xs = _axis_values(result.rows, p)
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in xs)
        xplot = np.asarray(xs, dtype=float) if numeric else np.arange(len(xs), dtype=float)
        others = [q for q in params if q != p]
        split = others[0] if others and len(_axis_values(result.rows, others[0])) <= 6 else None
        series = []
        for solver, rule in runs:
            base = _select(result.rows, solver=solver, rule=rule)
            levels = _axis_values(base, split) if split else [None]
            for level in levels:
                sub = base if level is None else _select(base, **{split: level})
                stats = [_quartiles(_column(_select(sub, **{p: x}), _METRIC)) for x in xs]
                med, lo, hi = (np.array([s[i] for s in stats]) for i in range(3))
                name = rule if len(runs) == 1 or solver == "newton" else f"{solver}/{rule}"
                if level is not None:
                    name = f"{name}, {split} = {_label(level)}"
                series.append(Series(xplot, med, name, lo=lo, hi=hi, marker="o"))
        panels.append(
            Panel(
                series,
                title=f"final error against {p}",
                xlabel=p if numeric else f"{p} ({', '.join(map(_label, xs))})",
                ylabel=_YLABEL,
                xscale="log" if _logx(xs) else "linear",
                yscale="log",
            )
        )
    return panels


def _counts(values) -> str:
    counts: dict[str, int] = {}
    for v in values:
        counts[v] = counts.get(v, 0) + 1
    return "; ".join(f"{n} {v}" for v, n in counts.items())


def _cells(result, params: list[str]) -> list[dict]:
    """One summary per (run, combination of the parameters)."""
    cells = []
    combos: list[tuple] = []
    for r in result.rows:
        key = (r["solver"], r["rule"], *(r[p] for p in params))
        if key not in combos:
            combos.append(key)
    for key in combos:
        where = {"solver": key[0], "rule": key[1], **dict(zip(params, key[2:]))}
        sub = _select(result.rows, **where)
        med, lo, hi, n = _quartiles(_column(sub, _METRIC))
        reached = _column(sub, "steps_to_threshold")
        stopped = sum(1 for r in sub if r["stop_reason"])
        cells.append(
            {
                **where,
                "median": med,
                "q25": lo,
                "q75": hi,
                "n": n,
                "trials": len(sub),
                "reached": int(np.sum(np.isfinite(reached))),
                "steps": quiet(np.nanmedian, reached) if np.isfinite(reached).any() else None,
                "stopped": stopped,
                "seconds": float(np.median(_column(sub, "wall_seconds"))),
                "outcomes": _counts(r["outcome"] for r in sub),
            }
        )
    return cells


def _heatmaps(doc: Document, result, params: list[str]) -> None:
    a, b = params[0], params[1]
    third = None
    if len(params) > 2 and len(_axis_values(result.rows, params[2])) <= 4:
        third = params[2]
    rows_v, cols_v = _axis_values(result.rows, a), _axis_values(result.rows, b)
    for solver, rule in _runs(result.rows):
        levels = _axis_values(result.rows, third) if third else [None]
        for j, level in enumerate(levels):
            base = _select(result.rows, solver=solver, rule=rule)
            if level is not None:
                base = _select(base, **{third: level})
            med = np.full((len(rows_v), len(cols_v)), np.nan)
            for i, x in enumerate(rows_v):
                for k, y in enumerate(cols_v):
                    med[i, k] = _quartiles(_column(_select(base, **{a: x, b: y}), _METRIC))[0]
            text = [[fmt(v, 2) for v in row] for row in med]
            with np.errstate(divide="ignore", invalid="ignore"):
                logmed = np.where(med > 0, np.log10(med), np.nan)
            extra = f", {third} = {_label(level)}" if level is not None else ""
            path = heatmap(
                logmed,
                [f"{a} = {_label(x)}" for x in rows_v],
                [_label(y) for y in cols_v],
                doc.folder / f"fig_heatmap_{solver}_{rule}_{j}.png",
                text=text,
                title=f"{rule}: median final / initial error ({b} across){extra}",
                colorbar="log10 median final / initial error",
                xlabel=b,
                dpi=doc.dpi,
            )
            pooled = [q for q in params if q not in (a, b, third)]
            doc.image(
                path,
                f"{rule} ({solver}{extra}): median over "
                + ("trials" if not pooled else f"trials and {', '.join(pooled)}")
                + f" of the final error relative to the initial one, {a} down, {b} across "
                "(cell text: the median; colour: its log10).",
            )


def _where(c: dict, params: list[str]) -> str:
    return ", ".join(f"{p} = {_label(c[p])}" for p in params) or "the only cell"


def _best_worst(doc: Document, cells: list[dict], params: list[str], threshold: float) -> None:
    doc.heading("Best and worst settings")
    doc.add(
        "Rule: per learning run, the grid cells (combinations of the swept parameters, seeds "
        "pooled) with the lowest and the highest median final / initial error.",
        "",
    )
    for solver, rule in dict.fromkeys((c["solver"], c["rule"]) for c in cells):
        mine = [c for c in cells if c["solver"] == solver and c["rule"] == rule]
        ok = [c for c in mine if np.isfinite(c["median"])]
        if not ok:
            doc.add(f"- {rule} ({solver}): no trial has a finite error.")
            continue
        best = min(ok, key=lambda c: c["median"])
        worst = max(ok, key=lambda c: c["median"])
        doc.add(
            f"- {rule} ({solver}): lowest at {_where(best, params)}: median "
            f"{fmt(best['median'])} (quartiles {fmt(best['q25'])}-{fmt(best['q75'])}, "
            f"{best['n']} trials; {best['reached']} of {best['trials']} reached {threshold:g} x "
            f"the initial error; outcomes: {best['outcomes']}); highest at "
            f"{_where(worst, params)}: median {fmt(worst['median'])} (quartiles "
            f"{fmt(worst['q25'])}-{fmt(worst['q75'])}; outcomes: {worst['outcomes']})."
        )
    stopped = sum(c["stopped"] for c in cells)
    total = sum(c["trials"] for c in cells)
    doc.add(
        f"- Trials that stopped early (a failed solve or a rule's stop; their error is the "
        f"last one measured): {stopped} of {total}.",
        "",
    )


def _eta_finding(doc: Document, result, params: list[str]) -> None:
    """Does GCL's final error depend on the nudge amplitude (noise-free rows)?"""
    key = "learning.eta"
    if key not in params:
        return
    others = [p for p in params if p not in (key, "learning.noise")]
    for solver, rule in _runs(result.rows):
        if not rule.startswith("gcl"):
            continue
        rows = [
            r
            for r in _select(result.rows, solver=solver, rule=rule)
            if r["noise"] == 0 and r.get("learning.noise", 0) in (0, 0.0)
        ]
        if not rows:
            continue
        if not doc.findings or doc.findings[-1].section != "Does the nudge amplitude matter?":
            doc.heading("Does the nudge amplitude matter?")
        etas = _axis_values(rows, key)
        everyone = len(rows)
        # a decoupled network met the task (if at all) by prestress: its error says
        # nothing about how coupled learning depends on eta
        rows = [r for r in rows if r.get("coupling", "coupled") != "decoupled"]
        if not rows:
            doc.finding(
                Finding(
                    claim=f"{rule}: without read-out noise the final error does not depend on "
                    f"the nudge amplitude eta over {_label(etas[0])}-{_label(etas[-1])} (the "
                    "small-eta limit of coupled learning)",
                    metric="largest ratio, over the other swept settings, of the highest to "
                    "the lowest median final / initial error across the eta values (noise 0, "
                    "trials not decoupled)",
                    measured={"trials": everyone, "decoupled trials": everyone},
                    verdict=NOT_COMPARABLE,
                    rule=_ETA_RULE,
                )
            )
            doc.add(
                f"- {rule} ({solver}), noise 0: every one of the {everyone} trials ended "
                "decoupled (source share below the coupling threshold; outcomes in the cell "
                "table): none learned the task by coupling, so how the error of coupled "
                f"learning depends on eta is **{NOT_COMPARABLE}** here (rule: {_ETA_RULE})."
            )
            continue
        spread, at = 1.0, ""
        combos = list(dict.fromkeys(tuple(r[p] for p in others) for r in rows))
        for combo in combos:
            sub = _select(rows, **dict(zip(others, combo)))
            med = np.array(
                [_quartiles(_column(_select(sub, **{key: e}), _METRIC))[0] for e in etas]
            )
            med = med[np.isfinite(med) & (med > 0)]
            if med.size >= 2 and med.max() / med.min() > spread:
                spread = float(med.max() / med.min())
                at = ", ".join(f"{p} = {_label(v)}" for p, v in zip(others, combo))
        verdict = REPRODUCED if spread <= ETA_FACTOR else NOT_REPRODUCED
        doc.finding(
            Finding(
                claim=f"{rule}: without read-out noise the final error does not depend on the "
                f"nudge amplitude eta over {_label(etas[0])}-{_label(etas[-1])} (the small-eta "
                "limit of coupled learning)",
                metric="largest ratio, over the other swept settings, of the highest to the "
                "lowest median final / initial error across the eta values (noise 0, trials "
                "not decoupled)",
                measured={
                    "ratio": spread,
                    "trials": everyone,
                    "decoupled trials": everyone - len(rows),
                },
                verdict=verdict,
                rule=_ETA_RULE,
            )
        )
        doc.add(
            f"- {rule} ({solver}), noise 0, over the {len(rows)} of {everyone} trials not "
            f"decoupled: across eta = {', '.join(map(_label, etas))} the "
            f"median final / initial error changes by at most a factor {fmt(spread)}"
            + (f" (largest at {at})" if at else "")
            + f": **{verdict}** (rule: at most a factor {ETA_FACTOR:g})."
        )


def _table(doc: Document, cells: list[dict], params: list[str], threshold: float) -> None:
    headers = [
        "run",
        *params,
        "median final/initial",
        "quartiles",
        f"reached {threshold:g}x",
        "median steps to it",
        "outcomes",
        "stopped",
        "median trial s",
    ]
    rows = [
        [
            f"{c['solver']}/{c['rule']}",
            *(_label(c[p]) for p in params),
            fmt(c["median"]),
            f"{fmt(c['q25'])}-{fmt(c['q75'])}",
            f"{c['reached']}/{c['trials']}",
            fmt(c["steps"]),
            c["outcomes"],
            str(c["stopped"]),
            fmt(c["seconds"], 2),
        ]
        for c in cells
    ]
    doc.table(headers, rows)


def section(doc: Document, result) -> None:
    """The sweep's grid, phase diagrams, best and worst cells, findings and cell table."""
    scene, info = result.scene, result.info
    threshold = scene.sweep.threshold
    params = _parameters(result)
    doc.heading("Grid")
    zipped = {k: g for g in scene.sweep.zip for k in g}
    grid = []
    for key, values in scene.sweep.axes:
        note = ""
        if key in zipped:
            note = f" (zipped with {', '.join(k for k in zipped[key] if k != key)})"
        grid.append([f"`{key}`", ", ".join(_label(v) for v in values) + note])
    doc.table(["key", "values"], grid)
    doc.add(
        f"{info['points']} grid points ({' x '.join(map(str, info['grid']))}), "
        f"{len(result.rows)} trials in the table `{result.directory / 'table.parquet'}` "
        "(CSV beside it; one row per grid point, learning run and trial)."
    )
    doc.heading("Final error against the swept parameters")
    if params:
        doc.figure(
            "phase",
            _line_panels(result, params),
            "Final error relative to the initial error against each swept parameter: median "
            "(line) and quartiles (band) over trials and over the values of the parameters "
            "not on the axis; one line per value of another swept parameter (in the legend).",
        )
        if len(params) >= 2:
            _heatmaps(doc, result, params)
    else:
        doc.add("Only the seed is swept: no parameter axis to draw.")
    cells = _cells(result, params)
    _best_worst(doc, cells, params, threshold)
    if scene.kind == "allostery":
        from .rates import rate_findings

        rate_findings(doc, result, params)
    else:
        _eta_finding(doc, result, params)
    doc.heading("Every grid cell")
    doc.add(
        "Outcomes count the trials by `learning.coupling.outcome`: the final / initial error "
        "and the coupling verdict of the trained network together (a task met by a "
        "decoupled network is met trivially, not learned)."
    )
    _table(doc, cells, params, threshold)
    doc.heading("How it was run")
    doc.add(
        f"Computed by {info['executor']} in {info['wall_seconds']:.1f} s wall "
        f"({info['reused']} of {info['points']} points reused from an earlier run); started "
        f"{info['started']}; commit `{info.get('commit', 'unknown')}`."
    )
