"""The report of a sweep: phase diagrams of the final error over the swept parameters.

:func:`write_sweep_report` reads a :class:`~continuum_vs_network.scenes.sweep.SweepResult`
(it runs nothing) and writes ``<folder>/report.md`` with

* the grid (every swept key and its values) and how it was run;
* for every swept parameter (the seed aside) the final error relative to the initial one
  against the parameter: medians and quartiles over every trial and every value of the
  parameters not on the axis, one line per value of another swept parameter;
* for two or more swept parameters a heat map of that median over the first two (one map
  per value of a third);
* a table per grid cell and the best and worst cells, chosen by the stated rule (lowest and
  highest median relative final error), with trials that stopped early counted.

Every number comes from the sweep's table; nothing is written by hand.
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

from ..io.atomic import write_text_atomic
from .figures import Panel, Series, heatmap, plot_panels

__all__ = ["write_sweep_report"]

_METRIC = "relative_error"
_YLABEL = "final / initial error"


def _quiet(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return fn(*args, **kw)


def _g(x: Any, digits: int = 3) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


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
                "steps": _quiet(np.nanmedian, reached) if np.isfinite(reached).any() else None,
                "stopped": stopped,
                "seconds": float(np.median(_column(sub, "wall_seconds"))),
            }
        )
    return cells


def _heatmaps(doc: list[str], folder: Path, result, params: list[str], dpi: int) -> list[Path]:
    a, b = params[0], params[1]
    third = None
    if len(params) > 2 and len(_axis_values(result.rows, params[2])) <= 4:
        third = params[2]
    rows_v, cols_v = _axis_values(result.rows, a), _axis_values(result.rows, b)
    files = []
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
            text = [[_g(v, 2) for v in row] for row in med]
            with np.errstate(divide="ignore", invalid="ignore"):
                logmed = np.where(med > 0, np.log10(med), np.nan)
            extra = f", {third} = {_label(level)}" if level is not None else ""
            name = f"fig_heatmap_{solver}_{rule}_{j}.png"
            path = heatmap(
                logmed,
                [f"{a} = {_label(x)}" for x in rows_v],
                [_label(y) for y in cols_v],
                folder / name,
                text=text,
                title=f"{rule}: median final / initial error ({b} across){extra}",
                colorbar="log10 median final / initial error",
                dpi=dpi,
            )
            files.append(path)
            pooled = [q for q in params if q not in (a, b, third)]
            caption = (
                f"{rule} ({solver}{extra}): median over "
                + ("trials" if not pooled else f"trials and {', '.join(pooled)}")
                + f" of the final error relative to the initial one, {a} down, {b} across "
                "(cell text: the median; colour: its log10)."
            )
            doc.extend(["", f"![{caption}]({name})", "", f"*{caption}*", ""])
    return files


def _findings(doc: list[str], cells: list[dict], params: list[str], threshold: float) -> None:
    doc.extend(["", "## Best and worst settings", ""])
    doc.append(
        "Rule: per learning run, the grid cells (combinations of the swept parameters, seeds "
        "pooled) with the lowest and the highest median final / initial error."
    )
    doc.append("")
    for solver, rule in dict.fromkeys((c["solver"], c["rule"]) for c in cells):
        mine = [c for c in cells if c["solver"] == solver and c["rule"] == rule]
        ok = [c for c in mine if np.isfinite(c["median"])]
        if not ok:
            doc.append(f"- {rule} ({solver}): no trial has a finite error.")
            continue
        best = min(ok, key=lambda c: c["median"])
        worst = max(ok, key=lambda c: c["median"])

        def where(c: dict) -> str:
            return ", ".join(f"{p} = {_label(c[p])}" for p in params) or "the only cell"

        doc.append(
            f"- {rule} ({solver}): lowest at {where(best)}: median {_g(best['median'])} "
            f"(quartiles {_g(best['q25'])}-{_g(best['q75'])}, {best['n']} trials; "
            f"{best['reached']} of {best['trials']} reached {threshold:g} x the initial "
            f"error); highest at {where(worst)}: median {_g(worst['median'])} "
            f"(quartiles {_g(worst['q25'])}-{_g(worst['q75'])})."
        )
    stopped = sum(c["stopped"] for c in cells)
    total = sum(c["trials"] for c in cells)
    doc.append(
        f"- Trials that stopped early (a failed solve or a rule's stop; their error is the "
        f"last one measured): {stopped} of {total}."
    )


def _table(doc: list[str], cells: list[dict], params: list[str], threshold: float) -> None:
    headers = [
        "run",
        *params,
        "median final/initial",
        "quartiles",
        f"reached {threshold:g}x",
        "median steps to it",
        "stopped",
        "median trial s",
    ]
    doc.extend(["", "| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)])
    for c in cells:
        cells_text = [
            f"{c['solver']}/{c['rule']}",
            *(_label(c[p]) for p in params),
            _g(c["median"]),
            f"{_g(c['q25'])}-{_g(c['q75'])}",
            f"{c['reached']}/{c['trials']}",
            _g(c["steps"]),
            str(c["stopped"]),
            _g(c["seconds"], 2),
        ]
        doc.append("| " + " | ".join(cells_text) + " |")
    doc.append("")


def write_sweep_report(result, folder: str | os.PathLike[str], *, command: str = "") -> Path:
    """Write ``<folder>/report.md`` and its figures for a sweep; return the report's path.

    Parameters
    ----------
    result : SweepResult
        From :func:`~continuum_vs_network.scenes.sweep.run_sweep` or ``load_sweep``.
    folder : path
        Destination, e.g. ``reports/<scene>``; created. Figures of an earlier report that
        this one does not use are removed.
    command : str
        The command that regenerates the sweep (shown in the report).
    """
    t0 = time.perf_counter()
    scene, info = result.scene, result.info
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    dpi = scene.report.dpi
    threshold = scene.sweep.threshold
    params = _parameters(result)
    doc = [f"# {scene.name}", "", scene.description, ""]
    doc.append(
        f"A sweep of a `{scene.kind}` scene: {info['points']} grid points "
        f"({' x '.join(map(str, info['grid']))}), {len(result.rows)} trials in the table."
        + (f" Regenerate with `{command}`." if command else "")
    )
    doc.extend(["", "## Grid", "", "| key | values |", "|---|---|"])
    zipped = {k: g for g in scene.sweep.zip for k in g}
    for key, values in scene.sweep.axes:
        note = ""
        if key in zipped:
            note = f" (zipped with {', '.join(k for k in zipped[key] if k != key)})"
        doc.append(f"| `{key}` | {', '.join(_label(v) for v in values)}{note} |")
    files: list[Path] = []
    doc.extend(["", "## Final error against the swept parameters", ""])
    if params:
        name = "fig_phase.png"
        path = plot_panels(_line_panels(result, params), folder / name, dpi=dpi)
        files.append(path)
        caption = (
            "Final error relative to the initial error against each swept parameter: median "
            "(line) and quartiles (band) over trials and over the values of the parameters "
            "not on the axis; one line per value of another swept parameter (in the legend)."
        )
        doc.extend(["", f"![{caption}]({name})", "", f"*{caption}*", ""])
        if len(params) >= 2:
            files += _heatmaps(doc, folder, result, params, dpi)
    else:
        doc.append("Only the seed is swept: no parameter axis to draw.")
    cells = _cells(result, params)
    _findings(doc, cells, params, threshold)
    doc.extend(["", "## Every grid cell", ""])
    _table(doc, cells, params, threshold)
    doc.extend(
        [
            "",
            "## Table and provenance",
            "",
            f"The tidy table (one row per grid point, learning run and trial) is "
            f"`{result.directory / 'table.parquet'}` (CSV beside it). Computed by "
            f"{info['executor']} in {info['wall_seconds']:.1f} s wall "
            f"({info['reused']} of {info['points']} points reused from an earlier run); "
            f"started {info['started']}.",
            "",
            "```json",
            json.dumps(scene.to_dict(), indent=1, sort_keys=True),
            "```",
        ]
    )
    report = write_text_atomic(folder / "report.md", "\n".join(doc).rstrip() + "\n")
    keep = {p.name for p in files}
    for old in folder.glob("*.png"):
        if old.name not in keep:
            old.unlink(missing_ok=True)
    compute = float(np.nansum(_column(result.rows, "wall_seconds")))
    meta = {
        "name": scene.name,
        "kind": f"{scene.kind} sweep",
        "description": scene.description,
        "default": scene.report.default,
        "wall_seconds": info["wall_seconds"],
        "compute_seconds": compute,
        "report_seconds": time.perf_counter() - t0,
        "started": info["started"],
        "commit": info.get("commit", "unknown"),
        "figures": sorted(keep),
    }
    write_text_atomic(folder / "report.json", json.dumps(meta, indent=1, sort_keys=True))
    return report
