"""The quasi-static reference of a physical_time scene that learns stiffnesses.

With ``[physical_time] dof = "stiffness"`` the rule is GCL with the package's adaptive
rate (no raw ``alpha``: a raw rate on stiffnesses is ill-conditioned, its line scales with
the squared strain), and the ratio of learning rate to relaxation rate is
``rho = tau / T_qs``: the medium's relaxation time over the quasi-static learning time.
:func:`reference_run` measures, per size, task draw and medium, the quasi-static run
(every physical step an equilibrium) at one adaptive step per time unit over
:data:`REFERENCE_STEPS` steps: ``steps_qs``, the steps it takes to make all but ``[physical_time]
fraction`` of its drop (:func:`~.units_time.crossing_time`), its final C/C0, and the coupling
of its final state (:mod:`.units_time_coupling`). The draw is *learned* when that run
reaches C/C0 <= :data:`~..learning.coupling.MET_AT` with a coupled verdict; then a run at
ratio ``rho`` takes ``step_time = tau / (rho steps_qs)`` per adaptive step, so that its
quasi-static learning time is ``tau / rho``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .results.physical_time import TimeRunResult

__all__ = ["REFERENCE_STEPS", "not_learned_result", "reference_run"]

#: Adaptive steps of the quasi-static reference run (the learning window that decides
#: whether a draw is learned).
REFERENCE_STEPS = 300


def reference_run(scene, learner, task, medium: str, vis) -> dict[str, Any]:
    """The quasi-static reference of one medium (module docstring): ``{"steps_qs",
    "error_qs", "source_share", "coupling", "learned", "seconds"}``."""
    import time

    from ..learning.coupling import MET_AT
    from ..learning.physical_time import learn_in_time
    from .units_time import _rule, crossing_time
    from .units_time_coupling import final_coupling

    spec = scene.physical_time
    rule = _rule("gcl", None, spec.eta, "stiffness")
    t0 = time.perf_counter()
    run = learn_in_time(
        learner, task, rule, viscosity=vis, duration=float(REFERENCE_STEPS), dt=1.0,
        n_outputs=REFERENCE_STEPS, quasistatic=True, step_time=1.0, form="twin",
    )  # fmt: skip
    e = run.error / run.error[0]
    level = e[-1] + spec.fraction * (1.0 - e[-1])
    out: dict[str, Any] = {
        "steps_qs": crossing_time(run.times, e, level),
        "error_qs": float(e[-1]),
        "seconds": time.perf_counter() - t0,
    }
    out.update(final_coupling(learner, task, run, medium))
    out["learned"] = bool(
        out["error_qs"] <= MET_AT and out["coupling"] == "coupled" and np.isfinite(out["steps_qs"])
    )
    return out


def not_learned_result(
    params: dict, n_nodes: int, rule: str, medium: str, ref: dict
) -> TimeRunResult:
    """A run unit of a draw whose quasi-static reference did not learn
    (:func:`reference_run`): no ratio is run, the unit counts apart."""
    return TimeRunResult(
        learned_qs=False,
        n=params["n"],
        draw=params.get("draw", 0),
        n_nodes=n_nodes,
        rule=rule,
        medium=medium,
        dof="stiffness",
        tau=ref["tau"],
        tau_force=ref["tau_force"],
        steps_qs=ref.get("steps_qs"),
        error_qs=ref.get("error_qs"),
        reference_coupling=ref.get("coupling"),
        coupling=ref.get("coupling"),
        source_share=ref.get("source_share"),
        runs=[],
        bisection=[],
        critical_low=math.nan,
        critical_high=math.nan,
        critical_ratio=math.nan,
        critical_by="not learned",
        non_monotone=0,
        series_ratio=None,
    )
