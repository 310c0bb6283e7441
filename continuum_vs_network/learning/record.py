"""What a training run records: one trial's arrays, filled after every step.

The arrays are the columns of :class:`~.history.History` (names in :data:`~.history.MEASUREMENTS`,
measured at steps ``0 .. steps``, and :data:`~.history.UPDATES`, one per step): ``rec[name][t]``
is written by :func:`record_update` (the rule's step), :func:`record_measure` (the free state
after it) and :func:`record_time` (wall-clock and solver counters).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..network.model import SpringNetwork
from .examples import TaskSet
from .history import MEASUREMENTS, UPDATES
from .medium import is_medium
from .node_tasks import NodeTask
from .step import Step

__all__ = [
    "COUNTERS",
    "new_record",
    "record_bytes",
    "record_measure",
    "record_time",
    "record_update",
]

_PER_TARGET = {
    "target_strain",
    "target_length",
    "target_rest_length",
    "desired_length",
    "clamp_length",
}
COUNTERS = ("solves", "factorisations", "iterations")


def record_bytes(steps: int, n_targets: int) -> int:
    """Bytes of one trial's history arrays (:func:`new_record`), a Python int (no overflow)."""
    per_target = len(_PER_TARGET)
    scalars = len(MEASUREMENTS) + len(UPDATES) - per_target
    return 8 * (steps + 1) * (scalars + per_target * max(int(n_targets), 1))


def new_record(steps: int, n_targets: int) -> dict[str, NDArray]:
    """One trial's arrays, all NaN: ``(steps + 1,)`` or ``(steps,)``, ``(.., n_targets)``
    for the per-target columns."""
    rec = {}
    for names, length in ((MEASUREMENTS, steps + 1), (UPDATES, steps)):
        for name in names:
            shape = (length, n_targets) if name in _PER_TARGET else (length,)
            rec[name] = np.full(shape, np.nan)
    return rec


def record_measure(rec, t, net, task, rule, free, mask) -> None:
    """Row ``t`` of the measurements: the task's desired values and, with ``free`` (the
    free state, a list of them for a task set, or None when not measured), the targets,
    errors, free energy and its gradient over the learning ``mask``."""
    if isinstance(task, TaskSet):
        _record_examples(rec, t, net, task, rule, free, mask)
        return
    if isinstance(task, NodeTask):
        _record_nodes(rec, t, net, task, rule, free, mask)
        return
    if is_medium(net):
        if free is not None:
            for name, value in net.measurements(task, free, rule.dof, mask).items():
                rec[name][t] = value
        return
    ref = rule.strain_reference
    rec["target_rest_length"][t] = net.rest_length[task.targets]
    rec["desired_length"][t] = task.desired_lengths(net, ref)
    if free is None:
        return
    x = free.positions
    r_t = net.lengths(x, task.targets)
    rec["target_length"][t] = r_t
    rec["target_strain"][t] = task.target_strains(net, r_t, ref)
    rec["error_current"][t] = task.error(net, x, "current")
    rec["error_initial"][t] = task.error(net, x, "initial")
    rec["energy_free"][t] = free.energy
    rec["energy_gradient_free"][t] = _energy_gradient(net, x, rule.dof, mask)
    rec["residual"][t] = free.residual


