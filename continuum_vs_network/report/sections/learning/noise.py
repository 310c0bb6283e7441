"""The read-out noise floor of the learning section (:mod:`.`): floors
against the noise, the (sigma/eta)^2 fit, its finding and figure.
"""

from __future__ import annotations

import numpy as np

from ...document import Document, fmt
from ...figures import COLORS, Panel, Series
from ...findings import Finding
from .checks import CONVENTION_TEXT
from .coupling import coupling_verdicts

__all__ = ["decoupled_caveat", "noise_floor"]


def decoupled_caveat(verdicts, *, ratios, runs: str, what: str, noun: str) -> tuple[str, dict]:
    """The caveat of a noise floor judged on every run, decoupled or not, and its counts.

    ``verdicts``: per-run coupling verdicts (:mod:`....learning.coupling`; empty when not
    measured); ``ratios``: each run's final C/C0 (NaN: not known), one per verdict, which
    tells whether it met the task (``<= MET_AT``); ``runs``: what they are, in words;
    ``what``: what the judged quantity is a property of (a sentence without its full
    stop); ``noun``: the counted thing ("trials"). Returns the sentences ("" when nothing
    is measured) and ``{noun: n, "decoupled " + noun: d, noun + " met trivially
    (decoupled)": k}`` for a finding's ``measured`` (empty when nothing is measured). Only
    the decoupled runs that met the task are said to have met it trivially; of those that
    did not, that what they learned is not carried by the sources."""
    from ....learning.coupling import MET_AT

    verdicts = list(verdicts)
    ratios = np.asarray(ratios, dtype=np.float64).ravel()
    if ratios.size != len(verdicts):
        raise ValueError(
            f"ratios needs one final C/C0 per verdict ({len(verdicts)}), got {ratios.size}"
        )
    if not verdicts:
        return "", {}
    dec = np.array([v == "decoupled" for v in verdicts], dtype=bool)
    met, missed = dec & (ratios <= MET_AT), dec & (ratios > MET_AT)
    unknown = int(dec.sum() - met.sum() - missed.sum())
    parts = []
    if met.any():
        parts.append(
            f"{int(met.sum())} met the task (final C/C0 <= {MET_AT:g}) trivially, their target "
            "strains not carried by the sources"
        )
    if missed.any():
        lo, hi = fmt(float(ratios[missed].min())), fmt(float(ratios[missed].max()))
        parts.append(
            f"{int(missed.sum())} did not meet the task (final C/C0 "
            + (lo if lo == hi else f"{lo} to {hi}")
            + f", above {MET_AT:g}): what they learned is not carried by the sources"
        )
    if unknown:
        parts.append(f"{unknown} have no final C/C0 (whether they met the task is not known)")
    text = (
        f"The {len(verdicts)} {runs}: {int(dec.sum())} decoupled (learning.coupling). {what}; "
        "it is judged on every run, "
        + (
            f"but a decoupled run shows no learned allostery; of the {int(dec.sum())} "
            "decoupled runs, " + "; ".join(parts) + "."
            if dec.any()
            else "and none here is decoupled."
        )
    )
    return text, {
        noun: len(verdicts),
        f"decoupled {noun}": int(dec.sum()),
        f"{noun} met trivially (decoupled)": int(met.sum()),
    }


