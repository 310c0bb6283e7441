"""Units of a ``continuum_learning`` scene: a lattice and its continuum learn the same task.

One triangular lattice (``[network] size``), one Stern-scale task on it (``[task]``), and
for every rule of ``[learning] rules`` the *same* rule object trains

* ``continuum_learning/network/<rule>``: the spring network (rest lengths);
* ``continuum_learning/refine<r>/<rule>``, ``r = 0 .. [continuum] refine``: the elastic
  continuum on the lattice's own triangles, refined ``r`` times (element size ``h / 2^r``),
  P1 or P2 (``[continuum] order``), learning its eigenstrain field. Sources and targets are
  the material springs between the same material points, clamped and read exactly.
* ``continuum_learning/relaxation`` (after the training units): the trained network and
  the trained continuum on the lattice triangles (first rule) at rest with the sources off;
  the sources are switched on at ``t = 0`` and both creep against node drag ``c = 1``
  (its continuum equivalent, :func:`~continuum_vs_network.continuum.node_drag_to_continuum`).
  Both are driven by a strain clamp: the continuum by
  :func:`~continuum_vs_network.continuum.learned_relaxation.source_step` (the source
  strains exact constraints), the network by
  :func:`~continuum_vs_network.network.strain_clamp.simulate_strain_clamped` (overdamped
  backward Euler, each source spring a rod of ``ROD_FACTOR`` times the mean stiffness at
  the clamp length, its end nodes otherwise free). Beside them, the network run as
  :func:`~continuum_vs_network.network.dynamics.simulate` holds clamps (both end nodes
  prescribed: ``network_nodes_*``). Target strains against time, the time to settle
  within 10 % of their values at the end of the run, the gap between those and the
  exact-clamp free state, and the rods' largest strain error.
* ``continuum_learning/paper/refine<r>``: the paper's one-source, one-target task
  (:func:`~continuum_vs_network.learning.tasks.paper_task` strains, about 5) on the same
  continuum patch with the first rule (linear elasticity: the continuum is scale-free; the
  network at strain 5 is far outside linear response and is not compared there).

Rules (``[learning] rules``), as in Stern-scale learning scenes: ``gcl``, ``gpc`` and
``exact`` learn in the bulk (the material of the sources and targets frozen: the network's
source and target springs, the continuum's elements their material springs cross; the task
is then not met by a target learning its own rest state); ``gcl_all`` and ``gpc_all`` let
everything learn. Learning rates are ``[learning] alpha_*`` for both media: the
continuum's update is per unit area, so a rate means the same on every mesh.

Each unit records the error and the wall-clock seconds after every step, the coupling of
the trained medium (:mod:`~continuum_vs_network.learning.coupling`: the source share
and its verdict), and the learned
field: the continuum's eigenstrain per element and averaged onto the lattice triangles, the
network's rest-length changes as the rest strain of each lattice triangle
(:func:`~continuum_vs_network.continuum.learned_fields.network_rest_strain`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .results import from_stored
from .results.continuum_learning import ContinuumRun, LearnedRelaxationResult, NetworkRun
from .schema import CONTINUUM_RULES, Scene
from .units import Unit, UnitContext

__all__ = ["continuum_rule", "plan_continuum_learning"]

#: time step and duration of the source-step relaxation (units of drag / stiffness)
RELAX_DT, RELAX_T_END = 1.0, 200.0


def continuum_rule(scene: Scene, name: str):
    """The rule object ``name`` of the scene (it trains the network *and* the continuum)."""
    from ..learning.rules import CoupledLearning, ExactGradient, ProspectiveConfiguration

    L = scene.learning
    bulk = not name.endswith("_all")
    common: dict[str, Any] = {
        "strain_reference": "initial",
        "learn_sources": not bulk,
        "learn_targets": not bulk,
    }
    base = name.removesuffix("_all")
    if base == "gcl":
        return CoupledLearning(L.alpha_gcl, L.eta, **common)
    if base == "gpc":
        return ProspectiveConfiguration(L.alpha_gpc, **common)
    if base == "exact":
        return ExactGradient(L.alpha_exact, **common)
    raise ValueError(f"continuum_learning rules are {', '.join(CONTINUUM_RULES)}; got {name!r}")


def plan_continuum_learning(scene: Scene) -> list[Unit]:
    """Network and continuum units for every rule and refinement (one phase)."""
    d = scene.to_dict()
    depends = {k: d[k] for k in ("seed", "network", "task", "learning", "continuum") if k in d}
    rules = scene.learning.rules
    units = []
    for rule in rules:
        units.append(
            Unit(
                key=f"continuum_learning/network/{rule}",
                func=network_unit,
                params={"rule": rule},
                depends=depends,
                weight=scene.learning.steps,
                parallel=False,
            )
        )
        for r in range(scene.continuum.refine + 1):
            units.append(
                Unit(
                    key=f"continuum_learning/refine{r}/{rule}",
                    func=continuum_unit,
                    params={"rule": rule, "refine": r, "task": "stern"},
                    depends=depends,
                    weight=scene.learning.steps,
                    parallel=False,
                )
            )
    units.append(
        Unit(
            key="continuum_learning/relaxation",
            func=relaxation_unit,
            params={"rule": rules[0], "dt": RELAX_DT, "t_end": RELAX_T_END},
            depends=depends,
            phase=1,
            parallel=False,
        )
    )
    for r in range(scene.continuum.refine + 1):
        units.append(
            Unit(
                key=f"continuum_learning/paper/refine{r}",
                func=continuum_unit,
                params={"rule": rules[0], "refine": r, "task": "paper"},
                depends=depends,
                weight=scene.learning.steps,
                parallel=False,
            )
        )
    return units


def _lattice_and_task(scene: Scene, which: str):
    from ..learning.tasks import paper_task, stern_task
    from ..network.builders import triangular_lattice

    n = scene.network.size
    noise = scene.network.noise or 0.0
    rng = np.random.default_rng([scene.seed, n])
    net = triangular_lattice(n, n, noise=noise, rng=rng if noise > 0 else None)
    t = scene.task
    if which == "paper":
        return net, paper_task(net, np.random.default_rng([scene.seed, n, 1]))
    task = stern_task(
        net, t.n_sources, t.n_targets, rng, source_std=t.source_std, target_std=t.target_std
    )
    return net, task


def _training(h) -> dict[str, Any]:
    """The fields every training run records (see :class:`~.results.continuum_learning._Training`)
    but the rule and the coupling."""
    return {
        "error": h.error_initial[0],
        "seconds_trace": h.seconds[0],
        "completed": int(h.completed[0]),
        "stop_reason": h.stop_reason[0],
        "factorisations": float(np.nan_to_num(h.factorisations[0, -1])),
        "solves": float(np.nan_to_num(h.solves[0, -1])),
    }


def _steps_callback(ctx: UnitContext):
    if ctx.on_step is None:
        return None
    return lambda trial, step, net: ctx.on_step()


def network_unit(scene: Scene, params: dict, ctx: UnitContext) -> NetworkRun:
    """Train the lattice with the rule; its learned rest strain on its own triangles."""
    from ..continuum.learned_fields import network_rest_strain
    from ..continuum.mesh import network_faces
    from ..learning.train import train

    net, task = _lattice_and_task(scene, "stern")
    rule = continuum_rule(scene, params["rule"])
    h = train(
        net,
        task,
        rule,
        scene.learning.steps,
        progress=False,
        callback=_steps_callback(ctx),
    )
    faces = network_faces(net)
    from ..learning.coupling import measure_coupling, outcome

    coupling = measure_coupling(net, h.final[0], task)
    return NetworkRun(
        **_training(h),
        coarse=network_rest_strain(net, h.final[0], faces),
        points=net.positions,
        triangles=faces,
        rest_change=h.final[0].rest_length / net.rest_length - 1.0,
        sources=task.sources,
        targets=task.targets,
        springs=net.springs,
        n_nodes=net.n_nodes,
        n_springs=net.n_springs,
        rule=rule.settings(),
        source_share=coupling.share,
        coupling=coupling.verdict,
        outcome=outcome(float(h.error_initial[0, -1] / h.error_initial[0, 0]), coupling.verdict),
    )


def continuum_unit(scene: Scene, params: dict, ctx: UnitContext) -> ContinuumRun:
    """Train the continuum at one refinement with the rule; its learned eigenstrain."""
    from ..continuum.learnable import learnable_body
    from ..continuum.learned_fields import coarse_average
    from ..continuum.material_task import MaterialTask
    from ..continuum.materials import lattice_lame
    from ..continuum.mesh import network_mesh
    from ..learning.train import train

    net, task = _lattice_and_task(scene, params["task"])
    c = scene.continuum
    material = lattice_lame(float(np.mean(net.stiffness)))
    t0 = time.perf_counter()
    lattice_body = learnable_body(network_mesh(net), material, order=c.order)
    body = (
        lattice_body
        if params["refine"] == 0
        else learnable_body(network_mesh(net, refine=params["refine"]), material, order=c.order)
    )
    mtask = MaterialTask.from_network(net, task, body)
    build_seconds = time.perf_counter() - t0
    rule = continuum_rule(scene, params["rule"])
    h = train(
        body,
        mtask,
        rule,
        scene.learning.steps,
        progress=False,
        callback=_steps_callback(ctx),
    )
    field = h.final[0].eigenstrain
    mask = rule.learning_mask(body, mtask)
    from ..learning.coupling import body_source_share, coupling_verdict, outcome

    share = body_source_share(body, h.final[0], mtask)
    ratio = float(h.error_initial[0, -1] / h.error_initial[0, 0])
    return ContinuumRun(
        **_training(h),
        field=field,
        coarse=coarse_average(field, body, lattice_body),
        area=body.area,
        frozen=~mask,
        points=body.body.mesh.p.T,
        triangles=body.body.mesh.t.T,
        source_share=share,
        coupling=coupling_verdict(share),
        outcome=outcome(ratio, coupling_verdict(share)),
        refine=params["refine"],
        order=c.order,
        n_dofs=body.n_dofs,
        n_elements=body.n_elements,
        build_seconds=build_seconds,
        rule=rule.settings(),
        task=params["task"],
        source_strain=mtask.source_strain.tolist(),
        target_strain=mtask.target_strain.tolist(),
    )


def relaxation_unit(scene: Scene, params: dict, ctx: UnitContext) -> LearnedRelaxationResult:
    """Target strains after the sources switch on: trained network and trained continuum."""
    from ..continuum.learnable import learnable_body
    from ..continuum.learned_relaxation import source_step, time_to_settle
    from ..continuum.material_task import MaterialTask
    from ..continuum.materials import lattice_area_per_node, lattice_lame, node_drag_to_continuum
    from ..continuum.mesh import network_mesh
    from ..continuum.viscoelastic import Damping
    from ..network.dynamics import simulate
    from ..network.equilibrium import relax
    from ..network.strain_clamp import ROD_FACTOR, rod_strain_error, simulate_strain_clamped

    rule = params["rule"]
    net, task = _lattice_and_task(scene, "stern")
    L0 = net.rest_length
    change = from_stored(ctx.unit(f"continuum_learning/network/{rule}"), NetworkRun).rest_change
    trained = net.with_rest_length(L0 * (1.0 + np.asarray(change)))
    off = {int(s): float(L0[s]) for s in task.sources}
    on = {int(s): float(L0[s] * (1 + S)) for s, S in zip(task.sources, task.source_strain)}
    x_off = relax(trained, pinned=task.pinned, clamped=off, tol=1e-12).positions
    x_on = relax(trained, pinned=task.pinned, clamped=on, tol=1e-12).positions
    i, j = trained.springs[task.targets].T

    def run(strain_clamp: bool):
        t0 = time.perf_counter()
        kw = dict(dt=params["dt"], t_end=params["t_end"], pinned=task.pinned, x0=x_off)
        if strain_clamp:
            traj = simulate_strain_clamped(trained, clamped=on, damping=1.0, inertia=False, **kw)
        else:
            traj = simulate(trained, clamped=on, damping=1.0, inertia=False, **kw)
        pos = traj.positions
        strain = np.linalg.norm(pos[:, j] - pos[:, i], axis=2) / L0[task.targets] - 1.0
        return traj, strain, time.perf_counter() - t0

    traj, net_strain, net_seconds = run(True)
    rod_error = max(
        float(np.max(np.abs(rod_strain_error(trained, on, p)))) for p in traj.positions[1:]
    )
    nodes, nodes_strain, nodes_seconds = run(False)
    net_final = trained.lengths(x_on, task.targets) / L0[task.targets] - 1.0

    field = from_stored(ctx.unit(f"continuum_learning/refine0/{rule}"), ContinuumRun).field
    c = scene.continuum
    body = learnable_body(
        network_mesh(net), lattice_lame(float(np.mean(net.stiffness))), order=c.order
    ).with_eigenstrain(field)
    mtask = MaterialTask.from_network(net, task, body)
    _, eta = node_drag_to_continuum(1.0, area_per_node=lattice_area_per_node(1.0))
    step = source_step(
        body, mtask, damping=Damping(drag=eta), dt=params["dt"], t_end=params["t_end"]
    )
    return LearnedRelaxationResult(
        times=step.times,
        continuum_strain=step.target_strain,
        continuum_final=step.final,
        network_times=traj.times,
        network_strain=net_strain,
        network_final=net_final,
        network_nodes_times=nodes.times,
        network_nodes_strain=nodes_strain,
        rule=rule,
        continuum_settle=time_to_settle(step.times, step.target_strain, step.target_strain[-1]),
        network_settle=time_to_settle(traj.times, net_strain, net_strain[-1]),
        continuum_gap=float(np.max(np.abs(step.target_strain[-1] - step.final))),
        network_gap=float(np.max(np.abs(net_strain[-1] - net_final))),
        network_nodes_settle=time_to_settle(nodes.times, nodes_strain, nodes_strain[-1]),
        network_nodes_gap=float(np.max(np.abs(nodes_strain[-1] - net_final))),
        network_nodes_seconds=nodes_seconds,
        rod_factor=ROD_FACTOR,
        rod_strain_error=rod_error,
        continuum_seconds=step.seconds,
        network_seconds=net_seconds,
        dt=params["dt"],
        t_end=params["t_end"],
    )
