"""Why the physical_time relaxation times differ from the `relaxation` scene's: the task
units' linear modes (:mod:`....scenes.units_time_modes`), shown as two tables, a paragraph
and findings by stated rules (:func:`modes_section`).

The `relaxation` scene reports the slowest-mode time of a lattice with one side held and
its continuum (within 5 % of each other, ~ n^2); physical_time's ``tau`` is the target
strain's 1 % settling time after a local source step. The tables give, per size and draw,
the slowest-mode times of both media with their own clamps and with the clamps and edges
matched, and which mode sets ``tau`` and with what weight.
"""

from __future__ import annotations

import math

import numpy as np

from ...document import Document, fmt
from ...findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding

#: Slowest-mode times of the two media "agree" within this relative difference ...
MODE_AGREEMENT = 0.10
#: ... and the modal prediction of tau "reproduces" the measured tau within this.
MODAL_AGREEMENT = 0.10
#: ... in every draw whose modes do not cancel at the target by more than this (sum of
#: weights): beyond it the 1 % band is under 1e-4 of the deviation, near the resolution.
CANCELLING = 100.0
#: tau / tau_mode "varies over draws" when its largest over its smallest at one size and
#: medium exceeds this.
DRAW_SPREAD = 2.0
#: Exponent range of tau_mode ~ n^p counted as diffusive growth (overdamped: 2).
EXPONENT = (1.5, 3.0)

_MEDIA = ("network", "continuum")


def _with_modes(tasks) -> list:
    """Task units whose media carry modes (both media when both ran)."""
    return [
        u
        for u in tasks
        if any((u.medium_times(m) or {}).get("modes") for m in _MEDIA)
        and all(u.medium_times(m).get("modes") for m in _MEDIA if u.medium_times(m) is not None)
    ]


def _exponent(tasks, medium: str, key: str) -> float:
    """Least-squares slope of log(geometric mean over draws of ``key``) on log n; nan with
    fewer than two sizes."""
    sizes = sorted({u.n for u in tasks})
    if len(sizes) < 2:
        return math.nan
    gm = [
        float(np.exp(np.mean([np.log(_get(u, medium, key)) for u in tasks if u.n == n])))
        for n in sizes
    ]
    return float(np.polyfit(np.log(sizes), np.log(gm), 1)[0])


def _get(u, medium: str, key: str) -> float:
    m = u.medium_times(medium)
    return float(m[key] if key in ("tau", "tau_force") else m["modes"][key])


def _mode_table(doc: Document, tasks, both: bool) -> None:
    rows = []
    for u in tasks:
        net = (u.network or {}).get("modes", {})
        body = (u.continuum or {}).get("modes", {})
        glob = u.global_step or {}
        rows.append(
            [
                u.n_nodes,
                u.draw,
                fmt(net.get("tau_mode_nodes", math.nan)),
                fmt(net.get("tau_mode_constraint", math.nan)),
                fmt(net.get("tau_mode_edges", math.nan)),
                fmt(body.get("tau_mode", math.nan)),
                fmt(body["tau_mode"] / net["tau_mode_edges"]) if both else "-",
                fmt(glob.get("tau_mode", math.nan)) if glob else "-",
            ]
        )
    doc.table(
        [
            "N",
            "draw",
            "network (end nodes held)",
            "network (strain clamp, as run)",
            "network (strain clamp, body's edges)",
            "continuum",
            "continuum / matched network",
            "relaxation scene's drive",
        ],
        rows,
    )


def _settling_table(doc: Document, tasks, media) -> None:
    rows = []
    for medium in media:
        for u in tasks:
            m = u.medium_times(medium)
            d = m["modes"]
            rows.append(
                [
                    medium,
                    u.n_nodes,
                    u.draw,
                    fmt(m["tau"]),
                    fmt(d["tau_modal"]),
                    fmt(d["tau_mode"]),
                    fmt(m["tau"] / d["tau_mode"]),
                    fmt(d["slow_weight"]),
                    fmt(d["displacement_share"]),
                    f"{fmt(d['setting_time'])} ({fmt(d['setting_weight'])})",
                    fmt(d["cancellation"]),
                ]
            )
    for u in tasks:
        g = u.global_step
        if g:
            rows.append(
                [
                    "relaxation scene's drive (network)",
                    u.n_nodes,
                    "-",
                    "-",
                    fmt(g["tau_modal"]),
                    fmt(g["tau_mode"]),
                    fmt(g["tau_modal"] / g["tau_mode"]),
                    fmt(g["slow_weight"]),
                    fmt(g["displacement_share"]),
                    f"{fmt(g['setting_time'])} ({fmt(g['setting_weight'])})",
                    fmt(g["cancellation"]),
                ]
            )
    doc.table(
        [
            "medium",
            "N",
            "draw",
            "tau",
            "tau_modal",
            "tau_mode",
            "tau / tau_mode",
            "slowest mode's weight",
            "slowest mode's share of d0",
            "setting mode: time (weight)",
            "sum of weights",
        ],
        rows,
    )