def noise_floor(doc: Document, result, h, solver: str, names) -> None:
    """Floors of every run against the noise, the (sigma/eta)^2 fit, a table."""
    from ....learning.metrics import final_values, normalised
    from ....learning.noise import floor_scaling
    from ....learning.noise import noise_floor as floor_of

    L = result.scene.learning
    doc.heading("Read-out noise: the (sigma / eta)^2 floor")
    doc.add(
        "Every length a rule reads is `r (1 + sigma xi)`, `xi ~ N(0, 1)`; the error is "
        "measured without noise, in the run's convention "
        f"{CONVENTION_TEXT[L.strain_reference]}. The *floor* of a trial is the mean of C "
        "over the last quarter of its steps (a trial that stopped, its equilibrium lost as "
        "the rest lengths diverged, has none). Coupled learning reads a signal of order "
        "eta times the length error against a noise of order sigma, so its floor should "
        "be c (sigma/eta)^2; the exponent p is fitted over the GCL points the noise limits "
        "(floor above 10 x the noise-free final C at the same eta). GPC and the exact "
        "gradient have no nudge: their floors are drawn against sigma."
    )
    sigmas = np.array(L.noise)
    gcl = [n for n in names if n.startswith("gcl")]
    ratio, floors, clean, rows = [], [], [], []
    med_floor = {}
    for name in names:
        cells = []
        for i in range(len(sigmas)):
            hist = h(solver, name, i)
            f = floor_of(hist.task_error(hist.strain_reference), hist.completed)
            stopped = int(np.sum(hist.completed < hist.steps))
            med = float(np.median(f[np.isfinite(f)])) if np.isfinite(f).any() else np.nan
            med_floor[name, i] = med
            cells.append(fmt(med) + (f" ({stopped}/{hist.trials} diverged)" if stopped else ""))
        rows.append([name, *cells])
    etas = {n: float(n.split("_eta")[1]) if "_eta" in n else L.eta for n in gcl}
    for name in gcl:
        c0 = med_floor.get((name, 0), np.nan) if sigmas[0] == 0 else np.nan
        for i, sigma in enumerate(sigmas):
            if sigma > 0:
                ratio.append(sigma / etas[name])
                floors.append(med_floor[name, i])
                clean.append(c0)
    fit = (
        floor_scaling(np.array(ratio), np.array(floors), np.array(clean))
        if ratio
        else {"p": np.nan, "c": np.nan, "n": 0, "spread": np.nan}
    )
    doc.table(["run", *[f"floor C, sigma = {s:g}" for s in sigmas]], rows)
    doc.add(
        f"Fit over {fit['n']} GCL points: floor = {fmt(fit['c'])} (sigma/eta)^"
        f"{fmt(fit['p'])}; the prefactor varies by a factor {fmt(fit['spread'])} over them."
    )
    verdicts, ratios = [], []
    for name in gcl:
        for i in np.flatnonzero(sigmas > 0):
            v = coupling_verdicts(result, f"{solver}/{name}/noise{int(i)}")
            hist = h(solver, name, int(i))
            final = final_values(normalised(hist.task_error(hist.strain_reference)), hist.completed)
            verdicts += v
            ratios += list(final) if len(final) == len(v) else [np.nan] * len(v)
    trivially, counts = decoupled_caveat(
        verdicts,
        ratios=ratios,
        runs="noisy GCL trials' trained networks",
        what="The exponent is a property of the rule's gradient estimate (a length noise "
        "sigma read through a nudge eta, balanced by the descent's pull near the minimum it "
        "settles in), whichever minimum that is",
        noun="trials",
    )
    trivially = f" {trivially}" if trivially else ""
    verdict = (
        "not comparable"
        if not np.isfinite(fit["p"])
        else "reproduced"
        if abs(fit["p"] - 2) <= 0.3
        else "not reproduced"
    )
    doc.finding(
        Finding(
            claim="GCL's noise floor scales like (sigma / eta)^2",
            metric="exponent p of floor = c (sigma/eta)^p fitted over the noise-limited GCL "
            "runs (median floor over trials)",
            measured={
                "p": fit["p"],
                "c": fit["c"],
                "points": fit["n"],
                **counts,
            },
            verdict=verdict,
            rule="reproduced if |p - 2| <= 0.3; not reproduced otherwise; not comparable "
            "with fewer than 3 points over a decade"
            + ("." + trivially.rstrip(".") if trivially else ""),
        )
    )
    if trivially:
        doc.add(trivially.strip())
    # figure: GCL floors against sigma/eta with the fitted line; every rule against sigma
    positive = sigmas > 0
    left = []
    for j, name in enumerate(gcl):
        xs = sigmas[positive] / etas[name]
        ys = [med_floor[name, i] for i in np.flatnonzero(positive)]
        left.append(
            Series(xs, ys, f"eta = {etas[name]:g}", marker="o", style="", color=COLORS[j % 10])
        )
    if np.isfinite(fit["p"]):
        grid = np.logspace(np.log10(min(ratio)), np.log10(max(ratio)), 50)
        left.append(
            Series(
                grid,
                fit["c"] * grid**2,
                f"{fmt(fit['c'])} (sigma/eta)^2",
                style="--",
                color="black",
            )
        )
    right = []
    for j, name in enumerate(names):
        ys = [med_floor[name, i] for i in np.flatnonzero(positive)]
        right.append(Series(sigmas[positive], ys, name, marker="o", color=COLORS[j % 10]))
    panels = [
        Panel(
            left,
            "GCL floor against sigma / eta",
            "sigma / eta",
            "floor of C",
            xscale="log",
            yscale="log",
        ),
        Panel(
            right,
            "every rule against sigma",
            "read-out noise sigma",
            "floor of C",
            xscale="log",
            yscale="log",
        ),
    ]
    doc.figure(
        "noise_floor",
        panels,
        "Floor of the task error C (mean over the last quarter of the steps, median over "
        "trials) against sigma / eta for GCL at every nudge, with the fitted "
        "c (sigma/eta)^2 line (left), and against sigma for every rule (right); diverged "
        "trials have no floor and are not drawn.",
        ncols=2,
    )
