"""Scene vocabulary (kinds, tables per kind, rules) and how a table declares its keys:
``_key`` and the small value checks and where-used predicates its options take.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable
from dataclasses import field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .scene import Scene


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
    "allostery",
    "continuum_mechanism",
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
    "allostery": (frozenset({"allostery"}), frozenset({"report"})),
    "continuum_mechanism": (frozenset({"mechanism"}), frozenset({"export", "report"})),
}

#: Learning runs a scene can name. Paper task: the paper's experiments (see
#: :func:`continuum_vs_network.scenes.replication.paper_experiments`; ``gcl``, ``gpc`` and
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
    "gcl_notebook",
)
#: Rules only the paper task knows, and only Stern-scale tasks know.
PAPER_RULES = ("gcl_floor", "gcl_frozen", "gpc_frozen", "gcl_notebook")
#: The runs of the paper's own setting (``[learning] paper_setting``): the author's notebooks
PAPER_SETTING_RULES = ("gcl", "gcl_notebook", "gpc", "gpc_frozen", "exact")
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

_REQUIRED = object()


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