def _record_examples(rec, t, net, tasks: TaskSet, rule, free, mask) -> None:
    """A task set: summed errors and energies, the examples' target values side by side,
    ``|sum_e dE_e/dtheta|`` and the largest residual."""
    ref = rule.strain_reference
    node = tasks.node_outputs  # node examples: outputs and displacements, as _record_nodes
    if not node:
        rec["target_rest_length"][t] = net.rest_length[tasks.targets]
    rec["desired_length"][t] = tasks.desired_lengths(net, ref)
    if free is None:
        return
    xs = [f.positions for f in free]
    if node:
        out = [k.outputs(x) for x, k in zip(xs, tasks.tasks)]
        rec["target_length"][t] = np.concatenate(out)
        rec["target_strain"][t] = np.concatenate(
            [o - k.reference for o, k in zip(out, tasks.tasks)]
        )
    else:
        r_t = np.concatenate([net.lengths(x, k.targets) for x, k in zip(xs, tasks.tasks)])
        rec["target_length"][t] = r_t
        rec["target_strain"][t] = np.concatenate(
            [k.target_strains(net, net.lengths(x, k.targets), ref) for x, k in zip(xs, tasks.tasks)]
        )
    rec["error_current"][t] = tasks.error(net, xs, "current")
    rec["error_initial"][t] = tasks.error(net, xs, "initial")
    rec["energy_free"][t] = float(sum(f.energy for f in free))
    rec["energy_gradient_free"][t] = _summed_gradient(net, xs, rule.dof, mask)
    rec["residual"][t] = float(max(f.residual for f in free))


def _record_nodes(rec, t, net, task: NodeTask, rule, free, mask) -> None:
    """A node task: ``target_length`` holds the target coordinates, ``target_strain`` their
    displacements, ``desired_length`` the desired coordinates; one error (no strain)."""
    rec["desired_length"][t] = task.desired
    if free is None:
        return
    x = free.positions
    out = task.outputs(x)
    rec["target_length"][t] = out
    rec["target_strain"][t] = out - task.reference
    rec["error_current"][t] = rec["error_initial"][t] = task.error(net, x)
    rec["energy_free"][t] = free.energy
    rec["energy_gradient_free"][t] = _energy_gradient(net, x, rule.dof, mask)
    rec["residual"][t] = free.residual


def _energy_gradient(net: SpringNetwork, x: NDArray, dof: str, mask: NDArray) -> float:
    return _summed_gradient(net, [x], dof, mask)


def _summed_gradient(net: SpringNetwork, xs: list, dof: str, mask: NDArray) -> float:
    """``|sum_x dE/dtheta(x)|`` over the learning springs (both rows for ``dof="both"``)."""
    g = 0.0
    for x in xs:
        dr = net.lengths(x) - net.rest_length
        by = {"rest_length": -net.stiffness * dr, "stiffness": 0.5 * dr**2}
        g = g + (np.stack([by["rest_length"], by["stiffness"]]) if dof == "both" else by[dof])
    return float(np.linalg.norm(np.asarray(g)[..., mask]))


def record_update(rec, t, step: Step, net, rule, mask) -> None:
    """Row ``t`` of the updates: the step's norm and its clamped (or nudged) state."""
    rec["update_norm"][t] = float(np.linalg.norm(step.delta))
    if step.examples is not None:
        clamped = [s.clamped for s in step.examples]
        if all(c is not None for c in clamped):
            rec["energy_clamped"][t] = float(sum(c.energy for c in clamped))
            xs = [c.positions for c in clamped]
            rec["energy_gradient_clamped"][t] = _summed_gradient(net, xs, rule.dof, mask)
            rec["clamp_length"][t] = np.concatenate([s.clamp_lengths for s in step.examples])
        return
    if step.clamped is not None and is_medium(net):
        rec["energy_clamped"][t] = step.clamped.energy
        g = net.local_gradient(step.clamped, rule.dof)
        rec["energy_gradient_clamped"][t] = float(np.linalg.norm(g[mask]))
    elif step.clamped is not None:
        rec["energy_clamped"][t] = step.clamped.energy
        rec["energy_gradient_clamped"][t] = _energy_gradient(
            net, step.clamped.positions, rule.dof, mask
        )
    if step.clamp_lengths is not None:
        rec["clamp_length"][t] = step.clamp_lengths


def record_time(rec, t, seconds, measure_seconds, counters) -> None:
    """Row ``t`` of the running totals: wall-clock seconds and the solver :data:`COUNTERS`."""
    rec["seconds"][t] = seconds
    rec["measure_seconds"][t] = measure_seconds
    for name in COUNTERS:
        rec[name][t] = counters[name]
