"""Findings of an allostery sweep over the learning rate and the nudge (``eta_alpha``).

Read from the sweep's table (it runs nothing). A row is one run on one draw; it *learned*
when its outcome is ``"learned (coupled)"`` (final C/C0 <= 1e-2 and the sources cause the
target's response, :mod:`~continuum_vs_network.learning.coupling`); rows of infeasible
draws (the bounded optimum cannot meet the task) and noisy rows are left out; without an
optimum per point, so are the draws no cell learned.

* **The rate**: per nudge, the share of draws learned and the median steps to the sweep's
  threshold at every rate. The best rate has the highest share (then the fewest steps); the
  grid brackets it when a smaller rate is slower or learns less and a larger one learns
  less (the instability).
* **The nudge**: at every rate up to the smallest of the nudges' best rates (the stable
  side) where each nudge learned at least ``STABLE`` of the draws,
  the median steps to the threshold over the learned rows of each nudge; the nudge does not
  matter when they differ by at most ``ETA_FACTOR``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...document import Document, fmt
from ...findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding

__all__ = ["ETA_FACTOR", "SLOWER", "rate_findings"]

#: The nudge does not matter when the median steps over its values differ by at most this.
ETA_FACTOR = 2.0
#: The nudges are compared at the rates where each learned at least this share of draws.
STABLE = 0.5
#: A smaller rate is "too slow" when it learns less or needs this many times the steps.
SLOWER = 2.0
LEARNED = "learned (coupled)"


def _label(v) -> str:
    if isinstance(v, tuple | list):
        return _label(v[0]) if len(v) == 1 else ", ".join(map(_label, v))
    return f"{v:g}" if isinstance(v, float) else str(v)


def _values(rows, key) -> list:
    out: list = []
    for r in rows:
        if r[key] not in out:
            out.append(r[key])
    return sorted(out)


def _stats(rows: Sequence[dict]) -> tuple[float, float, int]:
    """(share learned, median steps to the threshold over learned rows, rows)."""
    if not rows:
        return float("nan"), float("nan"), 0
    learned = [r for r in rows if r["outcome"] == LEARNED]
    steps = [r["steps_to_threshold"] for r in learned if r["steps_to_threshold"] is not None]
    return len(learned) / len(rows), float(np.median(steps)) if steps else float("nan"), len(rows)


def _better(a: tuple, b: tuple) -> bool:
    """Is (share, steps) ``a`` better than ``b``: more learned, then fewer steps."""
    if a[0] != b[0]:
        return a[0] > b[0]
    return np.nan_to_num(a[1], nan=np.inf) < np.nan_to_num(b[1], nan=np.inf)


def rate_findings(doc: Document, result, params: list[str]) -> None:
    """The rate bracket and the nudge dependence of an allostery sweep (see the module)."""
    rows = [r for r in result.rows if r["outcome"] != "infeasible" and r["noise"] == 0]
    rate = "allostery.alpha" if "allostery.alpha" in params else None
    nudge = "allostery.etas" if "allostery.etas" in params else None
    if rate is None and nudge is None:
        return
    noisy = sum(r["noise"] != 0 for r in result.rows)
    infeasible = sum(r["outcome"] == "infeasible" for r in result.rows)
    unlearned: list = []
    if not result.scene.allostery.optimum:
        # no optimum says which draws are feasible: a draw no cell learned is counted apart
        learned = {r["trial"] for r in rows if r["outcome"] == LEARNED}
        unlearned = sorted({r["trial"] for r in rows} - learned)
        rows = [r for r in rows if r["trial"] in learned]
    doc.heading("The best rate and the nudge")
    doc.add(
        "A run *learned* when its outcome is learned (coupled). Left out: "
        f"{noisy} rows with read-out noise, {infeasible} rows of draws the bounded optimum "
        "shows infeasible"
        + (
            f", and the draws no cell learned ({', '.join(map(str, unlearned)) or 'none'}: "
            "no optimum is computed per point, so these may be infeasible or beyond every "
            "rate's budget)"
            if not result.scene.allostery.optimum
            else ""
        )
        + f". Cells: share of draws learned, median steps to C/C0 <= "
        f"{result.scene.sweep.threshold:g} over them.",
        "",
    )
    etas = _values(rows, nudge) if nudge else [None]
    alphas = _values(rows, rate) if rate else [None]

    def cell(a, e):
        return [r for r in rows if (a is None or r[rate] == a) and (e is None or r[nudge] == e)]

    stats = {(a, e): _stats(cell(a, e)) for a in alphas for e in etas}
    doc.table(
        [("alpha" if rate else "") + (" \\ eta" if nudge else ""), *(_label(e) for e in etas)],
        [
            [_label(a), *(f"{fmt(stats[a, e][0], 2)}, {fmt(stats[a, e][1])}" for e in etas)]
            for a in alphas
        ],
    )
    if rate and len(alphas) >= 3:
        _rate_bracket(doc, alphas, etas, stats)
    if nudge and len(etas) >= 2:
        # the stable side: rates up to the smallest of the nudges' best rates
        top = min(_best(alphas, [stats[a, e] for a in alphas]) for e in etas)
        _nudge(doc, alphas[: top + 1], etas, stats)


def _best(alphas, col) -> int:
    """Index of the best rate of one nudge's column of (share, steps, rows)."""
    best = 0
    for i in range(1, len(col)):
        if _better(col[i], col[best]):
            best = i
    return best


