"""Scene tables ``[network]``, ``[task]``, ``[learning]`` and ``[solver]``: one frozen dataclass
each, every key declared with :func:`.keys._key`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .keys import (
    RULES,
    SOLVER_METHODS,
    _all,
    _at_least,
    _each,
    _increasing,
    _key,
    _kinds,
    _non_negative,
    _open_unit,
    _positive,
    _strain,
    _unique_nonempty,
    _when,
)

#: the raw-rate keys: every kind but beyond_paper, which uses the package's default rates
_NOT_BEYOND = _when(
    lambda s: s.kind != "beyond_paper", "outside beyond_paper (it uses the default rates)"
)


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
        "physical_time; beyond_paper: the largest hosts the single-network studies, all "
        "the capacity study)",
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
        "at their untrained rest strains): cannot be met trivially (stern, learning)",
        used=_when(
            lambda s: s.task.kind == "stern" and s.kind == "learning",
            "by stern tasks in learning scenes",
        ),
    )
    node_outputs: tuple[str, ...] = _key(
        "list[str]",
        ("absolute", "relative"),
        "outputs of the node task, one run per entry and rule: node coordinates "
        "('absolute') or a node's coordinate relative to another node's ('relative')",
        choices=("absolute", "relative"),
        check=_unique_nonempty,
        used=_kinds("beyond_paper"),
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
    alpha_gcl: float = _key(
        "float", 1e-3, "GCL learning rate", check=_positive, used=_NOT_BEYOND
    )
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
    alpha_gpc: float = _key(
        "float", 1e-3, "GPC learning rate", check=_positive, used=_NOT_BEYOND
    )
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
            lambda s: s.kind != "beyond_paper"
            and any(r.startswith("aging") for r in s.learning.rules),
            "with rules aging or aging_k (beyond_paper uses the default rates)",
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
    compare_tasks: tuple[str, ...] = _key(
        "list[str]",
        ("paper", "lattice"),
        "beyond_paper: the tasks every rule is compared on ('paper': the paper's network "
        "and task; 'lattice': Rocks et al.'s allosteric task on the first lattice)",
        choices=("paper", "lattice"),
        check=_unique_nonempty,
        used=_kinds("beyond_paper"),
    )
    examples: tuple[int, ...] = _key(
        "list[int]",
        (1, 2, 4, 8),
        "numbers of examples trained together, one capacity run per entry and lattice size",
        check=_all(_unique_nonempty, _each(_at_least(1)), _increasing),
        used=_kinds("beyond_paper"),
    )
    capacity_seeds: int = _key(
        "int",
        3,
        "draws of the examples per lattice size and number of examples (capacity study)",
        check=_at_least(1),
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
    paper_setting: bool = _key(
        "bool",
        False,
        "paper task: the runs of the author's notebooks, each rule in its own convention "
        "(GCL of both signs against the learning L, GPC against fixed rods, sources frozen; "
        "scenes.paper_setting)",
        used=_when(lambda s: s.task.kind == "paper", "by the paper task"),
    )
    steps_gpc: int = _key(
        "int",
        0,
        "learning steps of the GPC runs (0: steps)",
        check=_non_negative,
        used=_when(lambda s: s.task.kind == "paper", "by the paper task"),
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
