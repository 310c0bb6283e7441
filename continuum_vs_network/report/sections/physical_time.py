"""physical_time scenes: learning concurrent with the dynamics against the ratio of learning
rate to relaxation rate, the critical ratio against size, and the verdicts."""

from __future__ import annotations

import math

import numpy as np

from ..document import Document, fmt
from ..figures import COLORS, Panel, Series
from ..findings import CONTRADICTED, NOT_REPRODUCED, REPRODUCED, Finding

_NAMES = {
    "gcl": "GCL, twin networks",
    "gcl_phases": "GCL, free and nudged phases",
    "gpc": "GPC, continuous",
    "gcl/continuum": "GCL, twin continua",
    "gcl_phases/continuum": "GCL, phases, continuum",
    "gpc/continuum": "GPC, continuous, continuum",
}
#: Speed-up (learning time at the smallest ratio over the shortest) that counts as "the
#: learning rate speeds learning up", and below which it does not.
SPEEDUP_YES, SPEEDUP_NO = 3.0, 1.5
#: Largest |e - e_qs| (relative errors) at the smallest ratio for "converges to the
#: quasi-static result".
QS_AGREEMENT = 0.05
#: Relative errors above this are not drawn (a diverging run reaches 1e290 and beyond).
ERROR_CAP = 1e6


def _by_rule(result) -> dict[str, list]:
    out: dict[str, list] = {}
    for u in result.select("physical_time/").values():
        medium = u.meta.get("medium", "network")
        key = u.meta["rule"] if medium == "network" else f"{u.meta['rule']}/{medium}"
        out.setdefault(key, []).append(u)
    for units in out.values():
        units.sort(key=lambda u: u.meta["n_nodes"])
    return out


