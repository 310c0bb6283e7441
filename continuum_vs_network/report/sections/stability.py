"""Stability scenes: every stiff, extreme or degenerate case, converged or raised.

Equilibria are judged by the local imbalance the scene measures independently of the
solver (net force on a free coordinate over that node's own force scale); dynamics,
continuum locking and learning with stiff springs follow. Every README claim about
stability is a finding with a verdict computed here.
"""

from __future__ import annotations

import math

import numpy as np

from ...scenes.results import from_stored
from ...scenes.results.stability import (
    EquilibriumCaseResult,
    LockingResult,
    StepResult,
    StiffLearningResult,
)
from ..document import Document, fmt
from ..figures import heatmap
from ..findings import CONTRADICTED, NOT_REPRODUCED, REPRODUCED, Finding

__all__ = ["section"]

#: A state reported converged whose local imbalance exceeds this multiple of ``tol`` is a
#: silent failure.
SLACK = 10.0
#: Locking study: an error at least this multiple of the error at the smallest Poisson's
#: ratio (same element, same mesh) is locking, and must be warned about.
LOCKED = 2.0
#: ... and an error below this multiple must not be warned about (no false alarm).
UNLOCKED = 1.5

_GROUPS = {
    "stiff": "stiffness ratios between springs",
    "rod": "the paper's clamp rods",
    "strain": "extreme clamp strains (-0.999 is a clamp at 1e-3 of the rest length)",
    "collinear": "nearly collinear triangles",
    "float32": "float32 input",
}


def _outcome(m: EquilibriumCaseResult, tol: float) -> tuple[str, bool]:
    """(outcome text, honest): honest unless reported converged above SLACK * tol (or a
    floppy network solved instead of refused)."""
    if m.case == "floppy" and not m.error:
        return "SILENT: a floppy network solved", False
    if m.error and not m.converged:
        return "raised " + m.error.split(":", 1)[0], True
    if m.converged:
        ok = np.isfinite(m.imbalance) and m.imbalance <= SLACK * tol
        return ("converged" if ok else "SILENT: converged above tolerance"), bool(ok)
    return "SILENT: not converged, nothing raised", False


def section(doc: Document, result) -> None:
    """Equilibrium cases, dynamics, continuum locking, learning with stiff springs."""
    _equilibria(doc, result)
    st = result.scene.stability
    if st is None:
        return
    if st.explicit_dt or st.implicit_dt:
        _dynamics(doc, result)
    if st.poisson:
        _locking(doc, result)
    if st.learning_stiffness_ratios:
        _learning(doc, result)


