"""Scene tables ``[network]``, ``[task]``, ``[learning]`` and ``[solver]``: one frozen dataclass
each, every key declared with :func:`.keys.key`.
"""

from typing import Annotated, Literal

from .keys import (
    RULES,
    SOLVER_METHODS,
    Bool,
    Float,
    Int,
    _at_least,
    _each,
    _increasing,
    _kinds,
    _non_negative,
    _open_unit,
    _positive,
    _strain,
    _unique_nonempty,
    _when,
    key,
    table,
)

#: the raw-rate keys: every kind but beyond_paper, which uses the package's default rates
_NOT_BEYOND = _when(
    lambda s: s.kind != "beyond_paper", "outside beyond_paper (it uses the default rates)"
)


@table
class NetworkSpec:
    """``[network]``: which network to build.

    ``builder``: ``"paper"`` (the paper's N = 10, S = 18 patch), ``"triangular"`` (a
    triangular lattice), ``"diluted"`` (a rigid diluted lattice) or ``"jammed"`` (a jammed
    packing's contact network).
    """

    builder: Literal["paper", "triangular", "diluted", "jammed"] = key(doc="network builder")
    n_nodes: Annotated[Int, _at_least(4)] | None = key(
        None,
        "about this many nodes (learning on lattices, diluted or jammed networks)",
        used=_when(
            lambda s: s.kind == "learning" and s.network.builder != "paper",
            "by learning scenes on triangular, diluted or jammed networks",
        ),
    )
    size: Annotated[Int, _at_least(3)] | None = key(
        None,
        "one n x n triangular lattice (stability, continuum_learning)",
        used=_kinds("stability", "continuum_learning"),
    )
    sizes: Annotated[tuple[Int, ...], _unique_nonempty, _each(_at_least(3)), _increasing] | None = (
        key(
            None,
            "n x n triangular lattices, one per entry (transmission, relaxation, solvers, "
            "physical_time; beyond_paper: the largest hosts the single-network studies, all "
            "the capacity study)",
            used=_kinds("transmission", "relaxation", "solvers", "beyond_paper", "physical_time"),
        )
    )
    noise: Annotated[Float, _non_negative] | None = key(
        None,
        "position noise as a fraction of the spacing "
        "(default 0.1 for learning and stability, 0 otherwise)",
    )
    fraction: Annotated[Float, _open_unit] = key(
        0.2,
        "fraction of springs removed (diluted)",
        used=_when(lambda s: s.network.builder == "diluted", "by diluted networks"),
    )
    stiffness_ratios: Annotated[tuple[Float, ...], _each(_at_least(1.0))] = key(
        (), "stiffness ratios k_stiff / k_soft (stability)", used=_kinds("stability")
    )
    stiff_fraction: Annotated[Float, _open_unit] = key(
        0.2, "fraction of springs made stiff (stability)", used=_kinds("stability")
    )


