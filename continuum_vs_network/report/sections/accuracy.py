"""Accuracy scenes: every method's error against its run time.

Finite elements on Lamé's cylinder (error against DOFs and seconds), network and continuum
time integrators (error against the time step and seconds). Convergence orders are fitted
and judged against the textbook orders by a stated rule.
"""

from __future__ import annotations

import math

import numpy as np

from ...fits import power_law
from ...scenes.results import from_stored
from ...scenes.results.accuracy import FiniteElementResult, IntegratorResult
from ..document import Document, fmt
from ..figures import COLORS, Panel, Series
from ..findings import CONTRADICTED, NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding

__all__ = ["convergence_order", "section"]

#: Textbook order of the relative L2 displacement error in the mesh size h.
FE_ORDER = {"P1": 2.0, "P2": 2.0, "P2_curved": 3.0}
#: Textbook global order in the time step.
SCHEME_ORDER = {"backward_euler": 1.0, "newmark": 2.0, "explicit": 1.0}
_SCHEME_NAMES = {
    "backward_euler": "backward Euler",
    "newmark": "Newmark (trapezoidal)",
    "explicit": "explicit",
}
_ELEMENT_NAMES = {
    "P1": "P1",
    "P2": "P2, straight-sided",
    "P2_curved": "P2, curved (isoparametric)",
}
_TOLERANCE = 0.3
_FIT_POINTS = 3
_ASYMPTOTIC = 0.05  # an order is asymptotic: judged only where the error is below this


def _at_smallest(step: np.ndarray, error: np.ndarray) -> float:
    """The error at the smallest step with a finite error (NaN when none)."""
    ok = np.isfinite(error)
    return float(error[ok][np.argmin(step[ok])]) if ok.any() else math.nan


def convergence_order(step: np.ndarray, error: np.ndarray, points: int = _FIT_POINTS) -> float:
    """Slope of log(error) against log(step) over the ``points`` smallest finite steps."""
    step, error = np.asarray(step, dtype=float), np.asarray(error, dtype=float)
    ok = np.isfinite(step) & np.isfinite(error) & (step > 0) & (error > 0)
    step, error = step[ok], error[ok]
    if step.size < 2:
        return math.nan
    order = np.argsort(step)[:points]
    return power_law(step[order], error[order]).exponent


def _order_verdict(measured: float, expected: float, smallest_error: float) -> str:
    if math.isfinite(smallest_error) and smallest_error > _ASYMPTOTIC:
        return NOT_COMPARABLE
    if math.isfinite(measured) and abs(measured - expected) <= _TOLERANCE:
        return REPRODUCED
    if not math.isfinite(measured) or measured < expected / 2:
        return CONTRADICTED
    return NOT_REPRODUCED


_ORDER_RULE = (
    f"slope of log(error) against log(step) over the {_FIT_POINTS} smallest steps: "
    f"not comparable when the error at the smallest step exceeds {_ASYMPTOTIC:g} (not yet "
    f"asymptotic); else reproduced within +-{_TOLERANCE} of the expected order, "
    "contradicted below half of it (or no fit), otherwise not reproduced"
)


def section(doc: Document, result) -> None:
    """Finite elements and time integrators: error against step and against seconds."""
    a = result.scene.accuracy
    _finite_elements(doc, result, a)
    _integrators(doc, result, a)


