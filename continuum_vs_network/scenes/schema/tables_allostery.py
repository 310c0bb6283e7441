"""Scene table ``[allostery]``: the allostery study (kind ``allostery``), every key declared
with :func:`.keys._key`.

A draw ``i`` (``0 <= i < draws``) builds one jammed network and one allosteric task from
``numpy.random.default_rng([seed, i])``; every rule of the draw trains that network on that
task. The desired response ratio alternates in sign over the draws (``+ratio``, ``-ratio``).
"""

from typing import Annotated, Literal

from .keys import (
    Bool,
    Float,
    Int,
    _at_least,
    _between,
    _check,
    _each,
    _increasing,
    _non_negative,
    _positive,
    _unique_nonempty,
    key,
    table,
)

#: The rules an allostery scene compares: the package's default rule objects (nothing tuned).
ALLOSTERY_RULES = ("gcl", "exact", "gpc", "aging")
#: The tasks: Rocks et al. 2017 (one source, one target) and Stern et al. 2021 (10 -> 3).
ALLOSTERY_TASKS = ("1to1", "10to3")
#: The learning degrees of freedom.
ALLOSTERY_DOFS = ("stiffness", "rest_length", "both")


_signed_ratio = _check(lambda v: None if v != 0 else "must be non-zero")


@table
class AllosterySpec:
    """``[allostery]``: jammed networks, allosteric tasks, rules, draws and the feasibility map."""

    n_nodes: Annotated[tuple[Int, ...], _unique_nonempty, _each(_at_least(16)), _increasing] = key(
        (512,), "discs of the jammed packings, one study per entry (the network keeps 85-95 %)"
    )
    phi: Annotated[Float, _between(0.5, 0.95)] = key(
        0.86, "disc area fraction of the packings (jamming near 0.84)"
    )
    dz: Annotated[Float, _positive] | None = key(
        None, "prune the network to coordination Z_iso + dz (None: the packing's own contacts)"
    )
    tasks: Annotated[tuple[Literal[ALLOSTERY_TASKS], ...], _unique_nonempty] = key(
        ("1to1",),
        "allosteric tasks: '1to1' (Rocks 2017, one source, one target) and '10to3' "
        "(Stern 2021, 10 sources, 3 targets)",
    )
    dofs: Annotated[tuple[Literal[ALLOSTERY_DOFS], ...], _unique_nonempty] = key(
        ("stiffness",), "learning degrees of freedom, one study per entry"
    )
    rules: Annotated[tuple[Literal[ALLOSTERY_RULES], ...], _unique_nonempty] = key(
        ALLOSTERY_RULES,
        "rules (default rule objects): GCL, the exact gradient, GPC, directed aging",
    )
    draws: Annotated[Int, _at_least(1)] = key(10, "network and task draws per (size, task, dof)")
    steps: Annotated[Int, _at_least(1)] = key(1000, "learning steps of gcl and exact")
    clamped_steps: Annotated[Int, _at_least(1)] | None = key(
        None, "learning steps of the clamped-only rules gpc and aging (None: steps)"
    )
    etas: Annotated[tuple[Float, ...], _each(_positive), _increasing] = key(
        (), "GCL nudge amplitudes, one GCL run per value (empty: the rule's default)"
    )
    noise: Annotated[tuple[Float, ...], _unique_nonempty, _each(_non_negative), _increasing] = key(
        (0.0,),
        "relative read-out noise levels of the lengths a rule reads, one run per rule and level",
    )
    step: Annotated[Float, _between(1e-6, 100.0)] | None = key(
        None, "step of every rule's default rate (adaptive or scaled; None: the rule's own step)"
    )
    alpha: Annotated[Float, _positive] | None = key(
        None,
        "the paper's raw learning rate of GCL and the exact gradient (None: their default "
        "adaptive rate; GPC and aging keep their scaled rate)",
    )
    optimum: Bool = key(
        True, "compute every draw's bounded optimum (what the task allows; feasibility)"
    )
    ratio: Annotated[Float, _signed_ratio] = key(
        0.3, "allosteric response ratio S_T / S_S; its sign alternates over the draws"
    )
    source_strain: Annotated[Float, _between(1e-6, 0.5)] = key(0.05, "strain of each source spring")
    distance: Annotated[Float, _between(0.0, 1.0)] = key(
        0.25, "source-target distance (box sizes) of the trained draws"
    )
    map_distances: Annotated[tuple[Float, ...], _each(_between(0.0, 1.0)), _increasing] = key(
        (0.1, 0.25, 0.4),
        "source-target distances (box sizes) of the feasibility map (optimum only)",
    )
    map_ratios: Annotated[tuple[Float, ...], _each(_positive), _increasing] = key(
        (0.3, 1.0),
        "response ratios |S_T / S_S| of the feasibility map (sign alternates over draws)",
    )
    map_draws: Annotated[Int, _non_negative] = key(
        4, "draws per point of the feasibility map (0: no map)"
    )
