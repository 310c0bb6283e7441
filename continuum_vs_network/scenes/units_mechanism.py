"""Units of a ``continuum_mechanism`` scene: a material that learns a mechanism.

The body, the allosteric 1 -> 1 task and the force inverter are those of
:mod:`continuum_vs_network.continuum.mechanism` (``[mechanism]`` sets them); the modulus
field learns through the density filter of :mod:`continuum_vs_network.continuum.filtered`
(radius ``filter_radius``), starting uniform (``s = 1``), within the stiffness range.

* ``continuum_mechanism/learn/refine<r>/<rule>/<rate>``: the rule object (``gcl``:
  ``CoupledLearning(dof="modulus")``, ``exact``: ``ExactGradient(dof="modulus")``) at the rate
  (``adaptive``: the package's Adam rate, step ``adaptive_step``; ``scaled``: the raw rate
  fixed at the first step, ``scaled_step``) for ``steps`` steps on the mesh ``h / 2^r``.
  Arrays: ``error`` (steps + 1,) C/C0, ``seconds`` and ``solves`` (cumulative), ``field``
  (n_elements,) the learned modulus, ``coarse`` the same averaged onto the ``r = 0`` mesh,
  ``points``, ``triangles``, ``area``, ``frozen``. Meta: final C/C0, first step at
  C/C0 <= 1e-3, the response ratio ``S_T / S_S`` reached, the rest example's error, the
  source share and its verdict.
* ``continuum_mechanism/dof/refine<r>/<dof>`` (``r <= dof_refine``, ``dof`` in ``dofs``):
  GCL (raw rate ``dof_alpha``: the rule objects refuse a scale-free rate for a continuum's
  eigenstrain) of the filtered eigenstrain, or of both fields
  (:class:`~continuum_vs_network.continuum.filtered_fields.FilteredFields`, eigenstrain in
  units of :func:`eigenstrain_unit`), on the task and its rest example;
  ``eigenstrain_norest``: the eigenstrain on the task alone (the check that the rest
  example is what makes the task non-trivial). Coupling: the source share of the trained
  body's free states with the sources on and off. Arrays ``error``, ``seconds``,
  ``solves``, ``modulus``, ``dilation``; meta as the learning units'.
* ``continuum_mechanism/optimum/refine<r>``: the exact optimum (:func:`~continuum_vs_network.
  learning.field_optimum.field_optimum`) of the same medium and task.
* ``continuum_mechanism/dof_optimum/refine<r>/<dof>`` (``r <= min(dof_refine,
  dof_optimum_refine)``, ``dof`` in ``dofs``): the exact optimum of the eigenstrain field or
  of both on the dof units' medium (the same filter and :func:`eigenstrain_unit`) and
  objective (the task and its rest example, summed): L-BFGS-B on the adjoint gradient, log
  modulus within the stiffness range, eigenstrain unbounded. ``feasible``: its C/C0 <=
  ``MET_AT`` (the level the dof findings ask for); an infeasible dof's GCL verdict is
  ``"infeasible (optimum C/C0 = x)"``. Arrays ``error``, ``seconds``; meta C/C0,
  evaluations, solves (one free state per example per evaluation), seconds.
* ``continuum_mechanism/simp``: SIMP (penalty 3, density filter of the same radius, MMA when
  nlopt is installed, else OC) on the same task and the ``r = 0`` mesh, its modulus
  ``e_min + x^3 (e_max - e_min)`` spanning the learning's stiffness range (``1e-2 .. 1e2``);
  ``continuum_mechanism/simp_solid``: the textbook's SIMP, whose solid is the body's own
  material (``1e-4 .. 1``)
  (:func:`~continuum_vs_network.continuum.topology.simp_allosteric`).
* ``continuum_mechanism/lattice/refine<r>``: the network beside it: a triangular lattice
  covering the same rectangle at lattice constant ``h / 2^r`` (about the mesh's vertex
  count), source and target the springs nearest the material springs' centres, the same
  strains, with its rest example (:func:`~continuum_vs_network.learning.anchored`), learning
  its stiffnesses by ``CoupledLearning(dof="stiffness")`` at the adaptive rate (step
  ``adaptive_step``) for ``steps`` steps: the scaled rate's fixed gain, set at the first
  step, overshoots on a network once single springs soften (C/C0 oscillating between 1e-8
  and 0.9 at step 0.5 on the h lattice). Arrays ``error``, ``seconds``, ``solves``,
  ``positions``, ``springs``, ``k``; meta as the learning units'.
* ``continuum_mechanism/inverter``: SIMP on Sigmund's force inverter
  (:func:`~continuum_vs_network.continuum.topology.simp_inverter`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .results.mechanism import (
    DofOptimumResult,
    DofResult,
    InverterResult,
    LatticeResult,
    LearnResult,
    OptimumResult,
    SimpResult,
)
from .schema import Scene
from .units import Unit, UnitContext

__all__ = ["LEVEL", "plan_mechanism"]

#: C/C0 level of "learned" (the allostery scene's, Rocks et al.)
LEVEL = 1e-3


def _spec(scene: Scene):
    m = scene.mechanism
    assert m is not None
    return m


def build(scene: Scene, refine: int):
    """The learnable body, task and filtered medium of the mesh ``h / 2^refine``."""
    from ..continuum.filtered import filtered_modulus
    from ..continuum.learnable import learnable_body
    from ..continuum.materials import Material
    from ..continuum.mechanism import allosteric_task, mechanism_mesh

    m = _spec(scene)
    material = Material.from_young(1.0, 0.3, plane="stress")
    body = learnable_body(mechanism_mesh(m.width, m.height, m.h, refine=refine), material)
    task = allosteric_task(
        body, source=m.source, target=m.target, gap=m.gap, radius=m.end_radius,
        source_strain=m.source_strain, ratio=m.ratio,
    )  # fmt: skip
    return body, task, filtered_modulus(body, m.filter_radius, task=task)


def eigenstrain_unit(scene: Scene) -> float:
    """The eigenstrain design's strain unit: ``[mechanism] eigenstrain_unit`` when > 0, else
    balanced: on the coarsest mesh, with the task and its rest example, the first step of
    GCL on both fields moves the eigenstrain design ``e`` by the same norm as the modulus
    design ``rho`` (``|d rho| = |d e|``; at unit 1 the signal on ``e`` is
    ``|g_e| / |g_rho|`` times the modulus', and at unit ``u`` it is ``u`` times that).
    One raw rate then moves both designs by comparable fractions."""
    from ..continuum.filtered_fields import MaterialExamples, filtered_fields
    from ..continuum.mechanism import rest_example
    from ..learning.rules import CoupledLearning

    m = _spec(scene)
    if m.eigenstrain_unit > 0:
        return float(m.eigenstrain_unit)
    _, task, filtered = build(scene, 0)
    examples = MaterialExamples((task, rest_example(task)))
    raw = CoupledLearning(1.0, dof="both").update(filtered_fields(filtered, 1.0), examples).raw
    g_rho, g_e = np.linalg.norm(raw[:, 0]), np.linalg.norm(raw[:, 1:])
    if not (g_rho > 0 and g_e > 0):
        raise RuntimeError("the task gives no learning signal on the modulus or eigenstrain")
    return float(g_rho / g_e)


def plan_mechanism(scene: Scene) -> list[Unit]:
    m = _spec(scene)
    depends = {k: getattr(m, k) for k in m.__dataclass_fields__}
    units = [Unit("continuum_mechanism/inverter", inverter_unit, {}, depends)]
    units.append(Unit("continuum_mechanism/simp", simp_unit, {"solid": False}, depends))
    units.append(Unit("continuum_mechanism/simp_solid", simp_unit, {"solid": True}, depends))
    for r in range(m.refine + 1):
        if r <= m.optimum_refine:
            units.append(
                Unit(f"continuum_mechanism/optimum/refine{r}", optimum_unit, {"refine": r}, depends)
            )
        units.append(
            Unit(f"continuum_mechanism/lattice/refine{r}", lattice_unit, {"refine": r}, depends,
                 weight=m.steps)
        )  # fmt: skip
        if r <= min(m.dof_refine, m.dof_optimum_refine):
            for dof in m.dofs:
                units.append(
                    Unit(f"continuum_mechanism/dof_optimum/refine{r}/{dof}", dof_optimum_unit,
                         {"refine": r, "dof": dof}, depends)
                )  # fmt: skip
        if r <= m.dof_refine:
            for dof, rest in [(d, True) for d in m.dofs] + [("eigenstrain", False)]:
                name = dof + ("" if rest else "_norest")
                units.append(
                    Unit(f"continuum_mechanism/dof/refine{r}/{name}", dof_unit,
                         {"refine": r, "dof": dof, "rest": rest}, depends, weight=m.steps)
                )  # fmt: skip
        for rule in m.rules:
            for rate in m.rates:
                p = {"refine": r, "rule": rule, "rate": rate}
                units.append(
                    Unit(
                        f"continuum_mechanism/learn/refine{r}/{rule}/{rate}",
                        learn_unit,
                        p,
                        depends,
                        weight=m.steps,
                    )
                )
    return units


def _rule(scene: Scene, rule: str, rate: str):
    from ..learning.rates import Adaptive, Scaled
    from ..learning.rules import CoupledLearning, ExactGradient

    m = _spec(scene)
    r = Adaptive(step=m.adaptive_step) if rate == "adaptive" else Scaled(step=m.scaled_step)
    cls = CoupledLearning if rule == "gcl" else ExactGradient
    return cls(dof="modulus", rate=r)


def _mesh_arrays(body, field, coarse_body) -> dict[str, Any]:
    """``field``, ``coarse``, ``points``, ``triangles``, ``area`` of a result class."""
    from ..continuum.learned_fields import coarse_average

    return {
        "field": np.asarray(field),
        "coarse": coarse_average(field, body, coarse_body)
        if coarse_body is not body
        else np.asarray(field),
        "points": body.body.mesh.p.T,
        "triangles": body.body.mesh.t.T,
        "area": body.area,
    }


def _response(medium, task) -> float:
    return float(medium.free_state(task).target_strain[0] / task.source_strain[0])


def learn_unit(scene: Scene, params: dict, ctx: UnitContext) -> LearnResult:
    """Train the filtered modulus field with one rule and rate (see the module)."""
    from ..continuum.mechanism import rest_example
    from ..learning.coupling import body_source_share, coupling_verdict, outcome
    from ..learning.metrics import first_below
    from ..learning.train import train

    m = _spec(scene)
    body, task, medium = build(scene, params["refine"])
    coarse_body = body if params["refine"] == 0 else build(scene, 0)[0]
    rule = _rule(scene, params["rule"], params["rate"])
    h = train(medium, task, rule, m.steps, progress=False)
    err = h.error_initial[0] / h.error_initial[0, 0]
    trained = h.final[0]
    share = body_source_share(medium, trained, task)
    verdict = coupling_verdict(share)
    rest = rest_example(task)
    seconds = np.asarray(h.seconds[0], dtype=float)
    solves = np.asarray(h.solves[0], dtype=float)
    return LearnResult(
        refine=params["refine"],
        rule=params["rule"],
        rate=params["rate"],
        ratio=float(err[-1]),
        first_below=first_below(err, LEVEL),
        response=_response(trained, task),
        response_initial=_response(medium, task),
        asked=float(m.ratio),
        rest_error=float(rest.error(trained.free_state(rest).target_strain)),
        source_share=float(share),
        coupling=verdict,
        outcome=outcome(float(err[-1]), verdict),
        n_elements=int(body.n_elements),
        seconds=float(seconds[-1]),
        solves=float(solves[-1]),
        contrast=float(trained.modulus.max() / trained.modulus.min()),
        error=err,
        seconds_trace=seconds,
        solves_trace=solves,
        frozen=~trained.learning_mask(task, learn_sources=False, learn_targets=False),
        **_mesh_arrays(body, trained.modulus, coarse_body),
    )


def dof_unit(scene: Scene, params: dict, ctx: UnitContext) -> DofResult:
    """GCL of the filtered eigenstrain field, or of both fields, at the raw rate
    ``dof_alpha`` (the rule objects refuse a scale-free rate for a continuum's
    eigenstrain), on the task with its rest example (``rest``) or on the task alone."""
    from ..continuum.filtered_fields import MaterialExamples, filtered_fields
    from ..continuum.mechanism import rest_example
    from ..learning.coupling import coupling_verdict, outcome, source_share
    from ..learning.metrics import first_below
    from ..learning.rules import CoupledLearning
    from ..learning.train import train

    m = _spec(scene)
    body, task, filtered = build(scene, params["refine"])
    unit = eigenstrain_unit(scene)
    medium = filtered_fields(filtered, unit)
    rest = rest_example(task)
    examples = MaterialExamples((task, rest) if params["rest"] else (task,))
    rule = CoupledLearning(m.dof_alpha, dof=params["dof"], min_stiffness=0.01)
    h = train(medium, examples, rule, m.steps, progress=False)
    err = h.error_initial[0] / h.error_initial[0, 0]
    trained = h.final[0].body
    share = source_share(
        trained.free_state(task).target_strain, trained.free_state(rest).target_strain,
        body.free_state(rest).target_strain, body.free_state(task).target_strain,
    )  # fmt: skip
    verdict = coupling_verdict(share)
    e = trained.eigenstrain
    seconds = np.asarray(h.seconds[0], dtype=float)
    solves = np.asarray(h.solves[0], dtype=float)
    return DofResult(
        refine=params["refine"], dof=params["dof"], rest=params["rest"],
        ratio=float(err[-1]), first_below=first_below(err, LEVEL),
        response=_response(trained, task), asked=float(m.ratio),
        rest_error=float(rest.error(trained.free_state(rest).target_strain)),
        source_share=float(share), coupling=verdict,
        outcome=outcome(float(err[-1]), verdict), n_elements=int(body.n_elements),
        seconds=float(seconds[-1]), solves=float(solves[-1]),
        completed=int(h.completed[0]), eigenstrain_unit=unit,
        error=err, seconds_trace=seconds, solves_trace=solves,
        modulus=trained.modulus, dilation=0.5 * (e[:, 0] + e[:, 1]),
    )  # fmt: skip


def optimum_unit(scene: Scene, params: dict, ctx: UnitContext) -> OptimumResult:
    """The exact optimum of the filtered modulus field (L-BFGS-B, adjoint gradient)."""
    from ..learning.field_optimum import field_optimum

    body, task, medium = build(scene, params["refine"])
    coarse_body = body if params["refine"] == 0 else build(scene, 0)[0]
    o = field_optimum(medium, task)
    return OptimumResult(
        refine=params["refine"], ratio=o.ratio, evaluations=o.evaluations,
        solves=o.evaluations, seconds=o.seconds, converged=o.converged, message=o.message,
        contrast=o.contrast, response=_response(o.medium, task),
        n_elements=int(body.n_elements), error=o.errors, seconds_trace=o.times,
        **_mesh_arrays(body, o.medium.modulus, coarse_body),
    )  # fmt: skip


def dof_optimum_unit(scene: Scene, params: dict, ctx: UnitContext) -> DofOptimumResult:
    """The exact optimum of the filtered eigenstrain field, or of both fields, on the task and
    its rest example (L-BFGS-B, adjoint gradient; see the module)."""
    from ..continuum.filtered_fields import MaterialExamples, filtered_fields
    from ..continuum.mechanism import rest_example
    from ..learning.coupling import MET_AT
    from ..learning.field_optimum import field_optimum

    body, task, filtered = build(scene, params["refine"])
    unit = eigenstrain_unit(scene)
    medium = filtered_fields(filtered, unit)
    rest = rest_example(task)
    examples = MaterialExamples((task, rest))
    o = field_optimum(medium, examples, dof=params["dof"])
    trained = o.medium.body
    e = trained.eigenstrain
    return DofOptimumResult(
        refine=params["refine"], dof=params["dof"], ratio=o.ratio,
        feasible=bool(o.ratio <= MET_AT), evaluations=o.evaluations,
        solves=o.evaluations * len(examples.tasks), seconds=o.seconds,
        converged=o.converged, message=o.message, contrast=o.contrast,
        response=_response(trained, task),
        rest_error=float(rest.error(trained.free_state(rest).target_strain)),
        n_elements=int(body.n_elements), eigenstrain_unit=unit, error=o.errors,
        seconds_trace=o.times, modulus=trained.modulus, dilation=0.5 * (e[:, 0] + e[:, 1]),
    )  # fmt: skip


def simp_unit(scene: Scene, params: dict, ctx: UnitContext) -> SimpResult:
    """SIMP on the allosteric task, on the coarsest mesh: over the learning's stiffness
    range, or (``solid``) the textbook's ``1e-4 .. 1``."""
    from ..continuum.topology import simp_allosteric
    from ..learning.ranges import STIFFNESS_RANGE

    m = _spec(scene)
    body, task, _ = build(scene, 0)
    e_min, e_max = (1e-4, 1.0) if params["solid"] else STIFFNESS_RANGE
    r = simp_allosteric(
        body,
        task,
        volfrac=m.volfrac,
        radius=m.filter_radius,
        iterations=m.simp_iterations,
        e_min=e_min,
        e_max=e_max,
    )
    return SimpResult(
        ratio=r.final, solves=r.solves, seconds=r.seconds, iterations=r.iterations,
        volume=r.volume, method=r.method, e_min=e_min, e_max=e_max,
        response=_response(body.with_modulus(r.modulus), task),
        n_elements=int(body.n_elements), error=r.objective, seconds_trace=r.times,
        density=r.density, **_mesh_arrays(body, r.modulus, body),
    )  # fmt: skip


def inverter_unit(scene: Scene, params: dict, ctx: UnitContext) -> InverterResult:
    """SIMP + OC on Sigmund's force inverter (half model 2 x 1, symmetry at the top)."""
    from ..continuum.learnable import learnable_body
    from ..continuum.materials import Material
    from ..continuum.mechanism import inverter_layout, mechanism_mesh
    from ..continuum.topology import simp_inverter

    m = _spec(scene)
    t0 = time.perf_counter()
    body = learnable_body(
        mechanism_mesh(2.0, 1.0, m.inverter_h), Material.from_young(1.0, 0.3, plane="stress")
    )
    layout = inverter_layout(body)
    r, u_in = simp_inverter(
        body, layout, radius=m.inverter_radius, iterations=m.inverter_iterations
    )
    mesh = _mesh_arrays(body, r.density, body)
    return InverterResult(
        u_out=float(r.objective[-1]), u_out_initial=float(r.objective[0]), u_in=u_in,
        advantage=float(-r.objective[-1] / u_in), volume=r.volume, solves=r.solves,
        seconds=time.perf_counter() - t0, n_elements=int(body.n_elements),
        k_in=layout.k_in, k_out=layout.k_out, force=layout.force, output=r.objective,
        seconds_trace=r.times, density=r.density, **mesh,
    )  # fmt: skip


def lattice(scene: Scene, refine: int):
    """The triangular lattice of the module at ``h / 2^refine``, its task and task set."""
    from ..learning import anchored
    from ..learning.tasks import AllosteryTask
    from ..network.builders import triangular_lattice

    m = _spec(scene)
    a = m.h / 2**refine
    nx = round(m.width / a) + 1
    ny = round(m.height / (a * np.sqrt(3) / 2)) + 1
    net = triangular_lattice(nx, ny, spacing=a)
    mid = net.positions[net.springs].mean(axis=1)

    def nearest(c) -> int:
        return int(np.argmin(np.hypot(*(mid - np.asarray(c, float)).T)))

    task = AllosteryTask.create(
        net, [nearest(m.source)], [m.source_strain], [nearest(m.target)],
        [m.ratio * m.source_strain],
    )  # fmt: skip
    return net, task, anchored(task, net)


def lattice_unit(scene: Scene, params: dict, ctx: UnitContext) -> LatticeResult:
    """GCL of the lattice's stiffnesses on the same 1 -> 1 task (see the module)."""
    from ..learning import measure_coupling, train
    from ..learning.coupling import outcome
    from ..learning.metrics import first_below
    from ..learning.rates import Adaptive
    from ..learning.rules import CoupledLearning

    m = _spec(scene)
    net, task, tasks = lattice(scene, params["refine"])
    rule = CoupledLearning(dof="stiffness", rate=Adaptive(step=m.adaptive_step))
    h = train(net, tasks, rule, m.steps, progress=False)
    e = np.asarray(h.error_initial[0], dtype=float)
    err = e / e[0]
    final = h.final[0]
    c = measure_coupling(net, final, task)
    seconds = np.asarray(h.seconds[0], dtype=float)
    solves = np.asarray(h.solves[0], dtype=float)
    return LatticeResult(
        refine=params["refine"], ratio=float(err[-1]), first_below=first_below(err, LEVEL),
        source_share=float(c.share), coupling=c.verdict,
        outcome=outcome(float(err[-1]), c.verdict), n_nodes=int(net.n_nodes),
        n_springs=len(net.springs), spacing=float(m.h / 2 ** params["refine"]),
        completed=int(h.completed[0]), seconds=float(seconds[-1]), solves=float(solves[-1]),
        error=err, seconds_trace=seconds, solves_trace=solves, positions=net.positions,
        springs=net.springs, k=final.stiffness,
    )  # fmt: skip
