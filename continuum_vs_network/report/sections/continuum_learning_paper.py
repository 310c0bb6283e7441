"""The paper's 1 -> 1 task in the continuum (a part of the ``continuum_learning`` section,
:mod:`.continuum_learning`): table and finding at every refinement.
"""

from __future__ import annotations

import math

import numpy as np

from ...learning.coupling import DECOUPLED_BELOW
from ..document import fmt, mesh_name
from ..findings import NOT_REPRODUCED, REPRODUCED, Finding
from .continuum_learning_measures import TOLERANCE, steps_to


def _paper(doc, units, R: int, rule: str) -> None:
    doc.heading("The paper's 1 -> 1 task in the continuum", 3)
    rows, finals = [], []
    for r in range(R + 1):
        u = units[f"continuum_learning/paper/refine{r}"]
        e = np.asarray(u.arrays["error"], dtype=float)
        finals.append(float(e[-1] / e[0]) if np.isfinite(e[-1]) else math.inf)
        rows.append(
            [
                mesh_name(r),
                u.meta["n_dofs"],
                fmt(u.meta["source_strain"][0]),
                fmt(u.meta["target_strain"][0]),
                fmt(steps_to(e)),
                fmt(e[-1] / e[0]),
                f"{fmt(u.meta['source_share'], 2)} ({u.meta['coupling']})",
            ]
        )
    doc.add(
        f"One source and one target material spring with the paper's strains (about 5; "
        f"linear elasticity is scale-free), rule `{rule}`:"
    )
    doc.table(
        [
            "continuum",
            "DOFs",
            "source strain",
            "target strain",
            "steps to 1e-3",
            "C/C0 at the end",
            "source share (coupling)",
        ],
        rows,
    )
    worst = max(finals)
    share = min(
        float(units[f"continuum_learning/paper/refine{r}"].meta["source_share"])
        for r in range(R + 1)
    )
    learned = worst <= TOLERANCE and share >= DECOUPLED_BELOW
    doc.finding(
        Finding(
            source="paper",
            claim="paper, discussion (Sec. 1, 8): a visco-elastic material learns the paper's "
            "1 -> 1 task by a local rule (here: an elastic continuum)",
            metric=f"final C/C0 and source share at every refinement (rule {rule})",
            measured={"largest C/C0": worst, "smallest source share": share},
            verdict=REPRODUCED if learned else NOT_REPRODUCED,
            rule=f"reproduced when C/C0 <= {TOLERANCE:g} and the medium is not decoupled "
            f"(source share >= {DECOUPLED_BELOW:g}) at every refinement; a decoupled medium "
            "met the task by prestressing the target",
        )
    )
