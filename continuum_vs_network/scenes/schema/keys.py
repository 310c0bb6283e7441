"""Scene vocabulary (kinds, rules) and how a table declares its keys.

A table is a frozen pydantic dataclass (:func:`table`); a key is a field whose annotation
is its type and its value checks (``Annotated[Int, _at_least(1)]``, ``Literal[...]`` for
choices, ``tuple[...]`` for TOML lists) and whose default is :func:`key` (default, the
meaning ``cvn scenes --keys`` prints, and where the key is used).
"""

from __future__ import annotations

import dataclasses
import itertools
import types
from collections.abc import Callable
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import AfterValidator, BeforeValidator, ConfigDict, Strict
from pydantic.dataclasses import dataclass as _pydantic_dataclass
from pydantic_core import PydanticCustomError

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

_REQUIRED = dataclasses.MISSING

#: TOML's scalar types; a TOML list is a ``tuple[...]`` of them (a list is read as a tuple).
#: A bool is not an int and a string is never a number (nothing is coerced), an int is a
#: float.
Int = Annotated[int, Strict()]
Float = Annotated[float, Strict()]
Bool = Annotated[bool, Strict()]
Str = Annotated[str, Strict()]


def _not_bool(value: Any) -> Any:
    if isinstance(value, bool):  # True == 1: a Literal of ints alone would take it
        raise PydanticCustomError("int_type", "Input should be a valid integer")
    return value


#: Integer choices: ``Annotated[Literal[1, 2], NOT_BOOL]``.
NOT_BOOL = BeforeValidator(_not_bool)

#: One config for every table and scene: unknown keys are errors, numbers are finite.
CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False)


def table(cls: type) -> type:
    """A scene table: a frozen, validating dataclass (``dataclasses.replace`` validates)."""
    return _pydantic_dataclass(frozen=True, config=CONFIG)(cls)


# -- key declarations ----------------------------------------------------------------------
def key(
    default: Any = _REQUIRED,
    doc: str = "",
    *,
    used: tuple[Callable[[Any], bool], str] | None = None,
) -> Any:
    """A scene key's default (none: required), meaning and where it is used.

    ``used``: ``(predicate, where)`` when the key matters only in some scenes: a key given
    in a scene where ``predicate(scene)`` is false is an error naming ``where`` it is used,
    and :meth:`Scene.to_dict` (the settings a report prints) leaves it out. None: used
    wherever its table is.
    """
    meta = {"doc": doc, "used": used}
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class _Check(AfterValidator):
    """A value check: ``message(value)`` is None when the value is fine, else the problem."""

    message: Callable[[Any], str | None] = lambda v: None


def _check(message: Callable[[Any], str | None]) -> _Check:
    def run(value: Any) -> Any:
        msg = message(value)
        if msg:
            raise ValueError(msg)
        return value

    return _Check(run, message)


_positive = _check(lambda v: None if v > 0 else "must be > 0")
_non_negative = _check(lambda v: None if v >= 0 else "must be >= 0")
_open_unit = _check(lambda v: None if 0 < v < 1 else "must lie strictly between 0 and 1")
_strain = _check(
    lambda v: None if v > -1 else "a strain must be > -1 (a spring cannot have negative length)"
)
_nonempty = _check(lambda v: None if v else "must list at least one entry")


def _at_least(n: float) -> _Check:
    return _check(lambda v: None if v >= n else f"must be >= {n}")


def _between(lo: float, hi: float) -> _Check:
    return _check(lambda v: None if lo <= v <= hi else f"must lie in [{lo}, {hi}]")


def _each(check: _Check) -> _Check:
    """``check`` on every entry of a list; the problem names the first entry that fails."""
    inner = check.message

    def run(values: tuple) -> str | None:
        for i, v in enumerate(values):
            msg = inner(v)
            if msg:
                return f"entry {i} ({v!r}) {msg}"
        return None

    return _check(run)


def _unique(values: tuple) -> str | None:
    if not values:
        return "must list at least one entry"
    if len(set(values)) != len(values):
        return "must not repeat entries"
    return None


_unique_nonempty = _check(_unique)
_increasing = _check(
    lambda values: (
        "must be strictly increasing"
        if any(b <= a for a, b in itertools.pairwise(values))
        else None
    )
)


# -- where a key is used ---------------------------------------------------------------------
def _kinds(*kinds: str) -> tuple[Callable[[Any], bool], str]:
    names = kinds[0] if len(kinds) == 1 else ", ".join(kinds[:-1]) + " and " + kinds[-1]
    return (lambda scene: scene.kind in kinds), f"used by {names} scenes"


def _when(pred: Callable[[Any], bool], where: str) -> tuple[Callable[[Any], bool], str]:
    return pred, f"used {where}"


def _uses(scene: Any, table: str, key: str) -> bool:
    """Whether ``scene`` uses ``[table] key`` (see ``key(used=...)``)."""
    spec = getattr(scene, table)
    if spec is None:
        return False
    used = {f.name: f for f in dataclasses.fields(spec)}[key].metadata["used"]
    return used is None or bool(used[0](scene))


_TOML = {int: "int", float: "float", bool: "bool", str: "str"}


def toml_type(annotation: Any) -> tuple[str, tuple | None]:
    """A key's TOML type (``int``, ``list[float]``, ...) and its choices (None: any)."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return toml_type(args[0])
    if origin in (Union, types.UnionType):
        return toml_type(next(a for a in args if a is not type(None)))
    if origin is Literal:
        return _TOML[type(args[0])], args
    if origin is tuple:
        inner, choices = toml_type(args[0])
        return f"list[{inner}]", choices
    return _TOML[annotation], None
