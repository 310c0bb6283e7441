"""The task unit of physical_time scenes (phase 0 of :mod:`.units_time`): one per size and
task draw, the task, each medium's relaxation times and, learning stiffnesses, its
quasi-static reference (:mod:`.units_time_reference`).

Per medium: ``tau`` (the target strains' settling time after the source step) and
``tau_force`` (the net force's), and the linear modes behind ``tau``
(:mod:`.units_time_modes`, keys under ``modes``): the slowest-mode time ``tau_mode`` of
``C u' + K u = 0`` with the medium's own clamps, the slowest mode's and the setting mode's
weights in the target's response, the modal prediction ``tau_modal`` of ``tau``; the
network's also with the source clamp as a strain constraint and with the body's edges.
Empty with Maxwell arms (their internal strains add modes the analysis leaves out).
Draw 0 of each size adds ``global``: the `relaxation` scene's drive (one side held, the
other stepped) on the same lattice, by the same modal analysis.
"""

from __future__ import annotations

from typing import Any

from .results.physical_time import TimeTaskResult
from .schema import Scene
from .units import UnitContext

__all__ = ["task_unit"]


def task_unit(scene: Scene, params: dict, ctx: UnitContext) -> TimeTaskResult:
    """The task of one size and draw, and each medium's ``tau``, ``tau_force`` and modes."""
    from ..learning.physical_time import network_relaxation_time
    from .units_time import _body, _lattice_task, _viscosity
    from .units_time_modes import body_modes, global_step_share, network_modes

    n, draw = params["n"], params["draw"]
    net, task = _lattice_task(scene, n, draw)
    vis = _viscosity(scene)
    media: dict[str, dict[str, Any]] = {}
    stiffness = scene.physical_time.dof == "stiffness"
    for medium in scene.physical_time.media:
        reference: dict[str, Any] = {}
        if medium == "network":
            tau, tau_force = (
                network_relaxation_time(net, task, vis, measure=m) for m in ("target", "force")
            )
            modes = network_modes(net, task, vis) if not vis.has_arm else {}
            if stiffness:
                from .units_time_reference import reference_run

                reference = reference_run(scene, net, task, medium, vis)
        else:
            from ..continuum.damped_states import body_relaxation_time
            from ..continuum.viscoelastic import lattice_damping

            body, mtask = _body(net, task)
            damping = lattice_damping(vis)
            tau, tau_force = (
                body_relaxation_time(body, mtask, damping, measure=m) for m in ("target", "force")
            )
            modes = body_modes(body, mtask, damping) if not damping.has_arm else {}
            if stiffness:
                from .units_time_reference import reference_run

                reference = reference_run(scene, body, mtask, medium, vis)
        media[medium] = {"tau": float(tau), "tau_force": float(tau_force), "modes": modes}
        media[medium].update(reference)
    return TimeTaskResult(
        n=n,
        draw=draw,
        n_nodes=net.n_nodes,
        sources=task.sources,
        source_strain=task.source_strain,
        targets=task.targets,
        target_strain=task.target_strain,
        pinned=task.pinned,
        network=media.get("network"),
        continuum=media.get("continuum"),
        global_step=global_step_share(net, vis) if draw == 0 and not vis.has_arm else None,
    )