def modes_section(doc: Document, tasks) -> None:
    """Slowest-mode times, the modes that set tau and the findings (task units with modes;
    nothing when none has them)."""
    tasks = _with_modes(tasks)
    if not tasks:
        return
    media = [m for m in _MEDIA if tasks[0].medium_times(m) is not None]
    both = len(media) == 2
    doc.add(
        "Relaxation times against the `relaxation` scene. That scene holds one side of the "
        "lattice, steps the other and reports the slowest-mode time tau_mode = 1 / "
        "lambda_min of C u' + K u = 0, within 5 % between network and continuum and growing "
        "about as n^2. Here the drive is a local source step and tau reads one target "
        "strain. The task units compute the same linear modes for this scene's media and "
        "clamps (`scenes/units_time_modes.py`; linear about the unstressed lattice, all "
        "modes by a dense eigensolve): tau_mode with the clamps as run (both media hold "
        "only the source's strain: the network's source a chord-strain constraint, the "
        "continuum's material spring), the network's with the source's end nodes held "
        "instead (the other way to clamp a spring), and with the body's edges as "
        "well (the P1 body on the lattice's triangles is exactly the network with each "
        "edge spring at half stiffness and the drag per node area, lumped; its stiffness "
        "matrix equals that Hessian). Last column: the relaxation scene's drive on the "
        "same lattice, computed the same way."
    )
    _mode_table(doc, tasks, both)
    doc.add(
        "Which mode sets tau. The deviation d0 from the new equilibrium just after the step "
        "is expanded in the C-orthonormal modes; each mode's weight is its term in the "
        "target strain over the target's total change Delta (the scale of the 1 % band). "
        "A mode of time tau_i and weight w_i keeps the target outside the band until about "
        "tau_i ln(w_i / 0.01); the setting mode is the one for which this is longest. "
        "tau_modal is the settling time of the whole modal sum, the linear prediction of "
        "the measured tau. 'sum of weights' is 1 when every mode moves the target the same "
        "way and large when the modes nearly cancel (a small Delta, so a narrow band). For "
        "the relaxation scene's drive the read-out is every free coordinate (its 'tau / "
        "tau_mode' is tau_modal / tau_mode)."
    )
    _settling_table(doc, tasks, media)
    doc.add(_verdict_text(tasks, media))
    findings = _findings(tasks, media, both)
    for f in findings:
        doc.finding(f)
    doc.findings_table(findings)


def _ratios(tasks, medium: str) -> dict[int, list[float]]:
    """tau / tau_mode per size."""
    out: dict[int, list[float]] = {}
    for u in tasks:
        out.setdefault(u.n_nodes, []).append(
            u.medium_times(medium)["tau"] / u.medium_times(medium)["modes"]["tau_mode"]
        )
    return out


def _verdict_text(tasks, media) -> str:
    """One computed paragraph: exponents, the range of tau / tau_mode and the weights."""
    parts = []
    for medium in media:
        r = [x for v in _ratios(tasks, medium).values() for x in v]
        w = [u.medium_times(medium)["modes"]["slow_weight"] for u in tasks]
        parts.append(
            f"{medium}: tau_mode ~ n^{fmt(_exponent(tasks, medium, 'tau_mode'))}, tau ~ "
            f"n^{fmt(_exponent(tasks, medium, 'tau'))}; tau / tau_mode {fmt(min(r))} to "
            f"{fmt(max(r))}; the slowest mode's weight {fmt(min(w))} to {fmt(max(w))}"
        )
    grows = all(EXPONENT[0] <= _exponent(tasks, m, "tau_mode") <= EXPONENT[1] for m in media)
    cancel = max(u.medium_times(m)["modes"]["cancellation"] for m in media for u in tasks)
    return (
        "Over sizes and draws (exponents from the geometric means over draws per size): "
        + "; ".join(parts)
        + ". "
        + (
            "The slowest modes of both media grow with size about diffusively, as in the "
            "relaxation scene; "
            if grows
            else f"The slowest-mode exponents lie outside [{EXPONENT[0]:g}, {EXPONENT[1]:g}]; "
        )
        + "tau does not follow the slowest mode because a local step read at one target "
        "gives each mode a weight that depends on where the source and the target lie, and "
        "tau is set by whichever mode's time times ln(weight / 0.01) is largest"
        + (
            f"; where the modes' terms nearly cancel at the target (sum of weights up to "
            f"{fmt(cancel)}) the band is narrow and tau long."
            if cancel > 10
            else "."
        )
    )


