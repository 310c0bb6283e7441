"""Thermal noise in the ``beyond_paper`` section (:mod:`.`): the error floor
against temperature. Floors are told settled or not by the plateau test of
:func:`~continuum_vs_network.learning.metrics.tail_change` and
:func:`~continuum_vs_network.learning.metrics.bound`.
"""

from __future__ import annotations

import itertools

import numpy as np

from ....learning.metrics import PLATEAU, bound, tail_change
from ....scenes.results.beyond_paper import ThermalResult
from ...document import fmt
from ...figures import COLORS, Panel, Series
from ...findings import (
    CONTRADICTED,
    NOT_COMPARABLE,
    NOT_REPRODUCED,
    REPRODUCED,
    Finding,
    reasoned,
    runs_basis,
)
from ..learning.noise import decoupled_caveat

#: the least rise of a floor that counts as a rise (runs differ by ~1 % at equal settings)
RISE = 1.1
#: the noise-free baseline has converged when its final C/C0 is below every thermal floor
#: of its run by this factor (the floors are then the noise's, not the budget's)
CONVERGED_BELOW = 10.0


def baseline_converged(final0: float, floors) -> bool:
    """Whether a noise-free run's final C/C0 ``final0`` is at least :data:`CONVERGED_BELOW`
    times below every finite floor of ``floors`` (the same run at T > 0)."""
    finite = [f for f in floors if np.isfinite(f)]
    return bool(np.isfinite(final0) and finite and final0 * CONVERGED_BELOW <= min(finite))


def _at_least(kind: str) -> bool:  # the settled value is >= the floor read
    return kind in ("plateau", "lower bound")


def _at_most(kind: str) -> bool:  # the settled value is <= the floor read
    return kind in ("plateau", "upper bound")


def rises(floors, kinds, *, factor: float = RISE) -> str:
    """Verdict of "the floor rises by ``factor`` at every step up" over one sequence of
    floors (lowest T first) with their :func:`bound` kinds: reproduced when every rise is
    shown whatever the unsettled runs still do (the higher floor cannot fall, the lower
    cannot rise), not reproduced when some step's missing rise is shown the same way, not
    comparable otherwise (a floor not finite, or a transient that could go either way)."""
    verdicts = []
    for (a, ka), (b, kb) in itertools.pairwise(zip(floors, kinds)):
        if not (np.isfinite(a) and np.isfinite(b)):
            verdicts.append(NOT_COMPARABLE)
        elif b >= factor * a and _at_least(kb) and _at_most(ka):
            verdicts.append(REPRODUCED)
        elif b < factor * a and _at_most(kb) and _at_least(ka):
            verdicts.append(NOT_REPRODUCED)
        else:
            verdicts.append(NOT_COMPARABLE)
    if NOT_REPRODUCED in verdicts:
        return NOT_REPRODUCED
    return REPRODUCED if all(v == REPRODUCED for v in verdicts) else NOT_COMPARABLE


def coupling_cell(metas: dict[str, ThermalResult]) -> str:
    """The coupling of the runs at one temperature (``metas``: run label -> result with
    ``coupling`` and ``source_share``), in words: one verdict with its share range when all
    agree, else each run's."""
    verdicts = {k: m.coupling for k, m in metas.items()}
    shares = [m.source_share for m in metas.values()]
    if len(set(verdicts.values())) == 1:
        (v,) = set(verdicts.values())
        lo, hi = float(np.nanmin(shares)), float(np.nanmax(shares))
        share = fmt(lo, 2) if lo == hi else f"{fmt(lo, 2)} to {fmt(hi, 2)}"
        return f"all {v} (source share {share})"
    return "; ".join(f"{k} {v} ({fmt(x, 2)})" for (k, v), x in zip(verdicts.items(), shares))


def bounds_caption(points) -> str:
    """Which floors have plateaued by the plateau test and what the others are, computed
    from ``points``: (label, :func:`bound` kind) pairs."""
    plateau = [p for p, k in points if k == "plateau"]
    parts = [
        "plateaued by the plateau test (fitted change of C over the last quarter at most "
        f"{PLATEAU:.0%}): " + (", ".join(plateau) if plateau else "none")
    ]
    rest = len(points) - len(plateau)
    for kind, what in (
        ("upper bound", "upper bounds (C still falling: the run settles lower)"),
        ("lower bound", "lower bounds (C still rising: the run settles higher)"),
        ("unknown", "not known (no finite change)"),
    ):
        these = [p for p, k in points if k == kind]
        if these:
            every = "every other point" if plateau else "every point"
            parts.append(f"{what}: {every if len(these) == rest else ', '.join(these)}")
    return "; ".join(parts)