def section(doc: Document, result) -> None:
    """Tables, figures and findings of a physical_time scene."""
    from ...scenes.units_time import OSCILLATION, SLOWDOWN

    scene = result.scene
    spec = scene.physical_time
    rules = _by_rule(result)
    ratios = np.asarray(spec.ratios, float)
    vis = f"node drag c = {spec.drag:g}"
    if spec.dashpot:
        vis += f", spring dashpots gamma = {spec.dashpot:g}"
    if spec.arm_stiffness:
        vis += f", Maxwell arms k2 = {spec.arm_stiffness:g}, gamma2 = {spec.arm_dashpot:g}"
    doc.add(
        "Learning runs concurrently with the overdamped dynamics of the lattice "
        f"({vis}; k = 1), as one system of ODEs "
        "(`learning/physical_time.py`): GPC with sources and targets held and "
        "`dL/dt = alpha k (r - L)` while the nodes move; GCL as twin networks (a free and a "
        "nudged copy evolving together, the update from their difference) or with free and "
        f"nudged phases of {spec.phase:g} relaxation times (shorter when the learning step "
        "needs it). Stern-scale tasks "
        f"({scene.task.n_sources} sources, {scene.task.n_targets} target(s)), bulk learning "
        "(sources and targets frozen), strains against the initial rest lengths, clamps as "
        "held end nodes. The ratio is rho = alpha k tau, with tau the relaxation time after "
        "the source step, measured for each size: the time after which the target strains "
        "(what learning reads) stay within 1 % of their total change of their new "
        "equilibrium (Euclidean norm over the targets; the change from the state before the "
        "step, the equilibrium an exact solve with the sources clamped). tau_force, the time "
        "for the largest net force to stay below 1 % of its start, is shown beside it: local "
        "modes dominate it, so it does not follow the slow modes that the targets do. The "
        "quasi-static limit is the same run with an equilibrium at every step. Errors are "
        "Eq. 26 at the equilibrium free state of the parameters learned so far, relative to "
        "the initial error. Learning time T: when the error has made all but "
        f"{spec.fraction:g} of its quasi-static drop (in the same run length). A run is "
        f"past the quasi-static regime when T is {SLOWDOWN:g} times the quasi-static T or "
        f"the error climbs back to {OSCILLATION:g} times its running minimum (rebound, "
        "oscillation; errors below 1e-6 of the initial one do not count); the critical ratio "
        "is the smallest such ratio (interpolated in log-log"
        + (
            f", after {spec.bisections} bisections in log scale between the last grid ratio "
            "before it and the first past it"
            if spec.bisections
            else ""
        )
        + ")."
        + (
            " The continuum (rows '... continuum'): the lattice's own triangles (P1, lattice "
            "Lamé parameters), learning its eigenstrain with the same rule objects, the same "
            "task's material springs clamped exactly (Lagrange multipliers, not held nodes), "
            "against the lattice's node drag mapped to a substrate drag; its tau and tau_force "
            "by the same criteria (`continuum/damped_states.py`); rho = alpha k tau with the "
            "lattice's k = 1."
            if "continuum" in spec.media
            else ""
        )
    )
    rows = []
    for name, units in rules.items():
        for u in units:
            m = u.meta
            for r in m["runs"]:
                rows.append(
                    [
                        _NAMES[name],
                        m["n_nodes"],
                        fmt(m["tau"]),
                        fmt(r["ratio"]),
                        fmt(r["T"] / m["tau"]),
                        fmt(r["T_qs"] / m["tau"]),
                        fmt(r["slowdown"]),
                        fmt(r["error_at_qs_end"]),
                        fmt(r["error_qs_end"]),
                        fmt(r["error_final"]),
                        "diverged" if r["diverged"] else fmt(r["rebound"]),
                        fmt(r["seconds"] + r["seconds_qs"]),
                    ]
                )
    doc.table(
        [
            "rule",
            "N",
            "tau",
            "rho",
            "T / tau",
            "T_qs / tau",
            "T / T_qs",
            "error at t_qs",
            "quasi-static error",
            "final error",
            "rebound",
            "s",
        ],
        rows,
    )
    doc.add(
        "t_qs = learning_times / (alpha k), the length of the quasi-static run; the "
        "physical run lasts at least "
        f"{spec.relaxation_times:g} relaxation times."
    )
    crit_rows = []
    fits = {}
    for name, units in rules.items():
        N = np.array([u.meta["n_nodes"] for u in units], float)
        c = np.array([u.meta["critical_ratio"] for u in units], float)
        ok = np.isfinite(c)
        if ok.sum() >= 2:
            fits[name] = _slope(np.log(N[ok]), np.log(c[ok]))
        for u in units:
            m = u.meta
            crit_rows.append(
                [
                    _NAMES[name],
                    m["n_nodes"],
                    fmt(m["tau"]),
                    fmt(m["tau_force"]),
                    fmt(m["critical_ratio"])
                    if math.isfinite(m["critical_ratio"])
                    else f"> {ratios[-1]:g}",
                    m["critical_by"],
                ]
            )
    doc.table(["rule", "N", "tau", "tau_force", "critical ratio", "criterion met"], crit_rows)
    _tau_fits(doc, rules)
    if fits:
        doc.add(
            "Critical ratio against N, least-squares fit of log rho* on log N over the sizes "
            "with a critical ratio (exponent +- its standard error; 'no trend' when the "
            "exponent is within two standard errors of 0, 'no error estimate' from two sizes): "
            + "; ".join(f"{_NAMES[k]}: {_describe_fit(*v)}" for k, v in fits.items())
            + "."
        )
    _figures(doc, rules, ratios)
    _findings(doc, rules, ratios)


def _tau_fits(doc: Document, rules: dict) -> None:
    """Exponents of tau and tau_force against N per medium (one rule's units: the times
    depend on the medium and size only)."""
    parts = []
    for medium in ("network", "continuum"):
        same = [u for u in rules.values() if u[0].meta.get("medium", "network") == medium]
        if not same or len(same[0]) < 2:
            continue
        units = same[0]
        N = np.log([u.meta["n_nodes"] for u in units])
        for key in ("tau", "tau_force"):
            t = np.array([u.meta[key] for u in units], float)
            slope, err = _slope(N, np.log(t))
            parts.append(f"{medium} {key}: {_describe_fit(slope, err, key)}")
    if parts:
        doc.add(
            "Relaxation times against N, least-squares fit of log tau on log N (same "
            "conventions): " + "; ".join(parts) + "."
        )