def _equilibria(doc: Document, result) -> None:
    from ...scenes.units_stability import case_name, cases

    scene = result.scene
    methods = scene.solver.methods
    tol = scene.solver.tol
    doc.heading("Equilibria: stiff, extreme and degenerate cases")
    doc.add(
        f"A {scene.network.size} x {scene.network.size} triangular lattice (position noise) "
        "with the spring nearest the centre clamped: `stiff_r` has a random "
        f"{scene.network.stiff_fraction:g} of the springs r times stiffer (a soft spring "
        f"clamped at strain {scene.task.strain:g}); `rod_k` clamps with the paper's rod of "
        "stiffness k; `strain_s` clamps exactly at the extreme strain s; `collinear_h` is a "
        "triangle whose apex lies h above its base; `float32` is the lattice in float32; "
        "`floppy` has springs removed until three fewer than 2N - 3 remain and must raise. "
        f"Tolerance {tol:g}, budget {scene.solver.max_seconds:g} s per solve (one BLAS "
        "thread). "
        "**Local imbalance** is measured here, independently of the solver, at the returned "
        "positions: the largest "
        "net force on a free coordinate (clamp-normal components removed by least squares) "
        "over the force scale of that node's own springs, sum k L. A state reported "
        f"converged with a local imbalance above {SLACK:g} x tol is a silent failure."
    )
    rows, names, values, text = [], [], [], []
    metas: dict[tuple[str, str], EquilibriumCaseResult] = {}
    for kind, value in cases(scene):
        name = case_name(kind, value)
        names.append(name)
        vrow, trow = [], []
        for method in methods:
            m = from_stored(result.units[f"stability/{name}/{method}"], EquilibriumCaseResult)
            metas[name, method] = m
            outcome, honest = _outcome(m, tol)
            check = f"{m.check_name} {fmt(m.check)}" if m.check_name else ""
            rows.append(
                [
                    name,
                    method,
                    outcome,
                    fmt(m.imbalance),
                    fmt(m.clamp_error),
                    check,
                    fmt(m.seconds),
                    m.iterations,
                    m.error[:110],
                ]
            )
            r = m.imbalance
            vrow.append(
                math.log10(r) if np.isfinite(r) and r > 0 else (-17.0 if r == 0 else np.nan)
            )
            word = "ok" if outcome == "converged" else ("raised" if honest else "SILENT")
            trow.append(f"{word} {fmt(m.seconds, 2)} s" if np.isfinite(m.seconds) else word)
        values.append(vrow)
        text.append(trow)
    path = heatmap(
        values,
        names,
        list(methods),
        doc.folder / "fig_stability.png",
        text=text,
        title="local imbalance (log10); outcome and time",
        colorbar="log10 local imbalance",
        dpi=doc.dpi,
    )
    doc.image(
        path,
        "Every equilibrium case against every method: colour is the local imbalance at the "
        "returned positions (grey: nothing returned); text: converged (ok), raised an error, "
        "or SILENT (reported converged above tolerance), and the seconds taken.",
    )
    doc.table(
        [
            "case",
            "method",
            "outcome",
            "local imbalance",
            "clamp error / L",
            "check",
            "seconds",
            "iterations",
            "error raised",
        ],
        rows,
    )
    found = []
    if "newton" in methods:
        for kind, group in _GROUPS.items():
            cells = [
                (n, m) for (n, meth), m in metas.items() if meth == "newton" and m.case == kind
            ]
            if not cells:
                continue
            worst = max((m.imbalance for _, m in cells), default=math.nan)
            ok = [
                m.converged and np.isfinite(m.imbalance) and m.imbalance <= SLACK * tol
                for _, m in cells
            ]
            silent = [not _outcome(m, tol)[1] for _, m in cells]
            verdict = CONTRADICTED if any(silent) else (REPRODUCED if all(ok) else NOT_REPRODUCED)
            found.append(
                doc.finding(
                    Finding(
                        source="check",
                        claim=f"README: Newton converges to {tol:g} on {group}",
                        metric="Newton's local imbalance at the returned positions",
                        measured={
                            "cases": len(cells),
                            "converged": sum(ok),
                            "worst imbalance": worst,
                        },
                        verdict=verdict,
                        rule=f"reproduced when every case converged with local imbalance <= "
                        f"{SLACK:g} x tol; contradicted when one reports convergence above that "
                        "(silent); otherwise (an error raised) not reproduced",
                    )
                )
            )
    floppy = [m for (n, _), m in metas.items() if m.case == "floppy"]
    if floppy:
        raised = [m.error.startswith("ValueError") and "floppy" in m.error for m in floppy]
        found.append(
            doc.finding(
                Finding(
                    source="check",
                    claim="README: floppy networks raise a ValueError that counts their zero modes",
                    metric="error raised by every method on a lattice with 2N - 6 springs",
                    measured={"methods": len(floppy), "raised": sum(raised)},
                    verdict=REPRODUCED if all(raised) else CONTRADICTED,
                    rule="reproduced when every method raises a ValueError naming the network "
                    "floppy; contradicted otherwise",
                )
            )
        )
    honest = [_outcome(m, tol)[1] for m in metas.values()]
    found.append(
        doc.finding(
            Finding(
                source="check",
                claim="no method returns a non-converged state as converged",
                metric=f"cases x methods reported converged with local imbalance > {SLACK:g} x tol",
                measured={"rows": len(honest), "silent": len(honest) - sum(honest)},
                verdict=REPRODUCED if all(honest) else CONTRADICTED,
                rule="reproduced when no row is silent; contradicted otherwise",
            )
        )
    )
    doc.findings_table(found)


