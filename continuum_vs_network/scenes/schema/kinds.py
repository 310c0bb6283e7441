"""One model per scene kind (the tables it needs and accepts), the union of them keyed on
``kind``, and the registry :data:`KINDS`: each kind's model, checks, planner, report
section and memory estimate.

A table a kind's model does not name stays ``None``: a file that gives it is an error. A
needed table is a field without a default, an accepted one defaults to None. The planner,
section and estimate are named ``"module:function"`` and imported when first used, so
loading a scene imports neither the units nor the report.
"""

import dataclasses
import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal, Union

from pydantic import Field, TypeAdapter
from pydantic.dataclasses import dataclass as model

from . import checks
from .keys import CONFIG
from .scene import Scene
from .tables import _TABLES
from .tables_allostery import AllosterySpec
from .tables_learning import LearningSpec, NetworkSpec, SolverSpec, TaskSpec
from .tables_mechanism import MechanismSpec
from .tables_physics import (
    AccuracySpec,
    ContinuumSpec,
    DynamicsSpec,
    ExportSpec,
    PhysicalTimeSpec,
    StabilitySpec,
)

_kind = model(frozen=True, config=CONFIG, kw_only=True)


def _needed() -> Any:
    """A needed table: a field without a default (the base's None is not inherited)."""
    return field()


@_kind
class LearningScene(Scene):
    kind: Literal["learning"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    learning: LearningSpec = _needed()
    solver: SolverSpec | None = None
    export: ExportSpec | None = None


@_kind
class TransmissionScene(Scene):
    kind: Literal["transmission"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    continuum: ContinuumSpec | None = None
    solver: SolverSpec | None = None
    export: ExportSpec | None = None


@_kind
class RelaxationScene(Scene):
    kind: Literal["relaxation"]
    network: NetworkSpec = _needed()
    dynamics: DynamicsSpec = _needed()
    continuum: ContinuumSpec | None = None
    export: ExportSpec | None = None


@_kind
class StabilityScene(Scene):
    kind: Literal["stability"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    solver: SolverSpec = _needed()
    stability: StabilitySpec | None = None


@_kind
class SolversScene(Scene):
    kind: Literal["solvers"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    solver: SolverSpec = _needed()


@_kind
class AccuracyScene(Scene):
    kind: Literal["accuracy"]
    accuracy: AccuracySpec = _needed()


@_kind
class PhysicalTimeScene(Scene):
    kind: Literal["physical_time"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    physical_time: PhysicalTimeSpec = _needed()
    export: ExportSpec | None = None


@_kind
class ContinuumLearningScene(Scene):
    kind: Literal["continuum_learning"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    learning: LearningSpec = _needed()
    continuum: ContinuumSpec = _needed()
    export: ExportSpec | None = None


@_kind
class BeyondPaperScene(Scene):
    kind: Literal["beyond_paper"]
    network: NetworkSpec = _needed()
    task: TaskSpec = _needed()
    learning: LearningSpec = _needed()


@_kind
class AllosteryScene(Scene):
    kind: Literal["allostery"]
    allostery: AllosterySpec = _needed()


@_kind
class MechanismScene(Scene):
    kind: Literal["continuum_mechanism"]
    mechanism: MechanismSpec = _needed()
    export: ExportSpec | None = None


def _lazy(ref: str) -> Callable[..., Any]:
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module, __package__), name)


@dataclass(frozen=True)
class Kind:
    """A scene kind.

    Attributes
    ----------
    name : str
    schema : type
        Its model (a :class:`Scene`).
    check : callable
        ``check(scene, file)``: what its model's types cannot say (the combinations of
        keys it takes); raises :class:`SceneError`.
    plan, section, limits : str
        ``"module:function"`` of its planner ``plan(scene) -> list[Unit]``, its report
        section ``section(doc, result)`` and its memory estimate ``limits(scene, est)``
        (empty: none); called through :meth:`plan`, :meth:`section` and :meth:`estimate`.
    """

    name: str
    schema: type
    check: Callable[[Any, str], None]
    plan_ref: str
    section_ref: str
    limits_ref: str = ""

    def plan(self, scene: Any) -> list:
        return _lazy(self.plan_ref)(scene)

    def section(self, doc: Any, result: Any) -> None:
        _lazy(self.section_ref)(doc, result)

    def estimate(self, scene: Any, est: Any) -> None:
        if self.limits_ref:
            _lazy(self.limits_ref)(scene, est)

    def tables(self) -> tuple[frozenset[str], frozenset[str]]:
        """(tables it needs, tables it also accepts), ``report`` aside."""
        need, accept = set(), set()
        for f in dataclasses.fields(self.schema):
            if f.name in _TABLES and f.name != "report" and f.type not in (None, type(None)):
                if f.default is dataclasses.MISSING:
                    need.add(f.name)
                else:
                    accept.add(f.name)
        return frozenset(need), frozenset(accept | {"report"})


_S = "continuum_vs_network.report.sections."
_U = "..units_"
_L = "..limits:"
KINDS: dict[str, Kind] = {
    k.name: k
    for k in (
        Kind("learning", LearningScene, checks.learning, _U + "learning:plan_learning",
             _S + "learning:section", _L + "learning"),
        Kind("transmission", TransmissionScene, checks.lattice, _U + "physics:plan_physics",
             _S + "transmission:section", _L + "lattice"),
        Kind("relaxation", RelaxationScene, checks.relaxation, _U + "physics:plan_physics",
             _S + "relaxation:section", _L + "lattice"),
        Kind("stability", StabilityScene, checks.stability, _U + "stability:plan_stability",
             _S + "stability:section", _L + "lattice"),
        Kind("solvers", SolversScene, checks.lattice, _U + "solvers:plan_solvers",
             _S + "solvers:section", _L + "lattice"),
        Kind("accuracy", AccuracyScene, checks.nothing, _U + "accuracy:plan_accuracy",
             _S + "accuracy:section", _L + "accuracy"),
        Kind("physical_time", PhysicalTimeScene, checks.physical_time,
             _U + "time:plan_time", _S + "physical_time:section"),
        Kind("continuum_learning", ContinuumLearningScene, checks.continuum_learning,
             _U + "continuum_learning:plan_continuum_learning",
             _S + "continuum_learning:section", _L + "continuum_learning"),
        Kind("beyond_paper", BeyondPaperScene, checks.beyond_paper,
             _U + "beyond:plan_beyond_paper", _S + "beyond_paper:section",
             _L + "beyond_paper"),
        Kind("allostery", AllosteryScene, checks.allostery, _U + "allostery:plan_allostery",
             _S + "allostery:section"),
        Kind("continuum_mechanism", MechanismScene, checks.nothing,
             _U + "mechanism:plan_mechanism", _S + "continuum_mechanism:section"),
    )
}  # fmt: skip

#: Every kind's model, chosen by ``kind``.
SCENES: TypeAdapter = TypeAdapter(
    Annotated[Union[tuple(k.schema for k in KINDS.values())], Field(discriminator="kind")]  # noqa: UP007
)

#: For each kind: (tables it needs, tables it also accepts).
KIND_TABLES: dict[str, tuple[frozenset[str], frozenset[str]]] = {
    name: k.tables() for name, k in KINDS.items()
}