def _finite_elements(doc: Document, result, a) -> None:
    doc.heading("Finite elements: error against DOFs and against run time")
    doc.add(
        "Lamé's thick cylinder (radii 1 and 2, unit pressure inside, the outside clamped; "
        f"plane strain, Young's modulus 1, Poisson's ratio {a.poisson:g}) on ring meshes of "
        "size h. Error: relative L2 norm of the displacement error against the closed form "
        "u_r = A r + B / r. Seconds: the whole solve (mesh, basis, assembly, factorisation, "
        "solve), after a warm-up solve, with one BLAS thread. P2 on straight-sided "
        "triangles sees a polygonal boundary, a geometric error of order h^2; isoparametric "
        "P2 follows the circles."
    )
    rows, dof_s, time_s, summary = [], [], [], []
    for j, element in enumerate(a.elements):
        runs = [
            from_stored(result.units[f"accuracy/fe/{element}/h{h:g}"], FiniteElementResult)
            for h in a.mesh_sizes
        ]
        h = np.array([r.h for r in runs])
        err = np.array([r.error for r in runs])
        dofs = np.array([r.dofs for r in runs], dtype=float)
        secs = np.array([r.seconds for r in runs])
        rate = convergence_order(h, err)
        label = f"{_ELEMENT_NAMES[element]} (h^{rate:.2f})"
        dof_s.append(Series(dofs, err, label, marker="o", color=COLORS[j]))
        time_s.append(Series(secs, err, _ELEMENT_NAMES[element], marker="o", color=COLORS[j]))
        for r in runs:
            rows.append(
                [
                    _ELEMENT_NAMES[element],
                    fmt(r.h),
                    r.dofs,
                    fmt(r.error),
                    fmt(r.seconds),
                    "yes" if r.warned else "no",
                ]
            )
        fine = int(np.argmin(h))
        summary.append(
            [
                _ELEMENT_NAMES[element],
                f"{rate:.2f}",
                runs[fine].dofs,
                fmt(err[fine]),
                fmt(secs[fine], 2),
            ]
        )
        expected = FE_ORDER[element]
        doc.finding(
            Finding(
                source="check",
                claim=f"{_ELEMENT_NAMES[element]} elements converge at order {expected:g} in h "
                "(L2 displacement error)",
                metric="relative L2 displacement error on Lamé's cylinder against h",
                measured={"order": rate, "finest error": _at_smallest(h, err)},
                verdict=_order_verdict(rate, expected, _at_smallest(h, err)),
                rule=_ORDER_RULE,
            )
        )
    doc.figure(
        "fe_accuracy",
        [
            Panel(
                dof_s,
                "error against degrees of freedom",
                "DOFs",
                "relative L2 error",
                xscale="log",
                yscale="log",
            ),
            Panel(
                time_s,
                "error against wall-clock time",
                "seconds (whole solve)",
                "relative L2 error",
                xscale="log",
                yscale="log",
            ),
        ],
        "Lamé's cylinder: displacement error against DOFs (left; fitted order in h in the "
        "legend) and against the wall-clock seconds of the whole solve (right).",
    )
    doc.table(["element", "h", "DOFs", "L2 error", "seconds", "locking warning"], rows)
    doc.summary(
        "finite_elements",
        "Finite elements on Lamé's cylinder: fitted order in h, error and seconds of the "
        "finest mesh",
        ["element", "order", "DOFs", "L2 error", "seconds"],
        summary,
    )
    doc.findings_table([f for f in doc.findings if f.section.startswith("Finite elements")])