def _dynamics(doc: Document, result) -> None:
    st = result.scene.stability
    doc.heading("Dynamics: the explicit step limit and stiff implicit steps")
    doc.add(
        f"The same lattice (inertial, unit masses, drag 1), left side held, right side "
        "stepped inwards by 1 % of the width. The explicit scheme runs 200 steps of f times "
        "its stability limit (Gershgorin bound): above 1 it must refuse. Backward Euler and "
        "Newmark run 20 steps of f times the explicit limit on the lattice with "
        f"{result.scene.network.stiff_fraction:g} of its springs {st.implicit_stiffness:g} "
        "times stiffer. Mechanical energy: elastic + kinetic, in model units; local "
        "imbalance at the last step (a relaxed state has none)."
    )
    rows, explicit_ok, implicit_ran, be_energy = [], [], [], []
    growth: list[tuple[float, str, float]] = []  # implicit: end / start energy, scheme, f
    keys = [f"explicit_{f:g}" for f in st.explicit_dt]
    keys += [f"{s}_{f:g}" for s in ("implicit", "newmark") for f in st.implicit_dt]
    for key in keys:
        m = from_stored(result.units[f"stability/dynamics/{key}"], StepResult)
        name = {"implicit": "backward Euler", "newmark": "Newmark", "explicit": "explicit"}[
            m.scheme
        ]
        outcome = "raised " + m.error.split(":", 1)[0] if m.error else "ran"
        rows.append(
            [
                name,
                fmt(m.f),
                fmt(m.dt),
                m.steps,
                outcome,
                fmt(m.energy_start),
                fmt(m.energy_end),
                fmt(m.imbalance),
                fmt(m.seconds),
                m.error[:110],
            ]
        )
        if m.scheme == "explicit":
            if m.f > 1:
                explicit_ok.append(m.error.startswith("ValueError"))
            else:
                explicit_ok.append(not m.error and m.energy_end <= m.energy_start)
        else:
            implicit_ran.append(not m.error and np.isfinite(m.imbalance))
            if not m.error and m.energy_start > 0:
                growth.append((m.energy_end / m.energy_start, name, m.f))
            if m.scheme == "implicit" and not m.error:
                be_energy.append(m.energy_end / m.energy_start)
    doc.table(
        [
            "scheme",
            "dt / explicit limit",
            "dt",
            "steps",
            "outcome",
            "energy at start",
            "energy at end",
            "local imbalance at end",
            "seconds",
            "error raised",
        ],
        rows,
    )
    found = []
    if explicit_ok:
        found.append(
            doc.finding(
                Finding(
                    source="check",
                    claim="the explicit scheme refuses a step above its stability limit and is "
                    "stable below it",
                    metric="explicit runs: refusal above the limit, no energy growth below",
                    measured={"runs": len(explicit_ok), "as claimed": sum(explicit_ok)},
                    verdict=REPRODUCED if all(explicit_ok) else CONTRADICTED,
                    rule="reproduced when every run above the limit raises ValueError and every "
                    "run below ends with no more mechanical energy than it started with",
                )
            )
        )
    if implicit_ran:
        worst = max(growth, default=(float("nan"), "", float("nan")))
        found.append(
            doc.finding(
                Finding(
                    source="check",
                    claim="every implicit step's Newton solve converges far above the "
                    "explicit limit on stiff lattices (a claim about the solves, not the "
                    "trajectory's stability)",
                    metric="backward Euler and Newmark runs completed without an error; the "
                    "largest end / start mechanical energy beside it",
                    measured={
                        "runs": len(implicit_ran),
                        "completed": sum(implicit_ran),
                        "largest energy ratio": worst[0],
                    },
                    verdict=REPRODUCED if all(implicit_ran) else NOT_REPRODUCED,
                    rule="reproduced when every run completes (each step's Newton solve "
                    "converged); not reproduced when one raises. 'Converge' means the "
                    "solves, not the trajectory: the energy ratio is not judged here",
                )
            )
        )
        grew = [g for g in growth if g[0] > 1.0]
        doc.add(
            "",
            "*Converge* in the finding below means every implicit step's Newton solve "
            "converged; it says nothing about the trajectory. "
            + (
                "Runs that end with more mechanical energy than they started with, despite "
                "the drag: "
                + ", ".join(f"{n} at {fmt(f)} x the limit ({fmt(r)} x)" for r, n, f in grew)
                + "."
                if grew
                else "No implicit run ends with more mechanical energy than it started with."
            ),
        )
    newmark = [g for g in growth if "newmark" in str(g[1]).lower()] if implicit_ran else []
    if newmark:
        worst_nm = max(newmark)
        found.append(
            doc.finding(
                Finding(
                    source="field",
                    claim="the damped trapezoidal (Newmark) step adds no mechanical energy at "
                    "steps far above the explicit limit (A-stable)",
                    metric="mechanical energy at the end over the start, Newmark runs with drag",
                    measured={"runs": len(newmark), "largest ratio": worst_nm[0]},
                    verdict=REPRODUCED if worst_nm[0] <= 1.0 else CONTRADICTED,
                    rule="reproduced when no Newmark run ends with more mechanical energy than "
                    "it started with; contradicted otherwise (the nonlinear springs are outside "
                    "the linear A-stability argument)",
                )
            )
        )
    if be_energy:
        found.append(
            doc.finding(
                Finding(
                    source="check",
                    claim="backward Euler never adds mechanical energy, whatever the step "
                    "(L-stable)",
                    metric="mechanical energy at the end over the start, backward Euler runs",
                    measured={"runs": len(be_energy), "largest ratio": max(be_energy)},
                    verdict=REPRODUCED if max(be_energy) <= 1.0 else CONTRADICTED,
                    rule="reproduced when no run ends with more mechanical energy than it "
                    "started with; contradicted otherwise",
                )
            )
        )
    doc.findings_table(found)