def _rate_bracket(doc: Document, alphas, etas, stats) -> None:
    lines, bracketed = [], []
    for e in etas:
        col = [stats[a, e] for a in alphas]
        best = _best(alphas, col)
        slow = any(
            c[0] < col[best][0] or np.nan_to_num(c[1], nan=np.inf) >= SLOWER * col[best][1]
            for c in col[:best]
        )
        unstable = any(c[0] < col[best][0] for c in col[best + 1 :])
        bracketed.append(slow and unstable)
        lines.append(
            f"eta = {_label(e)}: best alpha = {_label(alphas[best])} (share "
            f"{fmt(col[best][0], 2)}, {fmt(col[best][1])} steps); "
            + ("smaller rates slower or learning less" if slow else "no slower rate below it")
            + "; "
            + ("larger rates learn less" if unstable else "no worse rate above it")
        )
    v = REPRODUCED if all(bracketed) else NOT_REPRODUCED
    doc.add("\n".join(f"- {x}" for x in lines), "")
    doc.finding(
        Finding(
            claim="the learning rate alpha has a best value: below it learning is slow, above "
            "it unstable (the grid brackets both, at every nudge)",
            metric="per nudge: share of draws learned (coupled) and median steps to the "
            "threshold against alpha",
            measured={
                "nudges bracketed": sum(bracketed),
                "nudges": len(etas),
                "best share": max(stats[a, e][0] for a in alphas for e in etas),
            },
            verdict=v,
            rule=f"reproduced when at every nudge a smaller rate learns less or needs >= "
            f"{SLOWER:g}x the steps of the best and a larger one learns less",
            source="field",
            basis="coupled",
        )
    )


def _nudge(doc: Document, alphas, etas, stats) -> None:
    spread, at, rows = 1.0, None, 0
    for a in alphas:
        med = np.array([stats[a, e][1] for e in etas])
        share = np.array([stats[a, e][0] for e in etas])
        if np.all(share >= STABLE) and np.all(np.isfinite(med)):
            rows += 1
            ratio = float(med.max() / med.min())
            if ratio > spread:
                spread, at = ratio, a
    if rows == 0:
        v = NOT_COMPARABLE
    else:
        v = REPRODUCED if spread <= ETA_FACTOR else NOT_REPRODUCED
    doc.add(
        f"Across eta = {', '.join(map(_label, etas))}, the median steps to the threshold "
        f"change by at most a factor {fmt(spread)} over the {rows} rates up to the nudges' "
        f"best where every nudge learned at least {STABLE:.0%} of the draws (the stable side; "
        "above the best rate single runs are erratic)"
        + (f" (largest at alpha = {_label(at)})" if at is not None else "")
        + f": **{v}** (rule: at most {ETA_FACTOR:g}x).",
        "",
    )
    doc.finding(
        Finding(
            claim="without read-out noise, coupled learning does not depend on the nudge eta "
            f"over {_label(etas[0])}-{_label(etas[-1])} (its small-eta limit)",
            metric="largest ratio over rates of the highest to the lowest median steps to the "
            "threshold across eta (learned (coupled) runs of feasible draws)",
            measured={"ratio": spread, "rates compared": rows},
            verdict=v,
            rule=f"reproduced when the ratio <= {ETA_FACTOR:g}, not reproduced otherwise; not "
            f"comparable when at no rate every nudge learned >= {STABLE:g} of the draws",
            source="field",
            basis="coupled" if rows else "",
        )
    )
