"""The validated :class:`Scene`: what every kind's model (:mod:`.kinds`) shares."""

import copy
import dataclasses
from dataclasses import field
from typing import Annotated, Any

from pydantic import AfterValidator, InstanceOf
from pydantic.dataclasses import dataclass

from .errors import _NAME, _NAME_MAX
from .keys import CONFIG, Int, Str, _check, _uses
from .sweep import SweepSpec
from .tables import _TABLES
from .tables_physics import ExportSpec, ReportSpec
from .values import _short

_SEED_MAX = 2**63 - 1  # seeds are stored as int64


def _plain_name(name: str) -> str | None:
    if _NAME.fullmatch(name) and len(name) <= _NAME_MAX:
        return None
    return (
        f"must be a plain name of at most {_NAME_MAX} characters (letters, digits, '_', "
        f"'-', '.'; starting with a letter or digit), got {_short(repr(name))}"
    )


def _one_line(text: str) -> str:
    text = text.strip()
    if not text or "\n" in text:
        raise ValueError("must be one non-empty line")
    return text


def _seed(seed: int) -> str | None:
    return None if 0 <= seed <= _SEED_MAX else f"must be in 0..2**63-1, got {_short(seed)}"


@dataclass(frozen=True, config=CONFIG, kw_only=True)
class Scene:
    """A validated scene: the fields every kind shares; a kind's model (:mod:`.kinds`)
    declares the tables it needs and accepts (a table it does not take stays None).

    Attributes
    ----------
    name, description : str
    seed : int
    kind : str
        One of :data:`KINDS`.
    network, task, learning, solver, continuum, dynamics, stability, accuracy, physical_time,
    allostery, mechanism, export : spec or None
        The tables given (None when absent).
    report : ReportSpec
        Always present (defaults when the table is absent).
    sweep : SweepSpec or None
        The ``[sweep]`` table: the scene is a grid of variants (see :mod:`.grid`).
    source : str
        The file the scene was read from.
    """

    name: Annotated[Str, _check(_plain_name)]
    description: Annotated[Str, AfterValidator(_one_line)]
    seed: Annotated[Int, _check(_seed)] = 0
    kind: Str
    network: None = None
    task: None = None
    learning: None = None
    solver: None = None
    continuum: None = None
    dynamics: None = None
    stability: None = None
    accuracy: None = None
    physical_time: None = None
    allostery: None = None
    mechanism: None = None
    export: None = None
    report: ReportSpec = field(default_factory=ReportSpec)
    sweep: InstanceOf[SweepSpec] | None = None
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

    def with_export(self, export: ExportSpec | None = None) -> "Scene":
        """The same scene with an ``[export]`` table (defaults when None), whether or not
        its kind's files may name one (``cvn export`` exports every kind)."""
        out = copy.copy(self)
        object.__setattr__(out, "export", export or ExportSpec())
        return out
