"""Scene tables ``[continuum]``, ``[dynamics]``, ``[stability]``, ``[accuracy]``, ``[export]``,
``[physical_time]`` and ``[report]``: one frozen dataclass each.
"""

from __future__ import annotations

from dataclasses import dataclass

from .keys import (
    _all,
    _at_least,
    _between,
    _each,
    _increasing,
    _key,
    _kinds,
    _non_negative,
    _open_unit,
    _positive,
    _unique_nonempty,
    _when,
)


@dataclass(frozen=True)
class ContinuumSpec:
    """``[continuum]``: the finite-element continuum compared with the network."""

    refine: int = _key("int", 1, "uniform refinements of the network's faces", check=_between(0, 4))
    order: int = _key("int", 2, "polynomial order of the displacement", choices=(1, 2))
    patch_radius: float = _key(
        "float",
        0.3,
        "source patch radius / source spring length",
        check=_open_unit,
        used=_kinds("transmission"),
    )
    material: str = _key(
        "str",
        "homogenised",
        "'homogenised' (relaxed moduli of the network) or 'lattice' (lam = mu = sqrt(3) k / 4)",
        choices=("homogenised", "lattice"),
        used=_kinds("transmission", "relaxation"),
    )


@dataclass(frozen=True)
class DynamicsSpec:
    """``[dynamics]``: damped relaxation after a step displacement of one side."""

    damping: float = _key("float", 1.0, "node drag c (force per velocity)", check=_positive)
    inertia: bool = _key("bool", False, "unit node masses (True) or overdamped (False)")
    scheme: str = _key(
        "str", "implicit", "time stepping", choices=("implicit", "newmark", "explicit")
    )
    step: float = _key(
        "float", 0.01, "step displacement of the right side / width", check=_between(1e-6, 0.2)
    )
    fraction: float = _key(
        "float",
        0.01,
        "relaxed when the displacement to the final state stays below this fraction of its start",
        check=_open_unit,
    )
    steps_per_tau: int = _key("int", 20, "time steps per slowest-mode time", check=_at_least(2))
    duration: float = _key("float", 12.0, "run length in slowest-mode times", check=_positive)
    frames: int = _key(
        "int",
        25,
        "frames of the exported series",
        check=_at_least(2),
        used=_when(
            lambda s: s.export is not None or s.report.images,
            "when the scene exports meshes or draws images",
        ),
    )


@dataclass(frozen=True)
class StabilitySpec:
    """``[stability]``: degenerate, dynamic, continuum and learning cases of a stability scene.

    See :mod:`~continuum_vs_network.scenes.units_stability` for what each case runs.
    """

    collinear_heights: tuple[float, ...] = _key(
        "list[float]",
        (),
        "apex heights of a nearly collinear triangle (base 2, sides 1.2)",
        check=_each(_positive),
    )
    float32: bool = _key("bool", False, "the lattice given as float32 arrays")
    floppy: bool = _key("bool", False, "the lattice with 12 springs removed (must raise)")
    explicit_dt: tuple[float, ...] = _key(
        "list[float]",
        (),
        "explicit dynamics steps, in units of the stability limit",
        check=_each(_positive),
    )
    implicit_dt: tuple[float, ...] = _key(
        "list[float]",
        (),
        "backward Euler and Newmark steps, in units of the explicit limit (stiff lattice)",
        check=_each(_positive),
    )
    implicit_stiffness: float = _key(
        "float",
        1e6,
        "stiffness ratio of the implicit-dynamics lattice",
        check=_at_least(1.0),
        used=_when(lambda s: bool(s.stability.implicit_dt), "with implicit_dt"),
    )
    poisson: tuple[float, ...] = _key(
        "list[float]",
        (),
        "Poisson's ratios of the locking study (Lamé's cylinder, P1 and curved P2)",
        check=_each(_between(0.0, 0.4999)),
    )
    locking_h: float = _key(
        "float",
        0.1,
        "mesh size of the locking study",
        check=_between(0.01, 0.5),
        used=_when(lambda s: bool(s.stability.poisson), "with poisson"),
    )
    learning_stiffness_ratios: tuple[float, ...] = _key(
        "list[float]",
        (),
        "stiffness ratios of coupled learning on a stiff lattice",
        check=_each(_at_least(1.0)),
    )
    learning_steps: int = _key(
        "int",
        5,
        "learning steps of those runs",
        check=_at_least(1),
        used=_when(
            lambda s: bool(s.stability.learning_stiffness_ratios), "with learning_stiffness_ratios"
        ),
    )