@table
class TaskSpec:
    """``[task]``: what is clamped and what should respond.

    ``kind``: ``"paper"`` (one source, one target, Sec. 7.1), ``"stern"`` (``n_sources``
    sources and ``n_targets`` targets, Sec. 6.4) or ``"source"`` (one spring, the one nearest
    the centre, clamped at ``strain``; transmission, stability, solvers).
    """

    kind: Literal["paper", "stern", "source"] = key(doc="task kind")
    n_sources: Annotated[Int, _at_least(1)] = key(
        10, "source springs (stern)", used=_when(lambda s: s.task.kind == "stern", "by stern tasks")
    )
    n_targets: Annotated[Int, _at_least(1)] = key(
        3, "target springs (stern)", used=_when(lambda s: s.task.kind == "stern", "by stern tasks")
    )
    source_std: Annotated[Float, _positive] = key(
        0.1,
        "std of the source strains (stern)",
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    target_std: Annotated[Float, _positive] = key(
        0.1,
        "std of the desired target strains (stern)",
        used=_when(lambda s: s.task.kind == "stern", "by stern tasks"),
    )
    anchored: Bool = key(
        False,
        "train the task together with its rest example (sources at zero strain, targets "
        "at their untrained rest strains): cannot be met trivially (stern, learning)",
        used=_when(
            lambda s: s.task.kind == "stern" and s.kind == "learning",
            "by stern tasks in learning scenes",
        ),
    )
    node_outputs: Annotated[tuple[Literal["absolute", "relative"], ...], _unique_nonempty] = key(
        ("absolute", "relative"),
        "outputs of the node task, one run per entry and rule: node coordinates "
        "('absolute') or a node's coordinate relative to another node's ('relative')",
        used=_kinds("beyond_paper"),
    )
    strain: Annotated[Float, _strain] = key(
        0.1,
        "strain of the clamped source spring (source)",
        used=_when(lambda s: s.task.kind == "source", "by source tasks"),
    )
    strains: Annotated[tuple[Float, ...], _each(_strain)] = key(
        (), "extreme source strains (stability)", used=_kinds("stability")
    )


@table
class LearningSpec:
    """``[learning]``: the training runs (every rule x solver x noise level, ``trials`` each)."""

    rules: Annotated[tuple[Literal[RULES], ...], _unique_nonempty] = key(doc="learning runs")
    trials: Annotated[Int, _at_least(1)] = key(
        10, "independent trials (seeds seed, seed + 1, ...)", used=_kinds("learning")
    )
    steps: Annotated[Int, _at_least(1)] = key(300, "learning steps per trial")
    strain_reference: Literal["initial", "current"] = key(
        "initial",
        "strain convention of clamps and error: 'initial' (fixed target geometries) or "
        "'current' (the paper's literal S = r / L - 1 with the learning L)",
    )
    alpha_gcl: Annotated[Float, _positive] = key(1e-3, "GCL learning rate", used=_NOT_BEYOND)
    eta: Annotated[Float, _positive] = key(0.1, "GCL nudge amplitude")
    etas: Annotated[tuple[Float, ...], _each(_positive)] = key(
        (),
        "GCL nudge amplitudes, one GCL run per value (named <rule>_eta<value>); empty: eta "
        "(beyond_paper: the thermal study's nudges)",
        used=_when(
            lambda s: (
                s.kind == "beyond_paper"
                or (s.kind == "learning" and any(r.startswith("gcl") for r in s.learning.rules))
            ),
            "by learning scenes with a GCL rule and beyond_paper scenes",
        ),
    )
    alpha_gpc: Annotated[Float, _positive] = key(1e-3, "GPC learning rate", used=_NOT_BEYOND)
    alpha_exact: Annotated[Float, _positive] = key(
        1.0, "exact-gradient learning rate", used=_kinds("learning", "continuum_learning")
    )
    alpha_aging: Annotated[Float, _positive] = key(
        0.5,
        "directed-aging rate (aging, aging_k)",
        used=_when(
            lambda s: (
                s.kind != "beyond_paper" and any(r.startswith("aging") for r in s.learning.rules)
            ),
            "with rules aging or aging_k (beyond_paper uses the default rates)",
        ),
    )
    temperatures: Annotated[
        tuple[Float, ...], _unique_nonempty, _each(_non_negative), _increasing
    ] = key(
        (0.0, 1e-8, 1e-6),
        "temperatures k_B T of the thermal study (every state read as a harmonic Boltzmann "
        "draw), one GCL run per nudge of etas and one exact-gradient run per entry",
        used=_kinds("beyond_paper"),
    )
    compare_tasks: Annotated[tuple[Literal["paper", "lattice"], ...], _unique_nonempty] = key(
        ("paper", "lattice"),
        "beyond_paper: the tasks every rule is compared on ('paper': the paper's network "
        "and task; 'lattice': Rocks et al.'s allosteric task on the first lattice)",
        used=_kinds("beyond_paper"),
    )
    examples: Annotated[tuple[Int, ...], _unique_nonempty, _each(_at_least(1)), _increasing] = key(
        (1, 2, 4, 8),
        "numbers of examples trained together, one capacity run per entry and lattice size",
        used=_kinds("beyond_paper"),
    )
    capacity_seeds: Annotated[Int, _at_least(1)] = key(
        3,
        "draws of the examples per lattice size and number of examples (capacity study)",
        used=_kinds("beyond_paper"),
    )
    floor: Annotated[Float, _positive] = key(
        0.1,
        "rest-length floor of the *_floor, *_frozen, gpc and exact runs",
        used=_kinds("learning"),
    )
    noise: Annotated[tuple[Float, ...], _unique_nonempty, _each(_non_negative)] = key(
        (0.0,), "relative read-out noise levels (one run per level)", used=_kinds("learning")
    )
    measure: Bool = key(
        True,
        "solve the free state after every step to measure the "
        "error even when the rule does not need it (GPC), and measure the coupling of "
        "every trained network",
        used=_kinds("learning"),
    )
    sweeps: Bool = key(
        False, "source sweeps of the trained networks (Fig. 5)", used=_kinds("learning")
    )
    sweep_span: Annotated[Float, _positive] = key(
        5.0,
        "sweep source strains S +- span",
        used=_when(
            lambda s: s.kind == "learning" and s.learning.sweeps,
            "by learning scenes with sweeps = true",
        ),
    )
    sweep_points: Annotated[Int, _at_least(2)] = key(
        11,
        "points per sweep",
        used=_when(
            lambda s: s.kind == "learning" and s.learning.sweeps,
            "by learning scenes with sweeps = true",
        ),
    )
    compare_gradient: Bool = key(
        False,
        "cosine of each rule's step with the exact gradient, at the initial and final networks",
        used=_kinds("learning"),
    )
    checkpoint_every: Annotated[Int, _at_least(1)] = key(
        25, "steps between checkpoints", used=_kinds("learning")
    )
    paper_setting: Bool = key(
        False,
        "paper task: the runs of the author's notebooks, each rule in its own convention "
        "(GCL of both signs against the learning L, GPC against fixed rods, sources frozen; "
        "scenes.paper_setting)",
        used=_when(lambda s: s.task.kind == "paper", "by the paper task"),
    )
    steps_gpc: Annotated[Int, _non_negative] = key(
        0,
        "learning steps of the GPC runs (0: steps)",
        used=_when(lambda s: s.task.kind == "paper", "by the paper task"),
    )


@table
class SolverSpec:
    """``[solver]``: equilibrium methods and their budgets.

    Learning scenes accept ``"newton"`` (exact equilibria) and ``"paper"`` (the paper's
    Adagrad with rods, ``paper_iterations`` per state); stability and solver scenes compare
    every method listed.
    """

    methods: Annotated[tuple[Literal[SOLVER_METHODS], ...], _unique_nonempty] = key(
        ("newton",), "equilibrium methods", used=_kinds("learning", "stability", "solvers")
    )
    tol: Annotated[Float, _open_unit] = key(
        1e-10,
        "relative residual tolerance (net force on a free coordinate / its node's sum k L)",
        used=_kinds("transmission", "stability", "solvers"),
    )
    max_seconds: Annotated[Float, _positive] = key(
        60.0, "time budget of one solve (s)", used=_kinds("stability", "solvers")
    )
    paper_iterations: Annotated[Int, _at_least(1)] = key(
        300,
        "Adagrad iterations per state (learning with 'paper')",
        used=_when(
            lambda s: s.kind == "learning" and "paper" in s.solver.methods,
            "by learning scenes with method 'paper'",
        ),
    )
    rod_stiffnesses: Annotated[tuple[Float, ...], _each(_positive)] = key(
        (), "stiffness of the paper's clamp rods (stability)", used=_kinds("stability")
    )
    ramp: Annotated[Int, _at_least(1)] = key(
        4, "strain continuation steps (stability)", used=_kinds("stability")
    )
