"""Scene files: TOML validated into frozen dataclasses.

A scene is data only (no code is executed from it). Top-level keys::

    name = "paper"            # plain name: letters, digits, '_', '-', '.'; names the folders
    description = "one line"  # shown by ``cvn scenes`` and in the report
    seed = 0                  # first seed; trial i uses seed + i
    kind = "learning"         # learning | transmission | relaxation | stability | solvers
                              # | accuracy | continuum_learning | beyond_paper
                              # | physical_time

and the optional tables ``[network]``, ``[task]``, ``[learning]``, ``[solver]``,
``[continuum]``, ``[dynamics]``, ``[stability]``, ``[accuracy]``, ``[physical_time]``,
``[export]``, ``[report]``, and ``[sweep]`` (the scene as a grid of variants,
:class:`SweepSpec`). Which tables a kind needs and which it accepts is in
:data:`KIND_TABLES`; a table a kind does not use is an error (a scene never carries settings
that are silently ignored). Every key of every table is
listed, with its type, default and meaning, in the dataclasses below (``cvn scenes --keys``
prints them).

Unknown keys, wrong types and impossible values raise :class:`SceneError`, a ``ValueError``
whose message and attributes name the file, the table and the key.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

__all__ = [
    "KINDS",
    "KIND_TABLES",
    "RULES",
    "SOLVER_METHODS",
    "AccuracySpec",
    "ContinuumSpec",
    "DynamicsSpec",
    "ExportSpec",
    "LearningSpec",
    "NetworkSpec",
    "PhysicalTimeSpec",
    "ReportSpec",
    "Scene",
    "SceneError",
    "SolverSpec",
    "StabilitySpec",
    "SweepSpec",
    "TaskSpec",
    "builtin_names",
    "builtin_path",
    "key_reference",
    "load_scene",
    "parse_scene",
    "parse_sweep",
    "sweep_values",
]

KINDS = (
    "learning",
    "transmission",
    "relaxation",
    "stability",
    "solvers",
    "accuracy",
    "physical_time",
    "continuum_learning",
    "beyond_paper",
)

#: For each kind: (tables it needs, tables it also accepts).
KIND_TABLES: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    "learning": (
        frozenset({"network", "task", "learning"}),
        frozenset({"solver", "export", "report"}),
    ),
    "transmission": (
        frozenset({"network", "task"}),
        frozenset({"continuum", "solver", "export", "report"}),
    ),
    "relaxation": (
        frozenset({"network", "dynamics"}),
        frozenset({"continuum", "export", "report"}),
    ),
    "stability": (frozenset({"network", "task", "solver"}), frozenset({"stability", "report"})),
    "solvers": (frozenset({"network", "task", "solver"}), frozenset({"report"})),
    "accuracy": (frozenset({"accuracy"}), frozenset({"report"})),
    "physical_time": (
        frozenset({"network", "task", "physical_time"}),
        frozenset({"export", "report"}),
    ),
    "continuum_learning": (
        frozenset({"network", "task", "learning", "continuum"}),
        frozenset({"export", "report"}),
    ),
    "beyond_paper": (frozenset({"network", "task", "learning"}), frozenset({"report"})),
}

#: Learning runs a scene can name. Paper task: the paper's experiments (see
#: :func:`continuum_vs_network.learning.replication.paper_experiments`; ``gcl``, ``gpc`` and
#: ``exact`` let every spring learn, as the paper does). Stern-scale tasks: ``gcl``, ``gpc``
#: and ``exact`` learn in the bulk only (sources and targets frozen), ``gcl_all`` and
#: ``gpc_all`` let every spring learn (a target can then meet the task alone); ``aging`` and
#: ``aging_k`` are directed aging of rest lengths and of stiffnesses
#: (:class:`~continuum_vs_network.learning.aging.DirectedAging`, in the bulk).
RULES = (
    "gcl",
    "gcl_floor",
    "gcl_frozen",
    "gpc",
    "gpc_frozen",
    "exact",
    "gcl_all",
    "gpc_all",
    "aging",
    "aging_k",
    "gcl_both",
)
#: Rules only the paper task knows, and only Stern-scale tasks know.
PAPER_RULES = ("gcl_floor", "gcl_frozen", "gpc_frozen")
STERN_RULES = ("gcl_all", "gpc_all", "aging", "aging_k", "gcl_both")
#: The rules a ``beyond_paper`` scene compares (in the bulk, on the paper's and Stern's task;
#: ``gcl_both`` learns rest lengths and stiffnesses together).
BEYOND_RULES = ("aging", "aging_k", "gpc", "gcl", "gcl_both", "exact")
#: The rules a ``continuum_learning`` scene trains both media with (Stern-scale meaning:
#: ``gcl``, ``gpc``, ``exact`` in the bulk, sources' and targets' material frozen).
CONTINUUM_RULES = ("gcl", "gpc", "exact", "gcl_all", "gpc_all")
#: Keys renamed: (table, old key) -> new key; an old key is an error naming the new one.
RENAMED = {("learning", "reference"): "strain_reference"}
#: Equilibrium methods of :func:`continuum_vs_network.relax`.
SOLVER_METHODS = ("newton", "fire", "lbfgs", "paper")

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]*")
_NAME_MAX = 100  # it names folders and files (file systems allow 255 bytes per name)
_SEED_MAX = 2**63 - 1  # seeds are stored as int64
_FILE_MAX = 1 << 20  # bytes; a scene is a few dozen lines
_REQUIRED = object()


class SceneError(ValueError):
    """A scene file that cannot be used: names the file, the table and the key.

    Attributes
    ----------
    file : str
    table : str
        ``"(top level)"`` for the top-level keys, ``"(syntax)"`` for a TOML syntax error.
    key : str
        The offending key ("" when the problem is the whole table or file).
    problem : str
    """

    def __init__(self, file: str, table: str, key: str, problem: str) -> None:
        self.file, self.table, self.key, self.problem = str(file), table, key, problem
        where = f"[{table}]" if table and not table.startswith("(") else table
        loc = f"{where} {key}".strip() if key else where
        super().__init__(f"{self.file}: {loc}: {problem}" if loc else f"{self.file}: {problem}")


# -- key declarations ----------------------------------------------------------------------
def _key(
    type_: str,
    default: Any = _REQUIRED,
    doc: str = "",
    *,
    choices: tuple | None = None,
    check: Callable[[Any], str | None] | None = None,
    used: tuple[Callable[[Scene], bool], str] | None = None,
) -> Any:
    """A scene key: TOML type (``int``, ``float``, ``bool``, ``str``, ``list[...]``).

    ``used``: ``(predicate, where)`` when the key matters only in some scenes: a key given
    in a scene where ``predicate(scene)`` is false is an error naming ``where`` it is used,
    and :meth:`Scene.to_dict` (the settings a report prints) leaves it out. None: used
    wherever its table is.
    """
    meta = {"type": type_, "doc": doc, "choices": choices, "check": check, "used": used}
    if default is _REQUIRED:
        return field(metadata=meta)
    return field(default=default, metadata=meta)


def _positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def _non_negative(v: float) -> str | None:
    return None if v >= 0 else "must be >= 0"


def _open_unit(v: float) -> str | None:
    return None if 0 < v < 1 else "must lie strictly between 0 and 1"


def _at_least(n: float) -> Callable[[Any], str | None]:
    return lambda v: None if v >= n else f"must be >= {n}"


def _between(lo: float, hi: float) -> Callable[[Any], str | None]:
    return lambda v: None if lo <= v <= hi else f"must lie in [{lo}, {hi}]"


def _strain(v: float) -> str | None:
    return None if v > -1 else "a strain must be > -1 (a spring cannot have negative length)"


def _each(check: Callable[[Any], str | None]) -> Callable[[tuple], str | None]:
    def run(values: tuple) -> str | None:
        for i, v in enumerate(values):
            msg = check(v)
            if msg:
                return f"entry {i} ({v!r}) {msg}"
        return None

    return run


def _unique_nonempty(values: tuple) -> str | None:
    if not values:
        return "must list at least one entry"
    if len(set(values)) != len(values):
        return "must not repeat entries"
    return None


def _all(*checks: Callable[[Any], str | None]) -> Callable[[Any], str | None]:
    def run(v: Any) -> str | None:
        for c in checks:
            msg = c(v)
            if msg:
                return msg
        return None

    return run


def _increasing(values: tuple) -> str | None:
    if any(b <= a for a, b in itertools.pairwise(values)):
        return "must be strictly increasing"
    return None


# -- where a key is used ---------------------------------------------------------------------
def _kinds(*kinds: str) -> tuple[Callable[[Scene], bool], str]:
    names = kinds[0] if len(kinds) == 1 else ", ".join(kinds[:-1]) + " and " + kinds[-1]
    return (lambda scene: scene.kind in kinds), f"used by {names} scenes"


def _when(pred: Callable[[Scene], bool], where: str) -> tuple[Callable[[Scene], bool], str]:
    return pred, f"used {where}"


def _uses(scene: Scene, table: str, key: str) -> bool:
    """Whether ``scene`` uses ``[table] key`` (see ``_key(used=...)``)."""
    spec = getattr(scene, table)
    if spec is None:
        return False
    used = {f.name: f for f in dataclasses.fields(spec)}[key].metadata["used"]
    return used is None or bool(used[0](scene))


# -- tables ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class NetworkSpec:
    """``[network]``: which network to build.

    ``builder``: ``"paper"`` (the paper's N = 10, S = 18 patch), ``"triangular"`` (a
    triangular lattice), ``"diluted"`` (a rigid diluted lattice) or ``"jammed"`` (a jammed
    packing's contact network).
    """

    builder: str = _key(
        "str", doc="network builder", choices=("paper", "triangular", "diluted", "jammed")
    )
    n_nodes: int | None = _key(
        "int",
        None,
        "about this many nodes (learning on lattices, diluted or jammed networks)",
        check=_at_least(4),
        used=_when(
            lambda s: s.kind == "learning" and s.network.builder != "paper",
            "by learning scenes on triangular, diluted or jammed networks",
        ),
    )
    size: int | None = _key(
        "int",
        None,
        "one n x n triangular lattice (stability, continuum_learning)",
        check=_at_least(3),
        used=_kinds("stability", "continuum_learning"),
    )
    sizes: tuple[int, ...] | None = _key(
        "list[int]",
        None,
        "n x n triangular lattices, one per entry (transmission, relaxation, solvers, "
        "physical_time; beyond_paper: the first hosts Stern's task, all the capacity study)",
        check=_all(_unique_nonempty, _each(_at_least(3)), _increasing),
        used=_kinds("transmission", "relaxation", "solvers", "beyond_paper", "physical_time"),
    )
    noise: float | None = _key(
        "float",
        None,
        "position noise as a fraction of the spacing "
        "(default 0.1 for learning and stability, 0 otherwise)",
        check=_non_negative,
    )
    fraction: float = _key(
        "float",
        0.2,
        "fraction of springs removed (diluted)",
        check=_open_unit,
        used=_when(lambda s: s.network.builder == "diluted", "by diluted networks"),
    )
    stiffness_ratios: tuple[float, ...] = _key(
        "list[float]",
        (),
        "stiffness ratios k_stiff / k_soft (stability)",
        check=_each(_at_least(1.0)),
        used=_kinds("stability"),
    )
    stiff_fraction: float = _key(
        "float",
        0.2,
        "fraction of springs made stiff (stability)",
        check=_open_unit,
        used=_kinds("stability"),
    )


@dataclass(frozen=True)
class TaskSpec:
    """``[task]``: what is clamped and what should respond.

    ``kind``: ``"paper"`` (one source, one target, Sec. 7.1), ``"stern"`` (``n_sources``
    sources and ``n_targets`` targets, Sec. 6.4) or ``"source"`` (one spring, the one nearest
    the centre, clamped at ``strain``; transmission, stability, solvers).
    """

    kind: str = _key("str", doc="task kind", choices=("paper", "stern", "source"))
    n_sources: int = _key(
        "int",
        10,
        "source springs (stern)",
        check=_at_least(1),
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    n_targets: int = _key(
        "int",
        3,
        "target springs (stern)",
        check=_at_least(1),
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    source_std: float = _key(
        "float",
        0.1,
        "std of the source strains (stern)",
        check=_positive,
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    target_std: float = _key(
        "float",
        0.1,
        "std of the desired target strains (stern)",
        check=_positive,
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    anchored: bool = _key(
        "bool",
        False,
        "train the task together with its rest example (sources at zero strain, targets "
        "at their untrained rest strains): non-trivial by construction (stern, learning)",
        used=_when(
            lambda s: s.task.kind == "stern" and s.kind == "learning",
            "by stern tasks in learning scenes",
        ),
    )
    strain: float = _key(
        "float",
        0.1,
        "strain of the clamped source spring (source)",
        check=_strain,
        used=_when(lambda s: s.task.kind == "source", "by source tasks"),
    )
    strains: tuple[float, ...] = _key(
        "list[float]",
        (),
        "extreme source strains (stability)",
        check=_each(_strain),
        used=_kinds("stability"),
    )


@dataclass(frozen=True)
class LearningSpec:
    """``[learning]``: the training runs (every rule x solver x noise level, ``trials`` each)."""

    rules: tuple[str, ...] = _key(
        "list[str]", doc="learning runs", choices=RULES, check=_unique_nonempty
    )
    trials: int = _key(
        "int",
        10,
        "independent trials (seeds seed, seed + 1, ...)",
        check=_at_least(1),
        used=_kinds("learning"),
    )
    steps: int = _key("int", 300, "learning steps per trial", check=_at_least(1))
    strain_reference: str = _key(
        "str",
        "initial",
        "strain convention of clamps and error: 'initial' (fixed target geometries) or "
        "'current' (the paper's literal S = r / L - 1 with the learning L)",
        choices=("initial", "current"),
    )
    alpha_gcl: float = _key("float", 1e-3, "GCL learning rate", check=_positive)
    eta: float = _key("float", 0.1, "GCL nudge amplitude", check=_positive)
    etas: tuple[float, ...] = _key(
        "list[float]",
        (),
        "GCL nudge amplitudes, one GCL run per value (named <rule>_eta<value>); empty: eta "
        "(beyond_paper: the thermal study's nudges)",
        check=_each(_positive),
        used=_when(
            lambda s: (
                s.kind == "beyond_paper"
                or (s.kind == "learning" and any(r.startswith("gcl") for r in s.learning.rules))
            ),
            "by learning scenes with a GCL rule and beyond_paper scenes",
        ),
    )
    alpha_gpc: float = _key("float", 1e-3, "GPC learning rate", check=_positive)
    alpha_exact: float = _key(
        "float",
        1.0,
        "exact-gradient learning rate",
        check=_positive,
        used=_kinds("learning", "continuum_learning"),
    )
    alpha_aging: float = _key(
        "float",
        0.5,
        "directed-aging rate (aging, aging_k)",
        check=_positive,
        used=_when(
            lambda s: any(r.startswith("aging") for r in s.learning.rules),
            "with rules aging or aging_k",
        ),
    )
    temperatures: tuple[float, ...] = _key(
        "list[float]",
        (0.0, 1e-8, 1e-6),
        "temperatures k_B T of the thermal study (every state read as a harmonic Boltzmann "
        "draw), one GCL run per nudge of etas and one exact-gradient run per entry",
        check=_all(_unique_nonempty, _each(_non_negative), _increasing),
        used=_kinds("beyond_paper"),
    )
    examples: tuple[int, ...] = _key(
        "list[int]",
        (1, 2, 4, 8),
        "numbers of examples trained together, one capacity run per entry and lattice size",
        check=_all(_unique_nonempty, _each(_at_least(1)), _increasing),
        used=_kinds("beyond_paper"),
    )
    floor: float = _key(
        "float",
        0.1,
        "rest-length floor of the *_floor, *_frozen, gpc and exact runs",
        check=_positive,
        used=_kinds("learning"),
    )
    noise: tuple[float, ...] = _key(
        "list[float]",
        (0.0,),
        "relative read-out noise levels (one run per level)",
        check=_all(_unique_nonempty, _each(_non_negative)),
        used=_kinds("learning"),
    )
    measure: bool = _key(
        "bool",
        True,
        "solve the free state after every step to measure the "
        "error even when the rule does not need it (GPC), and measure the coupling of "
        "every trained network",
        used=_kinds("learning"),
    )
    sweeps: bool = _key(
        "bool", False, "source sweeps of the trained networks (Fig. 5)", used=_kinds("learning")
    )
    sweep_span: float = _key(
        "float",
        5.0,
        "sweep source strains S +- span",
        check=_positive,
        used=_when(
            lambda s: s.kind == "learning" and s.learning.sweeps,
            "by learning scenes with sweeps = true",
        ),
    )
    sweep_points: int = _key(
        "int",
        11,
        "points per sweep",
        check=_at_least(2),
        used=_when(
            lambda s: s.kind == "learning" and s.learning.sweeps,
            "by learning scenes with sweeps = true",
        ),
    )
    compare_gradient: bool = _key(
        "bool",
        False,
        "cosine of each rule's step with the exact gradient, at the initial and final networks",
        used=_kinds("learning"),
    )
    checkpoint_every: int = _key(
        "int", 25, "steps between checkpoints", check=_at_least(1), used=_kinds("learning")
    )


@dataclass(frozen=True)
class SolverSpec:
    """``[solver]``: equilibrium methods and their budgets.

    Learning scenes accept ``"newton"`` (exact equilibria) and ``"paper"`` (the paper's
    Adagrad with rods, ``paper_iterations`` per state); stability and solver scenes compare
    every method listed.
    """

    methods: tuple[str, ...] = _key(
        "list[str]",
        ("newton",),
        "equilibrium methods",
        choices=SOLVER_METHODS,
        check=_unique_nonempty,
        used=_kinds("learning", "stability", "solvers"),
    )
    tol: float = _key(
        "float",
        1e-10,
        "relative residual tolerance (net force on a free coordinate / its node's sum k L)",
        check=_open_unit,
        used=_kinds("transmission", "stability", "solvers"),
    )
    max_seconds: float = _key(
        "float",
        60.0,
        "time budget of one solve (s)",
        check=_positive,
        used=_kinds("stability", "solvers"),
    )
    paper_iterations: int = _key(
        "int",
        300,
        "Adagrad iterations per state (learning with 'paper')",
        check=_at_least(1),
        used=_when(
            lambda s: s.kind == "learning" and "paper" in s.solver.methods,
            "by learning scenes with method 'paper'",
        ),
    )
    rod_stiffnesses: tuple[float, ...] = _key(
        "list[float]",
        (),
        "stiffness of the paper's clamp rods (stability)",
        check=_each(_positive),
        used=_kinds("stability"),
    )
    ramp: int = _key(
        "int",
        4,
        "strain continuation steps (stability)",
        check=_at_least(1),
        used=_kinds("stability"),
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
        (0.3, 1.0, 3.0, 10.0, 30.0),
        "ratios alpha k tau of learning rate to relaxation rate",
        check=_all(_unique_nonempty, _each(_positive), _increasing),
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
        "float", 6.0, "shortest run, in relaxation times", check=_positive
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
        used=_kinds("learning", "transmission", "relaxation", "continuum_learning"),
    )
    dpi: int = _key("int", 90, "resolution of the figures", check=_between(40, 300))


_TABLES: dict[str, type] = {
    "network": NetworkSpec,
    "task": TaskSpec,
    "learning": LearningSpec,
    "solver": SolverSpec,
    "continuum": ContinuumSpec,
    "dynamics": DynamicsSpec,
    "stability": StabilitySpec,
    "accuracy": AccuracySpec,
    "physical_time": PhysicalTimeSpec,
    "export": ExportSpec,
    "report": ReportSpec,
}


@dataclass(frozen=True)
class Scene:
    """A validated scene.

    Attributes
    ----------
    name, description : str
    seed : int
    kind : str
        One of :data:`KINDS`.
    network, task, learning, solver, continuum, dynamics, stability, accuracy, physical_time,
    export : spec or None
        The tables given (None when absent).
    report : ReportSpec
        Always present (defaults when the table is absent).
    sweep : SweepSpec or None
        The ``[sweep]`` table: the scene is a grid of variants (see :mod:`.grid`).
    source : str
        The file the scene was read from.
    """

    name: str
    description: str
    seed: int
    kind: str
    network: NetworkSpec | None = None
    task: TaskSpec | None = None
    learning: LearningSpec | None = None
    solver: SolverSpec | None = None
    continuum: ContinuumSpec | None = None
    dynamics: DynamicsSpec | None = None
    stability: StabilitySpec | None = None
    accuracy: AccuracySpec | None = None
    physical_time: PhysicalTimeSpec | None = None
    export: ExportSpec | None = None
    report: ReportSpec = field(default_factory=ReportSpec)
    sweep: SweepSpec | None = None
    source: str = field(default="", compare=False)

    def to_dict(self) -> dict[str, Any]:
        """Plain (TOML-like) dict of the scene: top-level keys and the tables given, each
        with the keys this scene uses (defaults included; unused and unset keys left out).
        ``parse_scene(scene.to_dict())`` gives the scene back."""
        out: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "seed": self.seed,
            "kind": self.kind,
        }
        for table in _TABLES:
            spec = getattr(self, table)
            if spec is not None:
                out[table] = {
                    k: list(v) if isinstance(v, tuple) else v
                    for k, v in dataclasses.asdict(spec).items()
                    if v is not None and _uses(self, table, k)
                }
        if self.sweep is not None:
            out["sweep"] = self.sweep.to_dict()
        return out

    def with_export(self, export: ExportSpec | None = None) -> Scene:
        """The same scene with an ``[export]`` table (defaults when None)."""
        return dataclasses.replace(self, export=export or ExportSpec())


# -- parsing -------------------------------------------------------------------------------
_TOP: dict[str, tuple[str, Any]] = {
    "name": ("str", _REQUIRED),
    "description": ("str", _REQUIRED),
    "seed": ("int", 0),
    "kind": ("str", _REQUIRED),
}


def _convert(value: Any, type_: str, where: tuple[str, str, str]) -> Any:
    file, table, key = where

    def fail(want: str) -> SceneError:
        got = type(value).__name__
        return SceneError(file, table, key, f"must be {want}, got {got} {value!r}")

    if type_ == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise fail("an integer")
        return int(value)
    if type_ == "float":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise fail("a number")
        value = float(value)
        if not math.isfinite(value):
            raise SceneError(file, table, key, f"must be finite, got {value}")
        return value
    if type_ == "bool":
        if not isinstance(value, bool):
            raise fail("true or false")
        return value
    if type_ == "str":
        if not isinstance(value, str):
            raise fail("a string")
        return value
    if type_.startswith("list["):
        inner = type_[5:-1]
        if not isinstance(value, list):
            raise fail(f"a list of {inner}s")
        out = []
        for i, item in enumerate(value):
            out.append(_convert(item, inner, (file, table, f"{key}[{i}]")))
        return tuple(out)
    raise AssertionError(type_)  # pragma: no cover


def _value(f: dataclasses.Field, value: Any, where: tuple[str, str, str]) -> Any:
    """One key's value converted to its type and checked against its choices and rules."""
    file, table, key = where
    meta = f.metadata
    converted = _convert(value, meta["type"], where)
    choices = meta["choices"]
    if choices is not None:
        items = converted if isinstance(converted, tuple) else (converted,)
        for item in items:
            if item not in choices:
                raise SceneError(
                    file, table, key, f"{item!r} is not one of {', '.join(map(repr, choices))}"
                )
    if meta["check"] is not None:
        msg = meta["check"](converted)
        if msg:
            raise SceneError(file, table, key, f"{msg} (got {value!r})")
    return converted


def _parse_table(cls: type, data: Any, file: str, table: str) -> Any:
    if not isinstance(data, Mapping):
        raise SceneError(
            file, "(top level)", table, f"must be a table [{table}], got {type(data).__name__}"
        )
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs: dict[str, Any] = {}
    for key, value in data.items():
        if (table, key) in RENAMED:
            raise SceneError(file, table, key, f"renamed; use {RENAMED[table, key]} = ...")
        if key not in fields:
            raise SceneError(
                file, table, key, f"unknown key; [{table}] accepts {', '.join(sorted(fields))}"
            )
        kwargs[key] = _value(fields[key], value, (file, table, key))
    for name, f in fields.items():
        if (
            name not in kwargs
            and f.default is dataclasses.MISSING
            and (f.default_factory is dataclasses.MISSING)
        ):
            raise SceneError(file, table, name, "is required")
    return cls(**kwargs)


def parse_scene(data: Mapping[str, Any], file: str = "<scene>") -> Scene:
    """Validate a scene given as a dict (as ``tomllib`` returns it).

    Raises
    ------
    SceneError
        Naming ``file``, the table and the key.
    """
    top: dict[str, Any] = {}
    tables: dict[str, Any] = {}
    for key, value in data.items():
        if key in _TABLES:
            tables[key] = _parse_table(_TABLES[key], value, file, key)
        elif key == "sweep":
            tables[key] = parse_sweep(value, file)
        elif key in _TOP:
            top[key] = _convert(value, _TOP[key][0], (file, "(top level)", key))
        else:
            known = sorted([*_TOP, *_TABLES, "sweep"])
            raise SceneError(
                file, "(top level)", key, f"unknown key or table; a scene has {', '.join(known)}"
            )
    for key, (_, default) in _TOP.items():
        if key not in top:
            if default is _REQUIRED:
                raise SceneError(file, "(top level)", key, "is required")
            top[key] = default
    if not _NAME.fullmatch(top["name"]) or len(top["name"]) > _NAME_MAX:
        raise SceneError(
            file,
            "(top level)",
            "name",
            f"must be a plain name of at most {_NAME_MAX} characters (letters, digits, '_', "
            f"'-', '.'; starting with a letter or digit), got {_short(repr(top['name']))}",
        )
    desc = top["description"].strip()
    if not desc or "\n" in desc:
        raise SceneError(file, "(top level)", "description", "must be one non-empty line")
    top["description"] = desc
    if not 0 <= top["seed"] <= _SEED_MAX:
        raise SceneError(
            file, "(top level)", "seed", f"must be in 0..2**63-1, got {_short(top['seed'])}"
        )
    if top["kind"] not in KINDS:
        raise SceneError(
            file,
            "(top level)",
            "kind",
            f"{top['kind']!r} is not one of {', '.join(map(repr, KINDS))}",
        )
    scene = Scene(**top, **tables, source=str(file))
    _check_kind(scene, file)
    _check_used(scene, data, file)
    if scene.learning is not None and scene.seed + scene.learning.trials - 1 > _SEED_MAX:
        raise SceneError(
            file,
            "(top level)",
            "seed",
            f"trial i uses seed + i, so seed + trials - 1 must be <= 2**63-1; got seed = "
            f"{scene.seed} with [learning] trials = {scene.learning.trials}",
        )
    from .limits import check_resources

    check_resources(scene, str(file))
    return scene


def _check_physical_time(scene: Scene, file: str, need_key: Callable) -> None:
    net, task, spec = scene.network, scene.task, scene.physical_time
    if net.builder != "triangular":
        raise SceneError(
            file, "network", "builder", "kind 'physical_time' runs on triangular lattices"
        )
    need_key("network", "sizes", "for a physical_time scene")
    if task.kind != "stern":
        raise SceneError(file, "task", "kind", "kind 'physical_time' takes kind = 'stern'")
    if (spec.arm_stiffness > 0) != (spec.arm_dashpot > 0):
        raise SceneError(
            file,
            "physical_time",
            "arm_dashpot",
            "arm_stiffness and arm_dashpot must both be > 0 (a Maxwell arm) or both 0",
        )


def _short(value: Any, width: int = 60) -> str:
    """``repr(value)`` (strings: the text itself) cut to ``width`` characters."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def _check_used(scene: Scene, data: Mapping[str, Any], file: str) -> None:
    """Every key given must be one the scene uses (tables: :func:`_check_kind`)."""
    for table, values in data.items():
        if table not in _TABLES:
            continue
        fields = {f.name: f for f in dataclasses.fields(_TABLES[table])}
        for key in values:
            used = fields[key].metadata["used"]
            if used is not None and not used[0](scene):
                raise SceneError(
                    file,
                    table,
                    key,
                    f"kind {scene.kind!r} does not use this key here ({used[1]}); remove it",
                )


def _check_kind(scene: Scene, file: str) -> None:
    """Tables a kind needs and accepts, and the keys each kind needs."""
    need, accept = KIND_TABLES[scene.kind]
    given = {t for t in _TABLES if getattr(scene, t) is not None}
    for table in sorted(need - given):
        raise SceneError(file, table, "", f"kind {scene.kind!r} needs a [{table}] table")
    for table in sorted(given - need - accept - {"report"}):
        raise SceneError(
            file, table, "", f"kind {scene.kind!r} does not use a [{table}] table; remove it"
        )

    def need_key(table: str, key: str, why: str) -> None:
        spec = getattr(scene, table)
        value = getattr(spec, key)
        if value is None or value == ():
            raise SceneError(file, table, key, f"is required {why}")

    net, task = scene.network, scene.task
    kind = scene.kind
    if kind == "continuum_learning":
        _check_continuum_learning(scene, file, need_key)
        return
    if kind == "beyond_paper":
        _check_beyond_paper(scene, file, need_key)
        return
    if kind == "accuracy":
        return
    if kind == "physical_time":
        _check_physical_time(scene, file, need_key)
        return
    if kind == "learning":
        assert net is not None and task is not None and scene.learning is not None
        if net.builder == "paper" and task.kind != "paper":
            raise SceneError(
                file, "task", "kind", "the paper network takes the paper task (kind = 'paper')"
            )
        if net.builder != "paper":
            if task.kind != "stern":
                raise SceneError(
                    file, "task", "kind", f"a {net.builder!r} network takes kind = 'stern'"
                )
            need_key("network", "n_nodes", "for a learning scene on a large network")
            if scene.learning.strain_reference != "initial":
                raise SceneError(
                    file,
                    "learning",
                    "strain_reference",
                    "Stern-scale runs measure strains against the initial rest "
                    "lengths; set strain_reference = 'initial'",
                )
            bad = [r for r in scene.learning.rules if r in PAPER_RULES]
            if bad:
                raise SceneError(
                    file,
                    "learning",
                    "rules",
                    f"{bad[0]!r} exists for the paper task only (Stern-scale 'gcl', 'gpc' "
                    "and 'exact' already freeze sources and targets; 'gcl_all' and "
                    "'gpc_all' let every spring learn)",
                )
        else:
            bad = [r for r in scene.learning.rules if r in STERN_RULES]
            if bad:
                raise SceneError(
                    file,
                    "learning",
                    "rules",
                    f"{bad[0]!r} exists for Stern-scale tasks only (the paper's 'gcl' and "
                    "'gpc' already let every spring learn; directed aging of the paper task "
                    "is in the beyond_paper scene)",
                )
        if scene.solver is not None:
            bad = [m for m in scene.solver.methods if m not in ("newton", "paper")]
            if bad:
                raise SceneError(
                    file,
                    "solver",
                    "methods",
                    f"learning runs use 'newton' (exact equilibria) or 'paper' "
                    f"(the paper's Adagrad), got {bad[0]!r}",
                )
        if scene.export is not None:
            bad = [t for t in scene.export.trials if t >= scene.learning.trials]
            if bad:
                raise SceneError(
                    file,
                    "export",
                    "trials",
                    f"trial {bad[0]} does not exist ([learning] trials = {scene.learning.trials})",
                )
    else:
        if net.builder != "triangular":
            raise SceneError(
                file,
                "network",
                "builder",
                f"kind {kind!r} runs on triangular lattices ('triangular')",
            )
        if task is not None and task.kind != "source":
            raise SceneError(file, "task", "kind", f"kind {kind!r} takes kind = 'source'")
        if kind == "stability":
            need_key("network", "size", "for a stability scene")
            if not (net.stiffness_ratios or task.strains or scene.solver.rod_stiffnesses):
                raise SceneError(
                    file,
                    "network",
                    "stiffness_ratios",
                    "a stability scene needs cases: stiffness_ratios, "
                    "[task] strains or [solver] rod_stiffnesses",
                )
        else:
            need_key("network", "sizes", f"for a {kind} scene")
    if kind == "relaxation" and scene.continuum is not None:
        assert scene.dynamics is not None
        if scene.dynamics.scheme == "explicit":
            raise SceneError(
                file,
                "dynamics",
                "scheme",
                "the continuum has no explicit scheme; use 'implicit' or 'newmark'",
            )


def _check_continuum_learning(scene: Scene, file: str, need_key) -> None:
    if scene.network.builder != "triangular":
        raise SceneError(
            file, "network", "builder", "continuum_learning runs on a triangular lattice"
        )
    need_key("network", "size", "for a continuum_learning scene (an n x n lattice)")
    if scene.task.kind != "stern":
        raise SceneError(file, "task", "kind", "continuum_learning takes kind = 'stern'")
    bad = [r for r in scene.learning.rules if r not in CONTINUUM_RULES]
    if bad:
        raise SceneError(
            file,
            "learning",
            "rules",
            f"{bad[0]!r} is not a continuum_learning rule ({', '.join(CONTINUUM_RULES)})",
        )
    if scene.learning.strain_reference != "initial":
        raise SceneError(
            file,
            "learning",
            "strain_reference",
            "a continuum's material springs measure strain against the undeformed body; "
            "set strain_reference = 'initial'",
        )


def _check_beyond_paper(scene: Scene, file: str, need_key) -> None:
    if scene.network.builder != "triangular":
        raise SceneError(file, "network", "builder", "beyond_paper runs on triangular lattices")
    need_key("network", "sizes", "for a beyond_paper scene (the capacity study's lattices)")
    if scene.task.kind != "stern":
        raise SceneError(
            file, "task", "kind", "beyond_paper takes kind = 'stern' (the paper's task is added)"
        )
    bad = [r for r in scene.learning.rules if r not in BEYOND_RULES]
    if bad:
        raise SceneError(
            file,
            "learning",
            "rules",
            f"{bad[0]!r} is not a beyond_paper rule ({', '.join(BEYOND_RULES)})",
        )
    if scene.learning.strain_reference != "initial":
        raise SceneError(
            file,
            "learning",
            "strain_reference",
            "beyond_paper learns fixed target geometries; set strain_reference = 'initial'",
        )


# -- sweeps ----------------------------------------------------------------------------------
#: Tables whose keys a sweep may vary (besides the top-level ``seed``).
_SWEEPABLE = tuple(t for t in _TABLES if t not in ("export", "report"))
_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")


@dataclass(frozen=True)
class SweepSpec:
    """``[sweep]``: the scene as a grid of variants (expanded by :func:`.grid.expand`).

    In the file, each key names a scene key (``learning.eta = [0.03, 0.1]``, or quoted
    ``"learning.eta"``, or ``seed = "0..9"`` for the integers 0 to 9) and lists its values;
    a single value sets the key for every point. Keys that take a list (``learning.noise``)
    take one list per value, or plain values that each become a one-entry list.

    Attributes
    ----------
    axes : tuple of (key, values)
        In the order given; the grid is their cartesian product, first key slowest.
    zip : tuple of tuple of str
        Groups of axes varied together instead (equal lengths): one grid dimension each.
    threshold : float
        ``steps_to_threshold`` in the sweep table is the first step whose error is at most
        ``threshold`` times the trial's initial error.
    """

    axes: tuple[tuple[str, tuple[Any, ...]], ...]
    zip: tuple[tuple[str, ...], ...] = ()
    threshold: float = 0.1

    def to_dict(self) -> dict[str, Any]:
        """Plain (TOML-like) dict of the table."""
        out: dict[str, Any] = {
            k: [list(v) if isinstance(v, tuple) else v for v in vals] for k, vals in self.axes
        }
        if self.zip:
            out["zip"] = [list(g) for g in self.zip]
        out["threshold"] = self.threshold
        return out


def sweep_values(key: str, raw: Any, file: str) -> tuple[Any, ...]:
    """The values of sweep axis ``key``, each converted and checked like the key itself.

    ``raw``: a list of values, one value, or ``"a..b"`` (the integers a to b) for an
    integer key. Raises :class:`SceneError` naming ``file``, ``[sweep]`` and the key.
    """
    where = (file, "sweep", key)
    if key == "seed":
        f = dataclasses.field(
            metadata={"type": "int", "choices": None, "check": _non_negative_int, "doc": ""}
        )
    else:
        table, _, name = key.partition(".")
        if table not in _SWEEPABLE:
            allowed = ", ".join(["seed", *(f"{t}.<key>" for t in _SWEEPABLE)])
            raise SceneError(file, "sweep", key, f"unknown sweep key; a sweep varies {allowed}")
        fields = {f.name: f for f in dataclasses.fields(_TABLES[table])}
        if (table, name) in RENAMED:
            new_key = f"{table}.{RENAMED[table, name]}"
            raise SceneError(file, "sweep", key, f"renamed; use {new_key}")
        if name not in fields:
            raise SceneError(
                file,
                "sweep",
                key,
                f"unknown key; [{table}] accepts {', '.join(sorted(fields))}",
            )
        f = fields[name]
    type_ = f.metadata["type"]
    match = _RANGE.match(raw) if isinstance(raw, str) else None
    if match and type_ == "int":
        lo, hi = int(match[1]), int(match[2])
        if hi < lo or hi - lo >= 100_000:
            raise SceneError(*where, f"range {raw!r} must run upwards, at most 100000 values")
        items: list[Any] = list(range(lo, hi + 1))
    elif isinstance(raw, list):
        items = raw
    else:
        items = [raw]
    if not items:
        raise SceneError(*where, "must list at least one value")
    out = []
    for i, item in enumerate(items):
        if type_.startswith("list[") and not isinstance(item, list):
            item = [item]
        label = key if len(items) == 1 else f"{key}[{i}]"
        out.append(_value(f, item, (file, "sweep", label)))
    if len(set(map(repr, out))) != len(out):
        raise SceneError(*where, f"must not repeat values (got {raw!r})")
    return tuple(out)


def _non_negative_int(v: int) -> str | None:
    return None if v >= 0 else "must be >= 0"


def parse_sweep(data: Any, file: str) -> SweepSpec:
    """Validate a ``[sweep]`` table (see :class:`SweepSpec`)."""
    if not isinstance(data, Mapping):
        raise SceneError(file, "(top level)", "sweep", "must be a table [sweep]")
    axes: dict[str, tuple] = {}
    zip_groups: Any = []
    threshold: Any = 0.1
    for key, value in data.items():
        if key == "zip":
            zip_groups = value
        elif key == "threshold":
            threshold = value
        elif isinstance(value, Mapping):  # learning.eta = [...] is {"learning": {"eta": ...}}
            for sub, v in value.items():
                axes[f"{key}.{sub}"] = sweep_values(f"{key}.{sub}", v, file)
        else:
            axes[key] = sweep_values(key, value, file)
    threshold = _convert(threshold, "float", (file, "sweep", "threshold"))
    if not 0 < threshold < 1:
        raise SceneError(file, "sweep", "threshold", "must lie strictly between 0 and 1")
    if not axes:
        raise SceneError(file, "sweep", "", "names no key to vary")
    groups = check_zip(zip_groups, axes, file)
    return SweepSpec(axes=tuple(axes.items()), zip=groups, threshold=threshold)


def check_zip(groups: Any, axes: Mapping[str, tuple], file: str) -> tuple[tuple[str, ...], ...]:
    """Validated zip groups: lists of two or more axes of equal length, each in one group."""
    where = (file, "sweep", "zip")
    if not isinstance(groups, list) or not all(isinstance(g, list) for g in groups):
        raise SceneError(*where, "must be a list of lists of sweep keys")
    seen: set[str] = set()
    out = []
    for g in groups:
        if len(g) < 2:
            raise SceneError(*where, f"a group needs two or more keys, got {g!r}")
        for k in g:
            if k not in axes:
                raise SceneError(*where, f"{k!r} is not a key of the sweep")
            if k in seen:
                raise SceneError(*where, f"{k!r} is in two groups")
            seen.add(k)
        lengths = {len(axes[k]) for k in g}
        if len(lengths) != 1:
            sizes = ", ".join(f"{k}: {len(axes[k])}" for k in g)
            raise SceneError(*where, f"zipped keys need equally many values ({sizes})")
        out.append(tuple(g))
    return tuple(out)


# -- files ---------------------------------------------------------------------------------
def builtin_names() -> list[str]:
    """Names of the built-in scenes (files ``scenes/builtin/<name>.toml``), sorted."""
    folder = resources.files("continuum_vs_network.scenes") / "builtin"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_path(name: str) -> Path:
    """Path of the built-in scene ``name``."""
    folder = resources.files("continuum_vs_network.scenes") / "builtin"
    path = Path(str(folder / f"{name}.toml"))
    if not path.is_file():
        raise SceneError(
            f"{name}.toml",
            "",
            "",
            f"no built-in scene {name!r}; built-in scenes: {', '.join(builtin_names())}",
        )
    return path


def load_scene(scene: str | Path) -> Scene:
    """Read a scene: a path to a ``.toml`` file or the name of a built-in scene."""
    if not isinstance(scene, str | Path):
        raise SceneError(repr(scene), "", "", "a scene is a path or a built-in name")
    path = Path(scene)
    try:
        is_file = path.is_file()
    except OSError as err:  # a name too long, a symlink loop
        raise SceneError(_short(str(scene)), "", "", f"cannot read: {err.strerror}") from None
    if not is_file:
        if path.is_dir():
            raise SceneError(_short(str(scene)), "", "", "is a folder, not a scene file")
        if str(scene).endswith(".toml") or "/" in str(scene) or path.exists():
            raise SceneError(_short(str(scene)), "", "", "no such scene file")
        if not _NAME.fullmatch(str(scene)) or len(str(scene)) > _NAME_MAX:
            raise SceneError(
                _short(str(scene)),
                "",
                "",
                f"no such scene file or built-in scene; built-in scenes: "
                f"{', '.join(builtin_names())}",
            )
        path = builtin_path(str(scene))
    try:
        with open(path, "rb") as fh:
            raw = fh.read(_FILE_MAX + 1)
        if len(raw) > _FILE_MAX:
            raise SceneError(str(path), "", "", f"larger than {_FILE_MAX} bytes: not a scene file")
        data = tomllib.loads(raw.decode("utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise SceneError(str(path), "(syntax)", "", f"not valid TOML: {err}") from err
    except UnicodeDecodeError as err:
        raise SceneError(
            str(path), "(syntax)", "", f"not UTF-8 text (byte {err.start}): a scene is TOML"
        ) from None
    except RecursionError:
        raise SceneError(str(path), "(syntax)", "", "nested too deeply to be a scene") from None
    except OSError as err:
        raise SceneError(str(path), "", "", f"cannot read: {err.strerror or err}") from None
    return parse_scene(data, str(path))


def key_reference() -> str:
    """Every table and key with its type, default and meaning (plain text)."""
    lines = [
        f"(top level): name (str), description (str), seed (int, 0), kind ({' | '.join(KINDS)})"
    ]
    for table, cls in _TABLES.items():
        lines.append(f"\n[{table}]")
        for f in dataclasses.fields(cls):
            meta = f.metadata
            default = "required" if f.default is dataclasses.MISSING else repr(f.default)
            choices = f" one of {', '.join(map(repr, meta['choices']))};" if meta["choices"] else ""
            lines.append(f"  {f.name} ({meta['type']}, {default}):{choices} {meta['doc']}")
    lines.append(
        "\n[sweep] (any kind; run with `cvn sweep`): <table>.<key> = [values] or seed = 'a..b' "
        "(a grid: cartesian product, first key slowest); zip = [[keys varied together]]; "
        "threshold (float, 0.1): steps_to_threshold counts steps to error <= threshold x initial"
    )
    lines.append("\nTables by kind (needed; also accepted):")
    for kind, (need, accept) in KIND_TABLES.items():
        lines.append(f"  {kind}: {', '.join(sorted(need))}; {', '.join(sorted(accept))}")
    return "\n".join(lines)