@dataclass(frozen=True)
class AccuracySpec:
    """``[accuracy]``: error against run time of the continuum and the time integrators.

    Finite elements on Lamé's thick cylinder (closed form), network time integrators
    against an independent DOP853 reference, continuum time integrators against the closed
    form of a lowest-mode decay (see :mod:`~continuum_vs_network.scenes.units_accuracy`).
    """

    elements: tuple[str, ...] = _key(
        "list[str]",
        ("P1", "P2", "P2_curved"),
        "finite elements (P2: straight-sided, P2_curved: isoparametric)",
        choices=("P1", "P2", "P2_curved"),
        check=_unique_nonempty,
    )
    mesh_sizes: tuple[float, ...] = _key(
        "list[float]",
        (0.4, 0.2, 0.1, 0.05),
        "mesh sizes h of the cylinder (radii 1 and 2)",
        check=_all(_unique_nonempty, _each(_between(0.01, 0.5))),
    )
    poisson: float = _key(
        "float", 0.3, "Poisson's ratio of the cylinder (plane strain)", check=_between(0.0, 0.499)
    )
    schemes: tuple[str, ...] = _key(
        "list[str]",
        ("backward_euler", "newmark", "explicit"),
        "time integrators (the continuum has no explicit scheme)",
        choices=("backward_euler", "newmark", "explicit"),
        check=_unique_nonempty,
    )
    problems: tuple[str, ...] = _key(
        "list[str]",
        ("overdamped", "inertial"),
        "dynamics: overdamped (first order) or inertial (unit masses)",
        choices=("overdamped", "inertial"),
        check=_unique_nonempty,
    )
    steps: tuple[int, ...] = _key(
        "list[int]",
        (8, 16, 32, 64, 128, 256, 512, 1024),
        "time steps over the run (one per entry)",
        check=_all(_unique_nonempty, _each(_at_least(2)), _increasing),
    )
    size: int = _key("int", 6, "n x n lattice of the network integrators", check=_between(3, 30))


@dataclass(frozen=True)
class ExportSpec:
    """``[export]``: meshes written to ``meshes/<scene>/`` (VTU, PVD series)."""

    networks: bool = _key("bool", True, "networks (initial and final free states)")
    continuum: bool = _key(
        "bool",
        True,
        "continuum fields",
        used=_when(lambda s: s.continuum is not None, "with a [continuum] table"),
    )
    series: bool = _key(
        "bool",
        False,
        "time series (learning trajectory, relaxation)",
        used=_kinds("learning", "relaxation", "physical_time"),
    )
    every: int = _key(
        "int",
        10,
        "learning steps between series frames",
        check=_at_least(1),
        used=_when(
            lambda s: s.kind == "learning" and s.export.series,
            "by learning scenes with series = true",
        ),
    )
    trials: tuple[int, ...] = _key(
        "list[int]",
        (0,),
        "learning trials to export",
        check=_all(_unique_nonempty, _each(_non_negative)),
        used=_kinds("learning"),
    )


#: Learning runs of a physical_time scene: GCL as twin networks, GCL with phases, GPC.
TIME_RULES = ("gcl", "gcl_phases", "gpc")


