"""Coupling of the states learned in physical time (:mod:`.units_time`).

A physical_time run learns a Stern task with bulk learning (sources and targets frozen):
the bulk may meet it trivially by prestressing the targets. The final learned state of
every run that did not diverge (the last recorded learning arrays of its
:class:`~..learning.physical_time.TimeHistory`: rest lengths and stiffnesses, a body's
eigenstrain and modulus fields) is measured by the rule of every other learning scene,
:func:`~..learning.coupling.source_share` and
:func:`~..learning.coupling.coupling_verdict`, from the target strains of the final and
the initial state with the sources on (the task) and off (zero strain), each at the free
state the run itself reads:

* a network: sources held by their lengths as stiff rods, no node held
  (:func:`~..learning.time_media.held_free_state`, the state of the run's recorded error).
  :func:`~..learning.coupling.measure_coupling` is not used: its solver holds the clamps as
  length constraints, another boundary condition (on a 5 x 5 lattice its initial error is
  5 % off the run's);
* a continuum: its free state with the clamps as exact strain constraints, as the
  continuum_learning scene measures a trained body
  (:func:`~..learning.coupling.body_source_share`).

The unit's verdict (meta ``"coupling"``, read by
:func:`~..report.sections.physical_time.findings.coupling_reason`) is
:func:`~..learning.coupling.coupling_verdict` of the smallest source share over its runs
measured (grid and bisection): the findings compare learning times across every ratio, so
a run decoupled at any ratio makes the unit's claims about learning not comparable. None
when no run could be measured (all diverged, or no equilibrium of the final state).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["coupling_rule", "final_coupling", "final_share", "final_state", "unit_coupling"]


def coupling_rule() -> dict[str, Any]:
    """The verdict's thresholds, which a run unit's stored verdict depends on (part of its
    fingerprint: a unit stored under other thresholds, or before runs measured coupling,
    is recomputed)."""
    from ..learning.coupling import COUPLED_AT, DECOUPLED_BELOW

    return {"coupled_at": COUPLED_AT, "decoupled_below": DECOUPLED_BELOW}


def final_state(run) -> tuple[np.ndarray, np.ndarray]:
    """The last recorded learning arrays of ``run``: rest lengths and stiffnesses
    ((n_springs,) each), a body's eigenstrain ((n_elements, 3)) and modulus
    ((n_elements,)) fields."""
    return run.rest_length[-1], run.stiffness[-1]


def final_share(initial, task, run, medium: str) -> float | None:
    """Source share of ``run``'s final learned state (None: its state at the task or with
    the sources off has no equilibrium).

    Parameters
    ----------
    initial : SpringNetwork or LearnableBody
        The medium the run started from.
    task : AllosteryTask or MaterialTask
    run : TimeHistory
        A run of :func:`~..learning.physical_time.learn_in_time` on ``initial``.
    medium : {"network", "continuum"}
    """
    from ..learning.coupling import source_share
    from ..learning.time_media import held_free_state

    rest, stiff = final_state(run)
    try:
        if medium == "network":
            trained = initial.with_rest_length(rest).with_stiffness(stiff)
            off = task.with_source_strain(np.zeros(task.n_sources))

            def strains(net, t):
                x = held_free_state(net, t, reference="initial")
                return t.target_strains(net, net.lengths(x, t.targets), "initial")

            return source_share(
                strains(trained, task), strains(trained, off), strains(initial, off),
                strains(initial, task),
            )  # fmt: skip
        from ..learning.coupling import body_source_share

        trained = initial.with_eigenstrain(rest)
        if not np.array_equal(stiff, initial.modulus):  # keeps the shared factorisations
            trained = trained.with_modulus(stiff)
        return float(body_source_share(initial, trained, task))
    except RuntimeError:  # no equilibrium (EquilibriumError, a step that did not converge)
        return None


def final_coupling(initial, task, run, medium: str) -> dict[str, Any]:
    """A run's ``{"source_share": share, "coupling": verdict}`` (:func:`final_share`; both
    None for a diverged run, ``run`` None, or a final state without equilibrium)."""
    from ..learning.coupling import coupling_verdict

    share = None if run is None else final_share(initial, task, run, medium)
    return {"source_share": share, "coupling": None if share is None else coupling_verdict(share)}


def unit_coupling(rows: list[dict]) -> dict[str, Any]:
    """The unit's ``{"coupling": verdict, "source_share": smallest share}`` from its runs'
    ``"source_share"`` (None for a run diverged or not measured); both None when no run was
    measured."""
    from ..learning.coupling import coupling_verdict

    shares = [r["source_share"] for r in rows if r.get("source_share") is not None]
    if not shares:
        return {"coupling": None, "source_share": None}
    share = min(shares)
    return {"coupling": coupling_verdict(share), "source_share": share}
