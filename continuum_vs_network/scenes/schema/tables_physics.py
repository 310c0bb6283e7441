"""Scene tables ``[continuum]``, ``[dynamics]``, ``[stability]``, ``[accuracy]``, ``[export]``,
``[physical_time]`` and ``[report]``: one frozen dataclass each.
"""

from typing import Annotated, Literal

from .keys import (
    NOT_BOOL,
    Bool,
    Float,
    Int,
    _at_least,
    _between,
    _each,
    _increasing,
    _kinds,
    _non_negative,
    _nonempty,
    _open_unit,
    _positive,
    _unique_nonempty,
    _when,
    key,
    table,
)


@table
class ContinuumSpec:
    """``[continuum]``: the finite-element continuum compared with the network."""

    refine: Annotated[Int, _between(0, 4)] = key(1, "uniform refinements of the network's faces")
    order: Annotated[Literal[1, 2], NOT_BOOL] = key(2, "polynomial order of the displacement")
    patch_radius: Annotated[Float, _open_unit] = key(
        0.3, "source patch radius / source spring length", used=_kinds("transmission")
    )
    material: Literal["homogenised", "lattice"] = key(
        "homogenised",
        "'homogenised' (relaxed moduli of the network) or 'lattice' (lam = mu = sqrt(3) k / 4)",
        used=_kinds("transmission", "relaxation"),
    )


@table
class DynamicsSpec:
    """``[dynamics]``: damped relaxation after a step displacement of one side."""

    damping: Annotated[Float, _positive] = key(1.0, "node drag c (force per velocity)")
    inertia: Bool = key(False, "unit node masses (True) or overdamped (False)")
    scheme: Literal["implicit", "newmark", "explicit"] = key("implicit", "time stepping")
    step: Annotated[Float, _between(1e-6, 0.2)] = key(
        0.01, "step displacement of the right side / width"
    )
    fraction: Annotated[Float, _open_unit] = key(
        0.01,
        "relaxed when the displacement to the final state stays below this fraction of its start",
    )
    steps_per_tau: Annotated[Int, _at_least(2)] = key(20, "time steps per slowest-mode time")
    duration: Annotated[Float, _positive] = key(12.0, "run length in slowest-mode times")
    frames: Annotated[Int, _at_least(2)] = key(
        25,
        "frames of the exported series",
        used=_when(
            lambda s: s.export is not None or s.report.images,
            "when the scene exports meshes or draws images",
        ),
    )


@table
class StabilitySpec:
    """``[stability]``: degenerate, dynamic, continuum and learning cases of a stability scene.

    See :mod:`~continuum_vs_network.scenes.units_stability` for what each case runs.
    """

    collinear_heights: Annotated[tuple[Float, ...], _each(_positive)] = key(
        (), "apex heights of a nearly collinear triangle (base 2, sides 1.2)"
    )
    float32: Bool = key(False, "the lattice given as float32 arrays")
    floppy: Bool = key(False, "the lattice with 12 springs removed (must raise)")
    explicit_dt: Annotated[tuple[Float, ...], _each(_positive)] = key(
        (), "explicit dynamics steps, in units of the stability limit"
    )
    implicit_dt: Annotated[tuple[Float, ...], _each(_positive)] = key(
        (), "backward Euler and Newmark steps, in units of the explicit limit (stiff lattice)"
    )
    implicit_stiffness: Annotated[Float, _at_least(1.0)] = key(
        1e6,
        "stiffness ratio of the implicit-dynamics lattice",
        used=_when(lambda s: bool(s.stability.implicit_dt), "with implicit_dt"),
    )
    poisson: Annotated[tuple[Float, ...], _each(_between(0.0, 0.4999))] = key(
        (), "Poisson's ratios of the locking study (Lamé's cylinder, P1 and curved P2)"
    )
    locking_h: Annotated[Float, _between(0.01, 0.5)] = key(
        0.1,
        "mesh size of the locking study",
        used=_when(lambda s: bool(s.stability.poisson), "with poisson"),
    )
    learning_stiffness_ratios: Annotated[tuple[Float, ...], _each(_at_least(1.0))] = key(
        (), "stiffness ratios of coupled learning on a stiff lattice"
    )
    learning_steps: Annotated[Int, _at_least(1)] = key(
        5,
        "learning steps of those runs",
        used=_when(
            lambda s: bool(s.stability.learning_stiffness_ratios), "with learning_stiffness_ratios"
        ),
    )


@table
class AccuracySpec:
    """``[accuracy]``: error against run time of the continuum and the time integrators.

    Finite elements on Lamé's thick cylinder (closed form), network time integrators
    against an independent DOP853 reference, continuum time integrators against the closed
    form of a lowest-mode decay (see :mod:`~continuum_vs_network.scenes.units_accuracy`).
    """

    elements: Annotated[tuple[Literal["P1", "P2", "P2_curved"], ...], _unique_nonempty] = key(
        ("P1", "P2", "P2_curved"), "finite elements (P2: straight-sided, P2_curved: isoparametric)"
    )
    mesh_sizes: Annotated[tuple[Float, ...], _unique_nonempty, _each(_between(0.01, 0.5))] = key(
        (0.4, 0.2, 0.1, 0.05), "mesh sizes h of the cylinder (radii 1 and 2)"
    )
    poisson: Annotated[Float, _between(0.0, 0.499)] = key(
        0.3, "Poisson's ratio of the cylinder (plane strain)"
    )
    schemes: Annotated[
        tuple[Literal["backward_euler", "newmark", "explicit"], ...], _unique_nonempty
    ] = key(
        ("backward_euler", "newmark", "explicit"),
        "time integrators (the continuum has no explicit scheme)",
    )
    problems: Annotated[tuple[Literal["overdamped", "inertial"], ...], _unique_nonempty] = key(
        ("overdamped", "inertial"), "dynamics: overdamped (first order) or inertial (unit masses)"
    )
    steps: Annotated[tuple[Int, ...], _unique_nonempty, _each(_at_least(2)), _increasing] = key(
        (8, 16, 32, 64, 128, 256, 512, 1024), "time steps over the run (one per entry)"
    )
    size: Annotated[Int, _between(3, 30)] = key(6, "n x n lattice of the network integrators")


