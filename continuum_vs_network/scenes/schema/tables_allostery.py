"""Scene table ``[allostery]``: the allostery study (kind ``allostery``), every key declared
with :func:`.keys._key`.

A draw ``i`` (``0 <= i < draws``) builds one jammed network and one allosteric task from
``numpy.random.default_rng([seed, i])``; every rule of the draw trains that network on that
task. The desired response ratio alternates in sign over the draws (``+ratio``, ``-ratio``).
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
    _non_negative,
    _positive,
    _unique_nonempty,
)

#: The rules an allostery scene compares: the package's default rule objects (nothing tuned).
ALLOSTERY_RULES = ("gcl", "exact", "gpc", "aging")
#: The tasks: Rocks et al. 2017 (one source, one target) and Stern et al. 2021 (10 -> 3).
ALLOSTERY_TASKS = ("1to1", "10to3")
#: The learning degrees of freedom.
ALLOSTERY_DOFS = ("stiffness", "rest_length", "both")


def _signed_ratio(v: float) -> str | None:
    return None if v != 0 else "must be non-zero"


@dataclass(frozen=True)
class AllosterySpec:
    """``[allostery]``: jammed networks, allosteric tasks, rules, draws and the feasibility map."""

    n_nodes: tuple[int, ...] = _key(
        "list[int]",
        (512,),
        "discs of the jammed packings, one study per entry (the network keeps 85-95 %)",
        check=_all(_unique_nonempty, _each(_at_least(16)), _increasing),
    )
    phi: float = _key(
        "float",
        0.86,
        "disc area fraction of the packings (jamming near 0.84)",
        check=_between(0.5, 0.95),
    )
    dz: float | None = _key(
        "float",
        None,
        "prune the network to coordination Z_iso + dz (None: the packing's own contacts)",
        check=_positive,
    )
    tasks: tuple[str, ...] = _key(
        "list[str]",
        ("1to1",),
        "allosteric tasks: '1to1' (Rocks 2017, one source, one target) and '10to3' "
        "(Stern 2021, 10 sources, 3 targets)",
        choices=ALLOSTERY_TASKS,
        check=_unique_nonempty,
    )
    dofs: tuple[str, ...] = _key(
        "list[str]",
        ("stiffness",),
        "learning degrees of freedom, one study per entry",
        choices=ALLOSTERY_DOFS,
        check=_unique_nonempty,
    )
    rules: tuple[str, ...] = _key(
        "list[str]",
        ALLOSTERY_RULES,
        "rules (default rule objects): GCL, the exact gradient, GPC, directed aging",
        choices=ALLOSTERY_RULES,
        check=_unique_nonempty,
    )
    draws: int = _key("int", 10, "network and task draws per (size, task, dof)", check=_at_least(1))
    steps: int = _key("int", 1000, "learning steps of gcl and exact", check=_at_least(1))
    clamped_steps: int | None = _key(
        "int",
        None,
        "learning steps of the clamped-only rules gpc and aging (None: steps)",
        check=_at_least(1),
    )
    etas: tuple[float, ...] = _key(
        "list[float]",
        (),
        "GCL nudge amplitudes, one GCL run per value (empty: the rule's default)",
        check=_all(_each(_positive), _increasing),
    )
    noise: tuple[float, ...] = _key(
        "list[float]",
        (0.0,),
        "relative read-out noise levels of the lengths a rule reads, one run per rule and level",
        check=_all(_unique_nonempty, _each(_non_negative), _increasing),
    )
    step: float | None = _key(
        "float",
        None,
        "step of every rule's default rate (adaptive or scaled; None: the rule's own step)",
        check=_between(1e-6, 100.0),
    )
    alpha: float | None = _key(
        "float",
        None,
        "the paper's raw learning rate of GCL and the exact gradient (None: their default "
        "adaptive rate; GPC and aging keep their scaled rate)",
        check=_positive,
    )
    optimum: bool = _key(
        "bool",
        True,
        "compute every draw's bounded optimum (what the task allows; feasibility)",
    )
    ratio: float = _key(
        "float",
        0.3,
        "allosteric response ratio S_T / S_S; its sign alternates over the draws",
        check=_signed_ratio,
    )
    source_strain: float = _key(
        "float", 0.05, "strain of each source spring", check=_between(1e-6, 0.5)
    )
    distance: float = _key(
        "float",
        0.25,
        "source-target distance (box sizes) of the trained draws",
        check=_between(0.0, 1.0),
    )
    map_distances: tuple[float, ...] = _key(
        "list[float]",
        (0.1, 0.25, 0.4),
        "source-target distances (box sizes) of the feasibility map (optimum only)",
        check=_all(_each(_between(0.0, 1.0)), _increasing),
    )
    map_ratios: tuple[float, ...] = _key(
        "list[float]",
        (0.3, 1.0),
        "response ratios |S_T / S_S| of the feasibility map (sign alternates over draws)",
        check=_all(_each(_positive), _increasing),
    )
    map_draws: int = _key(
        "int", 4, "draws per point of the feasibility map (0: no map)", check=_non_negative
    )