@dataclass(frozen=True)
class PhysicalTimeSpec:
    """``[physical_time]``: learning concurrent with the dynamics against the ratio of
    learning rate to relaxation rate (:mod:`continuum_vs_network.learning.physical_time`)."""

    rules: tuple[str, ...] = _key(
        "list[str]",
        ("gcl", "gpc"),
        "rules: gcl (twin networks), gcl_phases, gpc (continuous)",
        choices=TIME_RULES,
        check=_unique_nonempty,
    )
    ratios: tuple[float, ...] = _key(
        "list[float]",
        (1.0, 10.0, 100.0, 1000.0, 10000.0),
        "ratios alpha k tau of learning rate to relaxation rate (tau: the target strains' "
        "1 % settling time)",
        check=_all(_unique_nonempty, _each(_positive), _increasing),
    )
    media: tuple[str, ...] = _key(
        "list[str]",
        ("network",),
        "media: network (the lattice) and/or continuum (its elastic continuum on the "
        "lattice's triangles, P1, learning its eigenstrain against the mapped drag)",
        choices=("network", "continuum"),
        check=_unique_nonempty,
    )
    bisections: int = _key(
        "int",
        0,
        "bisections of the critical ratio between the largest ratio not past and the next "
        "ratio (log scale)",
        check=_at_least(0),
    )
    draws: tuple[int, ...] = _key(
        "list[int]",
        (1,),
        "task draws (random sources and targets) per size: one number for every size, or "
        "one per size",
        check=_all(lambda v: None if v else "must list at least one entry", _each(_at_least(1))),
    )
    dof: str = _key(
        "str",
        "rest_length",
        "what learns: rest_length (Stern task, raw rate alpha, rho = alpha k tau) or "
        "stiffness (Rocks' response task from [physical_time] response_ratio, source_strain "
        "and distance; GCL's adaptive rate; rho = tau / T_qs)",
        choices=("rest_length", "stiffness"),
    )
    response_ratio: float = _key(
        "float",
        0.3,
        "dof = stiffness: target strain / source strain asked for (sign alternating with the "
        "draw)",
        check=_positive,
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    source_strain: float = _key(
        "float",
        0.05,
        "dof = stiffness: source strain",
        check=_positive,
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    distance: float = _key(
        "float",
        0.25,
        "dof = stiffness: source-target distance in box sizes",
        check=_open_unit,
        used=_when(lambda s: s.physical_time.dof == "stiffness", "with dof = 'stiffness'"),
    )
    eta: float = _key(
        "float",
        0.1,
        "GCL nudge amplitude",
        check=_positive,
        used=_when(
            lambda s: any(r.startswith("gcl") for r in s.physical_time.rules), "by GCL rules"
        ),
    )
    drag: float = _key("float", 1.0, "node drag c", check=_positive)
    dashpot: float = _key("float", 0.0, "spring dashpot gamma (Kelvin-Voigt)", check=_non_negative)
    arm_stiffness: float = _key(
        "float", 0.0, "Maxwell-arm stiffness k2 (0: no arm)", check=_non_negative
    )
    arm_dashpot: float = _key("float", 0.0, "Maxwell-arm dashpot gamma2", check=_non_negative)
    learning_times: float = _key(
        "float", 5.0, "run length in learning times 1 / (alpha k)", check=_positive
    )
    relaxation_times: float = _key(
        "float", 0.05, "shortest run, in relaxation times", check=_positive
    )
    steps_per_tau: int = _key("int", 20, "physical steps per relaxation time", check=_at_least(2))
    steps_per_rate: int = _key(
        "int", 10, "physical steps per learning time 1 / (alpha k)", check=_at_least(1)
    )
    fraction: float = _key(
        "float",
        0.1,
        "learned when the error has made all but this fraction of its quasi-static drop",
        check=_open_unit,
    )
    phase: float = _key(
        "float", 1.0, "gcl_phases: phase length in relaxation times", check=_positive
    )
    frames: int = _key(
        "int",
        25,
        "frames of the exported series",
        check=_at_least(2),
        used=_when(
            lambda s: s.export is not None and s.export.series, "with [export] series = true"
        ),
    )


@dataclass(frozen=True)
class ReportSpec:
    """``[report]``: how the report is drawn."""

    default: bool = _key("bool", False, "part of the default set of ``cvn report``")
    images: bool = _key(
        "bool",
        False,
        "pyvista off-screen renders",
        used=_kinds(
            "learning", "transmission", "relaxation", "continuum_learning", "continuum_mechanism"
        ),
    )
    dpi: int = _key("int", 90, "resolution of the figures", check=_between(40, 300))