def _thermal(doc, scene, units) -> None:
    L = scene.learning
    temps = L.temperatures
    etas = L.etas or (L.eta,)
    runs = [f"gcl_eta{eta:g}" for eta in etas] + ["exact"]
    n = scene.network.sizes[-1]
    doc.heading("Thermal noise: the error floor against temperature", 3)
    doc.add(
        "Learning at temperature T (k_B T in energy units): every state a rule reads (free, "
        "nudged) is one draw of its thermal fluctuations, sampled exactly in the harmonic "
        "approximation (the Gaussian with covariance T times the inverse Hessian on the "
        "directions pins and clamps leave free: the stationary law of overdamped Langevin "
        "dynamics there, drawn without time-step error or burn-in); states are found as "
        "equilibria and the error is measured at equilibrium. GCL divides the difference of "
        "two noisy states by eta, so its update noise grows like sqrt(T)/eta (the scaling of "
        "the floor is not fitted here); the exact gradient reads one "
        "noisy free state. Both learn the stiffnesses (default rules, adaptive rate) of "
        f"Rocks et al.'s task on the {n} x {n} lattice with its rest example, a task they "
        "learn without noise (a network at rest learning stiffnesses has no prestress to "
        "meet it with). Floor: median C/C0 over the last quarter of the "
        f"{L.steps} steps; every temperature is read over the same steps, "
        "so where a run is still descending there (its error at the end below this "
        "median) the 'floor' is an upper bound and the comparison across T is at equal "
        "steps, not at convergence.",
        "",
    )
    metas: dict[str, list[ThermalResult]] = {
        run: [units[f"beyond/thermal/T{i}/{run}"] for i in range(len(temps))] for run in runs
    }
    floors = {run: [float(m.floor) for m in metas[run]] for run in runs}
    changes = {run: [tail_change(m.error) for m in metas[run]] for run in runs}
    kinds = {run: [bound(c) for c in changes[run]] for run in runs}
    labels = {run: f"GCL eta={eta:g}" for run, eta in zip(runs, etas)} | {"exact": "exact"}
    doc.add(
        "Plateau test: the fitted relative change of C over the same last quarter (a least "
        f"squares line through log C against the step); a floor is a *plateau* when it is at "
        f"most {PLATEAU:.0%}, an *upper bound* when C is still falling faster, a *lower "
        "bound* when it is still rising. A comparison of floors is decided only when the "
        "unsettled runs cannot reverse it; otherwise it is not comparable. In brackets: the "
        "change and what the floor is.",
        "",
    )
    doc.table(
        ["T", *(f"GCL eta={eta:g}" for eta in etas), "exact gradient", "coupling"],
        [
            [
                f"{T:g}",
                *(
                    f"{fmt(floors[run][i])} ({fmt(100 * changes[run][i], 2)} %, {kinds[run][i]})"
                    for run in runs
                ),
                coupling_cell({labels[run]: metas[run][i] for run in runs}),
            ]
            for i, T in enumerate(temps)
        ],
    )
    series = [
        Series(np.array(temps), np.array(floors[run]), run, marker="o",
               color=COLORS[j % len(COLORS)])
        for j, run in enumerate(runs)
    ]  # fmt: skip
    doc.figure(
        "beyond_thermal",
        [
            Panel(
                series,
                "thermal floor",
                "k_B T (energy: stiffness x length^2)",
                "floor of C / C0",
                xscale="log",
                yscale="log",
            )
        ],
        "The 'floor' (median C/C0 over the last quarter of the steps) against temperature "
        "for GCL at every nudge and the exact gradient (T = 0 is off the log axis; its "
        "floors are in the table). Of these floors, T = 0 included: "
        + bounds_caption(
            [
                (f"{labels[run]} at T = {T:g}", kinds[run][i])
                for run in runs
                for i, T in enumerate(temps)
            ]
        )
        + ".",
    )  # fmt: skip
    unsettled = (
        f"a floor counts as settled when C changes by at most {PLATEAU:.0%} over the last "
        "quarter (fitted); a still-falling run's floor is an upper bound, a still-rising "
        "run's a lower bound"
    )

    def caveat(judged: list[str], which: str) -> tuple[str, dict]:
        """The noise scene's caveat (:func:`.decoupled_caveat`) over the judged GCL runs
        (unit keys under beyond/thermal/; every run records a coupling verdict, "not
        measured" included)."""
        metas = [units[f"beyond/thermal/{k}"] for k in judged]
        return decoupled_caveat(
            [m.coupling for m in metas],
            ratios=[m.ratio for m in metas],
            runs=f"GCL runs judged here ({which}) with a coupling measurement",
            what="The floor is the rule's error under its thermal update noise over the "
            "steps run, whichever minimum the run descends to",
            noun="GCL runs",
        )

    if len(temps) >= 2:
        trivially, counts = caveat(
            [f"T{i}/{run}" for run in runs[:-1] for i in range(len(temps))], "every eta and T"
        )
        per_eta = {run: rises(floors[run], kinds[run]) for run in runs[:-1]}
        final0 = {run: float(metas[run][0].ratio) for run in runs}
        converged = {
            run: baseline_converged(final0[run], floors[run][1:]) if temps[0] == 0 else True
            for run in runs
        }
        reason = ""
        if not all(converged[run] for run in runs[:-1]):
            verdict = NOT_COMPARABLE
            reason = (
                "the noise-free baseline has not converged below the thermal floors ("
                + ", ".join(labels[r] for r in runs[:-1] if not converged[r])
                + ")"
            )
        elif NOT_REPRODUCED in per_eta.values():
            verdict = NOT_REPRODUCED
        elif all(v == REPRODUCED for v in per_eta.values()):
            verdict = REPRODUCED
        else:
            verdict = NOT_COMPARABLE
            reason = "an unsettled run (still falling or rising) could undo a rise"
        doc.finding(
            Finding(
                claim="GCL's error floor grows with the temperature at every nudge",
                metric="median C/C0 over the last quarter of the steps, per T and eta, and "
                "the fitted relative change of C over that quarter",
                measured={
                    **{f"{run} T={T:g}": floors[run][i] for run in runs[:-1]
                       for i, T in enumerate(temps)},
                    **{f"{run} T={T:g} change": changes[run][i] for run in runs[:-1]
                       for i, T in enumerate(temps)},
                    **{f"{run} final C/C0 at T=0": final0[run] for run in runs[:-1]},
                    **counts,
                },
                verdict=verdict,
                rule=reasoned(
                    f"with the noise-free baseline converged (its final C/C0 at least "
                    f"{CONVERGED_BELOW:g} x below every floor of its run at T > 0): reproduced "
                    f"when, at every eta, the floor rises by a factor >= {RISE:g} "
                    "at every step up in T (a smaller rise is within the runs' own spread) and "
                    "no unsettled run can undo a rise; not reproduced when some step's missing "
                    "rise is shown the same way; not comparable otherwise (a run stopped, or a "
                    f"transient decides it): {unsettled}"
                    + (". " + trivially.rstrip(".") if trivially else ""),
                    verdict,
                    reason or "a floor is not finite (a run stopped)",
                ),
                source="field",
                basis=runs_basis(m for run in runs[:-1] for m in metas[run]),
            )
        )  # fmt: skip
        doc.add(
            "Has the noise-free baseline converged? "
            + "; ".join(
                f"{labels[run]}: final C/C0 {fmt(final0[run])} at T = 0, lowest floor at T > 0 "
                f"{fmt(min([f for f in floors[run][1:] if np.isfinite(f)], default=np.nan))}"
                f" ({'converged' if converged[run] else 'not converged'})"
                for run in runs
            )
            + f" (converged: at least {CONVERGED_BELOW:g} x below every floor of its run).",
            "",
        )
        doc.add(
            "Does the floor grow with T? "
            + "; ".join(f"{run}: {v}" for run, v in per_eta.items())
            + f" (rule in the findings); overall **{verdict}**."
            + (
                " Still descending at T = 0 (the baseline): "
                + ", ".join(
                    f"{run} ({fmt(100 * changes[run][0], 2)} % over the last quarter)"
                    for run in runs[:-1]
                    if kinds[run][0] != "plateau"
                )
                + "."
                if any(kinds[run][0] != "plateau" for run in runs[:-1])
                else ""
            )
            + (f" {trivially}" if trivially else ""),
            "",
        )
    if len(etas) >= 2 and temps[-1] > 0:
        small, large = floors[runs[0]][-1], floors[runs[len(etas) - 1]][-1]
        ks, kl = kinds[runs[0]][-1], kinds[runs[len(etas) - 1]][-1]
        reason = ""
        if not (np.isfinite(small) and np.isfinite(large)):
            verdict, reason = NOT_COMPARABLE, "a floor is not finite (a run stopped)"
        elif small > large and _at_least(ks) and _at_most(kl):
            verdict = REPRODUCED
        elif small <= large and _at_most(ks) and _at_least(kl):
            verdict = CONTRADICTED
        else:
            verdict = NOT_COMPARABLE
            reason = "an unsettled run (still falling or rising) could reverse the order"
        trivially, counts = caveat(
            [f"T{len(temps) - 1}/{runs[0]}", f"T{len(temps) - 1}/{runs[len(etas) - 1]}"],
            f"T = {temps[-1]:g}, eta = {etas[0]:g} and {etas[-1]:g}",
        )
        doc.finding(
            Finding(
                claim="at a given temperature a larger nudge lowers GCL's floor "
                "(update noise ~ sqrt(T)/eta)",
                metric=f"floor at T = {temps[-1]:g}, smallest and largest eta, and the fitted "
                "relative change of C over the last quarter",
                measured={
                    f"eta={etas[0]:g}": small,
                    f"eta={etas[-1]:g}": large,
                    f"eta={etas[0]:g} change": changes[runs[0]][-1],
                    f"eta={etas[-1]:g} change": changes[runs[len(etas) - 1]][-1],
                    **counts,
                },
                verdict=verdict,
                rule=reasoned(
                    "reproduced when the smallest nudge's floor exceeds the largest's, "
                    "contradicted when not, in both cases only when the unsettled runs cannot "
                    "reverse the order; not comparable otherwise or when a run stopped: "
                    f"{unsettled}" + (". " + trivially.rstrip(".") if trivially else ""),
                    verdict,
                    reason,
                ),
                source="field",
                basis=runs_basis([metas[runs[0]][-1], metas[runs[len(etas) - 1]][-1]]),
            )
        )