def _integrators(doc: Document, result, a) -> None:
    doc.heading("Time integrators: error against the time step and against run time")
    doc.add(
        f"Network: a {a.size} x {a.size} triangular lattice (spacing 1, k = 1, unit masses), "
        "left side held, right side stepped inwards by 1 % of the width, run for one "
        "slowest-mode time (overdamped, drag 1) or half a period of the slowest mode "
        "(inertial, drag 0.1); error: the largest distance of any node from an independent "
        "reference (SciPy DOP853, rtol 1e-12) at any step, over the step displacement. "
        "Continuum: a P2 block (2 x 1, left edge clamped) started in its lowest mode, "
        "against the closed form exp(-t / tau) (overdamped, one tau) or cos(omega t) "
        "(inertial, 0.3 periods); error: the largest DOF error at the end over the mode "
        "amplitude. Time in the model's units (spacing 1, k = 1, unit mass and drag). "
        "Dashed: the explicit scheme's stability limit (Gershgorin bound); an explicit step "
        "above it is refused with a ValueError."
    )
    panels, rows, refused_ok, summary = [], [], [], []
    for medium in ("network", "continuum"):
        for problem in a.problems:
            dt_s, time_s = [], []
            limit = math.nan
            for j, scheme in enumerate(a.schemes):
                if medium == "continuum" and scheme == "explicit":
                    continue
                runs = [
                    from_stored(
                        result.units[f"accuracy/{medium}/{problem}/{scheme}/n{n}"],
                        IntegratorResult,
                    )
                    for n in a.steps
                ]
                dt = np.array([r.dt for r in runs])
                err = np.array([r.error for r in runs], dtype=float)
                secs = np.array([r.seconds for r in runs], dtype=float)
                rate = convergence_order(dt, err)
                name = _SCHEME_NAMES[scheme]
                dt_s.append(Series(dt, err, f"{name} (dt^{rate:.2f})", marker="o", color=COLORS[j]))
                time_s.append(Series(secs, err, name, marker="o", color=COLORS[j]))
                for r in runs:
                    if r.dt_limit is not None:
                        limit = r.dt_limit
                    rows.append(
                        [
                            medium,
                            problem,
                            name,
                            r.steps,
                            fmt(r.dt),
                            fmt(r.dt / r.dt_limit) if r.dt_limit is not None else "-",
                            fmt(r.error),
                            fmt(r.seconds),
                            (r.refused or "")[:110],
                        ]
                    )
                    if scheme == "explicit":
                        above = r.dt > r.dt_limit
                        refused_ok.append(above == bool(r.refused))
                ok = np.isfinite(err)
                best = int(np.flatnonzero(ok)[np.argmin(dt[ok])]) if ok.any() else 0
                summary.append(
                    [
                        f"{medium}, {problem}",
                        name,
                        f"{rate:.2f}",
                        fmt(err[best]),
                        fmt(secs[best], 2),
                    ]
                )
                expected = SCHEME_ORDER[scheme]
                doc.finding(
                    Finding(
                        source="check",
                        claim=f"{name} converges at order {expected:g} in dt ({medium}, {problem})",
                        metric="largest error over the run against the time step",
                        measured={"order": rate, "smallest-step error": _at_smallest(dt, err)},
                        verdict=_order_verdict(rate, expected, _at_smallest(dt, err)),
                        rule=_ORDER_RULE,
                    )
                )
            vl = (limit,) if math.isfinite(limit) else ()
            panels += [
                Panel(
                    dt_s,
                    f"{medium}, {problem}: error vs dt",
                    "time step dt (model time units)",
                    "error / amplitude",
                    xscale="log",
                    yscale="log",
                    vlines=vl,
                ),
                Panel(
                    time_s,
                    f"{medium}, {problem}: error vs run time",
                    "wall-clock seconds",
                    "error / amplitude",
                    xscale="log",
                    yscale="log",
                ),
            ]
    doc.figure(
        "integrators_accuracy",
        panels,
        "Error of every time integrator against the time step (left; fitted order in the "
        "legend, over the three smallest steps) and against wall-clock seconds (right). "
        "Refused or failed runs have no point.",
    )
    doc.summary(
        "time_integrators",
        "Time integrators: fitted order in dt, error and seconds at the smallest step",
        ["problem", "scheme", "order", "error", "seconds"],
        summary,
    )
    doc.table(
        [
            "medium",
            "problem",
            "scheme",
            "steps",
            "dt",
            "dt / explicit limit",
            "error",
            "seconds",
            "refused",
        ],
        rows,
    )
    if refused_ok:
        doc.finding(
            Finding(
                source="check",
                claim="the explicit network scheme refuses exactly the steps above its "
                "stability limit and runs every step below it",
                metric="explicit runs whose refusal matches dt > limit",
                measured={"matching": sum(refused_ok), "runs": len(refused_ok)},
                verdict=REPRODUCED if all(refused_ok) else CONTRADICTED,
                rule="reproduced when every explicit run is refused if and only if its dt "
                "exceeds the limit; contradicted otherwise",
            )
        )
    doc.findings_table([f for f in doc.findings if f.section.startswith("Time integrators")])