def _findings(tasks, media, both: bool) -> list[Finding]:
    out = []
    if both:
        matched = [
            u.continuum["modes"]["tau_mode"] / u.network["modes"]["tau_mode_edges"] for u in tasks
        ]
        as_run = [u.continuum["modes"]["tau_mode"] / u.network["modes"]["tau_mode"] for u in tasks]
        clamp = [
            u.network["modes"]["tau_mode_constraint"] / u.network["modes"]["tau_mode_nodes"]
            for u in tasks
        ]
        dev = max(abs(x - 1.0) for x in matched)
        out.append(
            Finding(
                claim=(
                    "package: the lattice's and its continuum's slowest-mode times agree (as "
                    "in the relaxation scene) once the two are clamped and edged alike"
                ),
                metric=(
                    "continuum tau_mode / network tau_mode with the source as a strain "
                    "constraint, the edge springs halved and the drag per node area, over "
                    "sizes and draws; beside it the ratio as run (both strain-clamped, the "
                    "edges differing) and the factor by which the strain clamp slows the "
                    "network's slowest mode against held end nodes"
                ),
                measured={
                    "largest |matched ratio - 1|": dev,
                    "smallest ratio as run": min(as_run),
                    "largest ratio as run": max(as_run),
                    "smallest clamp factor": min(clamp),
                    "largest clamp factor": max(clamp),
                },
                verdict=REPRODUCED if dev <= MODE_AGREEMENT else NOT_REPRODUCED,
                rule=(
                    f"reproduced when the matched ratio is within {MODE_AGREEMENT:.0%} of 1 "
                    "at every size and draw, otherwise not reproduced"
                ),
            )
        )

    def gaps(resolved: bool) -> list[float]:
        return [
            abs(u.medium_times(m)["modes"]["tau_modal"] / u.medium_times(m)["tau"] - 1.0)
            for m in media
            for u in tasks
            if math.isfinite(u.medium_times(m)["modes"]["tau_modal"])
            and (u.medium_times(m)["modes"]["cancellation"] <= CANCELLING) == resolved
        ]

    errs, apart = gaps(True), gaps(False)
    out.append(
        Finding(
            claim=(
                "package: the measured tau is the settling of the linear modes after the "
                "source step (the modal sum predicts it)"
            ),
            metric=(
                "|tau_modal / tau - 1|, largest over media, sizes and draws; a draw whose "
                f"modes cancel at the target (sum of weights > {CANCELLING:g}: the target's "
                f"total change is under 1/{CANCELLING:g} of the modes' terms, so its 1 % band "
                "lies near the clamp's and the solver's resolution) is shown apart"
            ),
            measured={
                "largest |tau_modal / tau - 1|": max(errs) if errs else math.nan,
                f"draws apart (sum of weights > {CANCELLING:g})": len(apart),
                "largest |tau_modal / tau - 1| apart": max(apart) if apart else math.nan,
            },
            verdict=(
                NOT_COMPARABLE
                if not errs
                else REPRODUCED
                if max(errs) <= MODAL_AGREEMENT
                else NOT_REPRODUCED
            ),
            rule=(
                f"reproduced when within {MODAL_AGREEMENT:.0%} everywhere, otherwise not "
                "reproduced; not comparable without the dense modes (large lattices)"
            ),
        )
    )
    spreads = {
        f"{m} N={n} max/min": max(v) / min(v)
        for m in media
        for n, v in _ratios(tasks, m).items()
        if len(v) >= 2
    }
    out.append(
        Finding(
            claim=(
                "package: the target's settling time tau is set by the local source-target "
                "coupling, not by the slowest mode"
            ),
            metric=(
                "tau / tau_mode, largest over smallest over the task draws of one size and medium"
            ),
            measured=spreads or {"sizes with 2 draws": 0},
            verdict=(
                NOT_COMPARABLE
                if not spreads
                else REPRODUCED
                if max(spreads.values()) > DRAW_SPREAD
                else NOT_REPRODUCED
            ),
            rule=(
                f"reproduced when tau / tau_mode varies over the draws of some size and "
                f"medium by more than a factor {DRAW_SPREAD:g}, otherwise not reproduced; not "
                "comparable without a size of two draws"
            ),
        )
    )
    exps = {f"{m} exponent": _exponent(tasks, m, "tau_mode") for m in media}
    finite = [p for p in exps.values() if math.isfinite(p)]
    out.append(
        Finding(
            claim=(
                "relaxation scene: the slowest-mode time grows diffusively with the lattice "
                "side, tau_mode ~ n^2, here with the task's clamps"
            ),
            metric="exponent p of tau_mode ~ n^p (geometric means over draws per size)",
            measured=exps,
            verdict=(
                NOT_COMPARABLE
                if not finite
                else REPRODUCED
                if all(EXPONENT[0] <= p <= EXPONENT[1] for p in finite)
                else NOT_REPRODUCED
            ),
            rule=(
                f"reproduced when every medium's p lies in [{EXPONENT[0]:g}, {EXPONENT[1]:g}]"
                ", otherwise not reproduced; not comparable with one size"
            ),
        )
    )
    return out
