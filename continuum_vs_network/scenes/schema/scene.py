"""The validated :class:`Scene`, parsing a scene dict, and the checks each kind makes."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .keys import (
    _REQUIRED,
    BEYOND_RULES,
    CONTINUUM_RULES,
    KIND_TABLES,
    KINDS,
    PAPER_RULES,
    PAPER_SETTING_RULES,
    RENAMED,
    RULES,
    STERN_RULES,
    _uses,
)
from .sweep import SweepSpec, parse_sweep
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
    ReportSpec,
    StabilitySpec,
)
from .values import SceneError, _convert, _short, _value

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]*")
_NAME_MAX = 100  # it names folders and files (file systems allow 255 bytes per name)
_SEED_MAX = 2**63 - 1  # seeds are stored as int64


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
    allostery, export : spec or None
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
    allostery: AllosterySpec | None = None
    mechanism: MechanismSpec | None = None
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
    from ..limits import check_resources

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
    if len(spec.draws) not in (1, len(net.sizes)):
        raise SceneError(
            file,
            "physical_time",
            "draws",
            f"must give one number for every size or one per size ({len(net.sizes)} sizes), "
            f"got {len(spec.draws)}",
        )
    if (spec.arm_stiffness > 0) != (spec.arm_dashpot > 0):
        raise SceneError(
            file,
            "physical_time",
            "arm_dashpot",
            "arm_stiffness and arm_dashpot must both be > 0 (a Maxwell arm) or both 0",
        )


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
    if kind == "allostery":
        a = scene.allostery
        if a is not None and a.alpha is not None and a.step is not None:
            raise SceneError(
                file, "allostery", "step", "a raw rate alpha has no step; set one of the two"
            )
        return
    if kind in ("accuracy", "continuum_mechanism"):
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
            allowed = PAPER_SETTING_RULES if scene.learning.paper_setting else RULES
            bad = [
                r
                for r in scene.learning.rules
                if r not in allowed or (r == "gcl_notebook" and not scene.learning.paper_setting)
            ]
            if bad and bad[0] not in STERN_RULES:
                raise SceneError(
                    file,
                    "learning",
                    "rules",
                    f"{bad[0]!r} is not a run of "
                    + (
                        "the paper's own setting (paper_setting = true runs "
                        + ", ".join(PAPER_SETTING_RULES)
                        + ")"
                        if scene.learning.paper_setting
                        else "the package's setting ('gcl_notebook' needs paper_setting = true)"
                    ),
                )
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