def _locking(doc: Document, result) -> None:
    from ...continuum.body import LOCKING_RATIO

    st = result.scene.stability
    doc.heading("Continuum: locking of P1 elements as nu -> 0.5")
    doc.add(
        f"Lamé's cylinder (as in the accuracy scene; mesh size h = {st.locking_h:g}) at "
        "several Poisson's ratios, P1 and curved P2. Locking inflates P1's error against the "
        "closed form; the ratio is the error over that element's error at the smallest "
        f"Poisson's ratio on the same mesh. The package warns (LockingWarning) for P1 when "
        f"lam / mu > {LOCKING_RATIO:g}."
    )
    rows, calls = [], []
    for element in ("P1", "P2_curved"):
        metas = [
            from_stored(result.units[f"stability/locking/{element}_nu{nu:g}"], LockingResult)
            for nu in st.poisson
        ]
        base = metas[int(np.argmin([m.poisson for m in metas]))].error
        for m in metas:
            nu = m.poisson
            ratio = m.error / base
            rows.append(
                [
                    element,
                    fmt(nu),
                    fmt(2 * nu / (1 - 2 * nu)),
                    m.dofs,
                    fmt(m.error),
                    fmt(ratio),
                    "yes" if m.warned else "no",
                ]
            )
            if element == "P1":
                if ratio >= LOCKED:
                    calls.append(m.warned)
                elif ratio < UNLOCKED:
                    calls.append(not m.warned)
    doc.table(
        ["element", "nu", "lam / mu", "DOFs", "L2 error", "error / error at smallest nu", "warned"],
        rows,
    )
    if calls:
        doc.findings_table(
            [
                doc.finding(
                    Finding(
                        source="check",
                        claim="P1 warns where locking inflates its error, and not elsewhere",
                        metric="P1 cases: warned iff error >= "
                        f"{LOCKED:g} x the error at the smallest nu",
                        measured={"cases judged": len(calls), "warned correctly": sum(calls)},
                        verdict=REPRODUCED if all(calls) else CONTRADICTED,
                        rule=f"a case with error ratio >= {LOCKED:g} must warn, one below "
                        f"{UNLOCKED:g} must not (in between either); reproduced when every "
                        "judged case does",
                    )
                )
            ]
        )


def _learning(doc: Document, result) -> None:
    st = result.scene.stability
    doc.heading("Learning with stiff springs")
    doc.add(
        f"Coupled learning (alpha 1e-3, eta 0.1, strains against the initial rest lengths) "
        f"for {st.learning_steps} steps on the lattice with "
        f"{result.scene.network.stiff_fraction:g} of its springs r times stiffer, a Stern "
        "task of 3 sources and 2 targets. A run either completes or stops with a stated "
        "reason; nothing it returns may be NaN."
    )
    rows, ok = [], []
    for r in st.learning_stiffness_ratios:
        m = from_stored(result.units[f"stability/learning/stiff_{r:g}"], StiffLearningResult)
        rows.append(
            [
                fmt(r),
                f"{m.completed} / {m.steps}",
                fmt(m.ratio_error),
                m.error[:110] or "-",
                fmt(m.seconds),
            ]
        )
        ok.append(bool(m.finite) and (m.completed == m.steps or bool(m.error)))
    doc.table(["stiffness ratio", "steps done", "final C / C0", "stop reason", "seconds"], rows)
    doc.findings_table(
        [
            doc.finding(
                Finding(
                    source="check",
                    claim="learning on stiff lattices completes or stops with a stated reason, "
                    "never NaN",
                    metric="runs that completed, or stopped with a reason, with finite errors",
                    measured={"runs": len(ok), "as claimed": sum(ok)},
                    verdict=REPRODUCED if all(ok) else CONTRADICTED,
                    rule="reproduced when every run does; contradicted otherwise",
                )
            )
        ]
    )