@table
class ExportSpec:
    """``[export]``: meshes written to ``meshes/<scene>/`` (VTU, PVD series)."""

    networks: Bool = key(True, "networks (initial and final free states)")
    continuum: Bool = key(
        True,
        "continuum fields",
        used=_when(lambda s: s.continuum is not None, "with a [continuum] table"),
    )
    series: Bool = key(
        False,
        "time series (learning trajectory, relaxation)",
        used=_kinds("learning", "relaxation", "physical_time"),
    )
    every: Annotated[Int, _at_least(1)] = key(
        10,
        "learning steps between series frames",
        used=_when(
            lambda s: s.kind == "learning" and s.export.series,
            "by learning scenes with series = true",
        ),
    )
    trials: Annotated[tuple[Int, ...], _unique_nonempty, _each(_non_negative)] = key(
        (0,), "learning trials to export", used=_kinds("learning")
    )


#: Learning runs of a physical_time scene: GCL as twin networks, GCL with phases, GPC.
TIME_RULES = ("gcl", "gcl_phases", "gpc")


@table
class PhysicalTimeSpec:
    """``[physical_time]``: learning concurrent with the dynamics against the ratio of
    learning rate to relaxation rate (:mod:`continuum_vs_network.learning.physical_time`)."""

    rules: Annotated[tuple[Literal[TIME_RULES], ...], _unique_nonempty] = key(
        ("gcl", "gpc"), "rules: gcl (twin networks), gcl_phases, gpc (continuous)"
    )
    ratios: Annotated[tuple[Float, ...], _unique_nonempty, _each(_positive), _increasing] = key(
        (1.0, 10.0, 100.0, 1000.0, 10000.0),
        "ratios alpha k tau of learning rate to relaxation rate (tau: the target strains' "
        "1 % settling time)",
    )
    media: Annotated[tuple[Literal["network", "continuum"], ...], _unique_nonempty] = key(
        ("network",),
        "media: network (the lattice) and/or continuum (its elastic continuum on the "
        "lattice's triangles, P1, learning its eigenstrain against the mapped drag)",
    )
    bisections: Annotated[Int, _at_least(0)] = key(
        0,
        "bisections of the critical ratio between the largest ratio not past and the next "
        "ratio (log scale)",
    )
    draws: Annotated[tuple[Int, ...], _nonempty, _each(_at_least(1))] = key(
        (1,),
        "task draws (random sources and targets) per size: one number for every size, or "
        "one per size",
    )
    dof: Literal["rest_length", "stiffness"] = key(
        "rest_length",
        "what learns: rest_length (Stern task, raw rate alpha, rho = alpha k tau) or "
        "stiffness (Rocks' response task from [physical_time] response_ratio, source_strain "
        "and distance; GCL's adaptive rate; rho = tau / T_qs)",
    )
    response_ratio: Annotated[Float, _positive] = key(
        0.3,
        "dof = stiffness: target strain / source strain asked for (sign alternating with the draw)",
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    source_strain: Annotated[Float, _positive] = key(
        0.05,
        "dof = stiffness: source strain",
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    distance: Annotated[Float, _open_unit] = key(
        0.25,
        "dof = stiffness: source-target distance in box sizes",
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    eta: Annotated[Float, _positive] = key(
        0.1,
        "GCL nudge amplitude",
        used=_when(
            lambda s: any(r.startswith("gcl") for r in s.physical_time.rules), "by GCL rules"
        ),
    )
    drag: Annotated[Float, _positive] = key(1.0, "node drag c")
    dashpot: Annotated[Float, _non_negative] = key(0.0, "spring dashpot gamma (Kelvin-Voigt)")
    arm_stiffness: Annotated[Float, _non_negative] = key(
        0.0, "Maxwell-arm stiffness k2 (0: no arm)"
    )
    arm_dashpot: Annotated[Float, _non_negative] = key(0.0, "Maxwell-arm dashpot gamma2")
    learning_times: Annotated[Float, _positive] = key(
        5.0, "run length in learning times 1 / (alpha k)"
    )
    relaxation_times: Annotated[Float, _positive] = key(0.05, "shortest run, in relaxation times")
    steps_per_tau: Annotated[Int, _at_least(2)] = key(20, "physical steps per relaxation time")
    steps_per_rate: Annotated[Int, _at_least(1)] = key(
        10, "physical steps per learning time 1 / (alpha k)"
    )
    fraction: Annotated[Float, _open_unit] = key(
        0.1, "learned when the error has made all but this fraction of its quasi-static drop"
    )
    phase: Annotated[Float, _positive] = key(1.0, "gcl_phases: phase length in relaxation times")
    frames: Annotated[Int, _at_least(2)] = key(
        25,
        "frames of the exported series",
        used=_when(
            lambda s: s.export is not None and s.export.series, "with [export] series = true"
        ),
    )


@table
class ReportSpec:
    """``[report]``: how the report is drawn."""

    default: Bool = key(False, "part of the default set of ``cvn report``")
    images: Bool = key(
        False,
        "pyvista off-screen renders",
        used=_kinds(
            "learning", "transmission", "relaxation", "continuum_learning", "continuum_mechanism"
        ),
    )
    dpi: Annotated[Int, _between(40, 300)] = key(90, "resolution of the figures")
