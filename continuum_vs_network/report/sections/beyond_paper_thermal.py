"""Thermal noise in the ``beyond_paper`` section (:mod:`.beyond_paper`): the error floor
against temperature.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..figures import COLORS, Panel, Series
from ..findings import CONTRADICTED, NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED, Finding
from .beyond_paper_format import _g

#: the least rise of a floor that counts as a rise (runs differ by ~1 % at equal settings)
RISE = 1.1


def _thermal(doc, scene, units) -> None:
    L = scene.learning
    temps = L.temperatures
    etas = L.etas or (L.eta,)
    runs = [f"gcl_eta{eta:g}" for eta in etas] + ["exact"]
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
        "noisy free state. Floor: median C/C0 over the last quarter of the "
        f"{L.steps} steps, Stern's task on the {scene.network.sizes[0]} x "
        f"{scene.network.sizes[0]} lattice; every temperature is read over the same steps, "
        "so where a run is still descending there (its error at the end below this "
        "median) the 'floor' is an upper bound and the comparison across T is at equal "
        "steps, not at convergence.",
        "",
    )
    floors = {
        run: [float(units[f"beyond/thermal/T{i}/{run}"].meta["floor"]) for i in range(len(temps))]
        for run in runs
    }
    doc.table(
        ["T", *(f"GCL eta={eta:g}" for eta in etas), "exact gradient"],
        [[f"{T:g}", *(_g(floors[run][i]) for run in runs)] for i, T in enumerate(temps)],
    )
    series = [
        Series(np.array(temps), np.array(floors[run]), run, marker="o",
               color=COLORS[j % len(COLORS)])
        for j, run in enumerate(runs)
    ]  # fmt: skip
    doc.figure(
        "beyond_thermal",
        [Panel(series, "thermal floor", "k_B T", "floor of C / C0", xscale="log",
               yscale="log")],
        "Error floor against temperature for GCL at every nudge and the exact gradient "
        "(T = 0 is off the log axis; its floors are in the table).",
    )  # fmt: skip
    if len(temps) >= 2:
        grows = all(
            all(np.isfinite(f)) and all(b >= RISE * a for a, b in itertools.pairwise(f))
            for f in (floors[run] for run in runs[:-1])
        )
        doc.finding(
            Finding(
                claim="GCL's error floor grows with the temperature at every nudge",
                metric="median C/C0 over the last quarter of the steps, per T and eta",
                measured={f"{run} T={T:g}": floors[run][i] for run in runs[:-1]
                          for i, T in enumerate(temps)},
                verdict=REPRODUCED if grows else NOT_REPRODUCED,
                rule=f"reproduced when, at every eta, the floor rises by a factor >= {RISE:g} "
                "at every step up in T (a smaller rise is within the runs' own spread; every "
                "run completed)",
            )
        )  # fmt: skip
    if len(etas) >= 2 and temps[-1] > 0:
        small, large = floors[runs[0]][-1], floors[runs[len(etas) - 1]][-1]
        if not (np.isfinite(small) and np.isfinite(large)):
            verdict = NOT_COMPARABLE
        elif small > large:
            verdict = REPRODUCED
        else:
            verdict = CONTRADICTED
        doc.finding(
            Finding(
                claim="at a given temperature a larger nudge lowers GCL's floor "
                "(update noise ~ sqrt(T)/eta)",
                metric=f"floor at T = {temps[-1]:g}, smallest and largest eta",
                measured={f"eta={etas[0]:g}": small, f"eta={etas[-1]:g}": large},
                verdict=verdict,
                rule="reproduced when the smallest nudge's floor exceeds the largest's, "
                "contradicted when not; not comparable when a run stopped",
            )
        )