def _slope(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of ``y`` on ``x`` and its standard error (nan from two points)."""
    coef, residuals, *_ = np.polyfit(x, y, 1, full=True)
    if x.size < 3:
        return float(coef[0]), math.nan
    rss = float(residuals[0]) if residuals.size else 0.0
    spread = float(np.sum((x - x.mean()) ** 2))
    return float(coef[0]), math.sqrt(rss / (x.size - 2) / spread)


def _describe_fit(slope: float, error: float, quantity: str = "rho*") -> str:
    """``"quantity ~ N^(slope +- error), trend"``; no trend within two standard errors."""
    if not math.isfinite(error):
        return f"{quantity} ~ N^{slope:.2f} (no error estimate)"
    trend = "no trend" if abs(slope) <= 2 * error else ("grows" if slope > 0 else "falls")
    return f"{quantity} ~ N^({slope:.2f} +- {error:.2f}), {trend}"


def _figures(doc: Document, rules: dict, ratios: np.ndarray) -> None:
    panels = []
    for name, units in rules.items():
        series = []
        for j, u in enumerate(units):
            m = u.meta
            T = np.array([r["T"] for r in m["runs"]]) / m["tau"]
            Tq = np.array([r["T_qs"] for r in m["runs"]]) / m["tau"]
            c = COLORS[j % len(COLORS)]
            series.append(Series(ratios, T, f"N={m['n_nodes']}", marker="o", color=c))
            series.append(
                Series(ratios, Tq, f"N={m['n_nodes']}, quasi-static", style="--", color=c)
            )
        panels.append(
            Panel(series, _NAMES[name], "rho = alpha k tau", "T / tau", xscale="log", yscale="log")
        )
    doc.figure(
        "physical_time_speed",
        panels,
        "Learning time (in relaxation times) against the ratio of learning rate to relaxation "
        "rate; dashed: the quasi-static limit of the same run. Points missing: the level was "
        "not reached.",
    )
    panels = []
    for name, units in rules.items():
        u = units[-1]
        series = []
        for i, ratio in enumerate(ratios):
            a = u.arrays
            c = COLORS[i % len(COLORS)]
            t = a[f"r{i}/times"] / u.meta["tau"]
            e = np.asarray(a[f"r{i}/error"], float)
            e = np.where(e <= ERROR_CAP, e, np.nan)  # diverging runs: drawn up to the cap
            series.append(Series(t, e, f"rho={ratio:g}", color=c))
            tq = a[f"r{i}/times_qs"] / u.meta["tau"]
            series.append(Series(tq, a[f"r{i}/error_qs"], "", style=":", color=c))
        panels.append(
            Panel(
                series,
                f"{_NAMES[name]}, N={u.meta['n_nodes']}",
                "t / tau",
                "error / initial",
                xscale="log",
                yscale="log",
            )
        )
    doc.figure(
        "physical_time_error",
        panels,
        "Error against time (in relaxation times) at the largest size for every ratio; "
        f"dotted: the quasi-static limit; errors above {ERROR_CAP:g} times the initial one "
        "(runs diverging without a failed step) are not drawn.",
    )
    series = []
    for j, (name, units) in enumerate(rules.items()):
        N = [u.meta["n_nodes"] for u in units]
        c = [u.meta["critical_ratio"] for u in units]
        series.append(Series(N, c, _NAMES[name], marker="o", color=COLORS[j % len(COLORS)]))
    doc.figure(
        "physical_time_critical",
        [Panel(series, "critical ratio", "N (nodes)", "rho*", xscale="log", yscale="log")],
        f"Critical ratio against size (grid ratios: {', '.join(f'{r:g}' for r in ratios)}, "
        "then bisected between the bracketing ones where the scene asks; none past the "
        "regime: not drawn).",
    )


def _speedups(units, *, below_critical: bool = False) -> list[float]:
    """Learning time at the smallest ratio over the shortest one, per size; with
    ``below_critical``, only over the ratios below that size's critical ratio."""
    out = []
    for u in units:
        T = np.array([r["T"] for r in u.meta["runs"]], float)
        if below_critical and np.isfinite(u.meta["critical_ratio"]):
            ratio = np.array([r["ratio"] for r in u.meta["runs"]], float)
            T = T[ratio < u.meta["critical_ratio"]]
        out.append(float(T[0] / np.min(T)) if T.size and np.isfinite(T[0]) else math.nan)
    return out


def _findings(doc: Document, rules: dict, ratios: np.ndarray) -> None:
    findings = []
    for name, units in rules.items():
        sp = _speedups(units)
        worst = min(sp) if sp and all(np.isfinite(sp)) else math.nan
        best = max(sp) if sp else math.nan
        if np.isfinite(worst) and worst >= SPEEDUP_YES:
            verdict = CONTRADICTED
        elif np.isfinite(best) and best < SPEEDUP_NO:
            verdict = REPRODUCED
        else:
            verdict = NOT_REPRODUCED
        measured = {f"speed-up N={u.meta['n_nodes']}": s for u, s in zip(units, sp)}
        measured.update({f"rho* N={u.meta['n_nodes']}": u.meta["critical_ratio"] for u in units})
        findings.append(
            Finding(
                claim=(
                    "paper, discussion: the speed of learning cannot be addressed by "
                    f"increasing the learning rate ({_NAMES[name]})"
                ),
                metric=(
                    "speed-up = learning time at the smallest ratio / shortest learning time "
                    f"over ratios {ratios[0]:g}..{ratios[-1]:g}, per size"
                ),
                measured=measured,
                verdict=verdict,
                rule=(
                    f"contradicted when the speed-up is >= {SPEEDUP_YES:g} at every size, "
                    f"reproduced when it is < {SPEEDUP_NO:g} at every size, otherwise not "
                    "reproduced"
                ),
            )
        )
        crit = [u.meta["critical_ratio"] for u in units]
        by = [u.meta["critical_by"] for u in units]
        below = _speedups(units, below_critical=True)
        worst_below = min(below) if below and all(np.isfinite(below)) else math.nan
        ok = all(np.isfinite(crit)) and all(b == "oscillation" for b in by)
        ok = ok and np.isfinite(worst_below) and worst_below >= SPEEDUP_YES
        findings.append(
            Finding(
                claim=(
                    "Stern et al. 2022: learning speeds up with the learning rate until a "
                    "critical ratio of learning rate to relaxation rate, beyond which the "
                    f"error oscillates ({_NAMES[name]})"
                ),
                metric="critical ratio rho* per size, the criterion it met, speed-up below it",
                measured={
                    **{f"rho* N={u.meta['n_nodes']}": c for u, c in zip(units, crit)},
                    "smallest speed-up below rho*": worst_below,
                },
                verdict=REPRODUCED if ok else NOT_REPRODUCED,
                rule=(
                    "reproduced when at every size a critical ratio lies in the tested range, "
                    "met by oscillation (error rebound >= 2), and the speed-up over the ratios "
                    f"below it is >= {SPEEDUP_YES:g}; otherwise not reproduced"
                ),
            )
        )
        gaps = [
            math.inf
            if u.meta["runs"][0]["diverged"]
            else abs(u.meta["runs"][0]["error_at_qs_end"] - u.meta["runs"][0]["error_qs_end"])
            for u in units
        ]
        findings.append(
            Finding(
                claim=(
                    "package: learning in physical time tends to the quasi-static result as "
                    f"the ratio goes to 0 ({_NAMES[name]})"
                ),
                metric=(
                    f"|error - quasi-static error| at t_qs at the smallest ratio ({ratios[0]:g}), "
                    "relative errors, largest over sizes"
                ),
                measured={"largest gap": max(gaps)},
                verdict=REPRODUCED if max(gaps) < QS_AGREEMENT else NOT_REPRODUCED,
                rule=f"reproduced when the gap is < {QS_AGREEMENT:g} at every size",
            )
        )
    for f in findings:
        doc.finding(f)
    doc.findings_table(findings)
