"""Scene files: TOML validated into frozen (pydantic) dataclasses, one model per kind.

A scene is data only (no code is executed from it). Top-level keys::

    name = "paper"            # plain name: letters, digits, '_', '-', '.'; names the folders
    description = "one line"  # shown by ``cvn scenes`` and in the report
    seed = 0                  # first seed; trial i uses seed + i
    kind = "learning"         # learning | transmission | relaxation | stability | solvers
                              # | accuracy | continuum_learning | beyond_paper
                              # | physical_time | allostery

and the optional tables ``[network]``, ``[task]``, ``[learning]``, ``[solver]``,
``[continuum]``, ``[dynamics]``, ``[stability]``, ``[accuracy]``, ``[physical_time]``,
``[allostery]``, ``[export]``, ``[report]``, and ``[sweep]`` (the scene as a grid of variants,
:class:`SweepSpec`). Which tables a kind needs and which it accepts is in
its model (:mod:`.kinds`, summed up in :data:`KIND_TABLES`); a table a kind does not use is
an error (a scene never carries settings that are silently ignored). Every key of every
table is listed, with its type, default and meaning, in the table dataclasses (``cvn scenes
--keys`` prints them). :data:`KINDS` is the registry of kinds: each one's model, checks,
planner, report section and memory estimate (:class:`Kind`).

Unknown keys, wrong types and impossible values raise :class:`SceneError`, a ``ValueError``
whose message and attributes name the file, the table and the key.

Modules: :mod:`.keys` (vocabulary, key types and checks), :mod:`.values` (:class:`SceneError`,
validation errors said as scene errors), :mod:`.tables_learning`, :mod:`.tables_physics`,
:mod:`.tables_allostery` and :mod:`.tables_mechanism` (one dataclass per table), :mod:`.tables`
(tables by name), :mod:`.sweep` (``[sweep]``), :mod:`.scene` (:class:`Scene`, parsing),
:mod:`.kinds` (one model per kind, the registry), :mod:`.checks` (each kind's checks),
:mod:`.builtin` (files, built-in scenes, key reference).
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

from .builtin import builtin_names, builtin_path, key_reference, load_scene
from .errors import SceneError

# everything else is imported when first used: the models need pydantic, which importing
# the package (``import continuum_vs_network``) must not
_LAZY = {
    **dict.fromkeys(
        ("BEYOND_RULES", "CONTINUUM_RULES", "PAPER_RULES", "RENAMED", "RULES", "SOLVER_METHODS",
         "STERN_RULES"), ".keys"),
    **dict.fromkeys(("KINDS", "KIND_TABLES", "SCENES", "Kind"), ".kinds"),
    "Scene": ".scene",
    "parse_scene": ".parse",
    **dict.fromkeys(("SweepSpec", "check_zip", "parse_sweep", "sweep_values"), ".sweep"),
    "_TABLES": ".tables",
    **dict.fromkeys(("ALLOSTERY_RULES", "AllosterySpec"), ".tables_allostery"),
    **dict.fromkeys(("LearningSpec", "NetworkSpec", "SolverSpec", "TaskSpec"), ".tables_learning"),
    "MechanismSpec": ".tables_mechanism",
    **dict.fromkeys(
        ("TIME_RULES", "AccuracySpec", "ContinuumSpec", "DynamicsSpec", "ExportSpec",
         "PhysicalTimeSpec", "ReportSpec", "StabilitySpec"), ".tables_physics"),
}  # fmt: skip


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value


__all__ = [
    "ALLOSTERY_RULES",
    "BEYOND_RULES",
    "CONTINUUM_RULES",
    "KINDS",
    "KIND_TABLES",
    "PAPER_RULES",
    "RENAMED",
    "RULES",
    "SCENES",
    "SOLVER_METHODS",
    "STERN_RULES",
    "TIME_RULES",
    "AccuracySpec",
    "AllosterySpec",
    "ContinuumSpec",
    "DynamicsSpec",
    "ExportSpec",
    "Kind",
    "LearningSpec",
    "MechanismSpec",
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
    "check_zip",
    "key_reference",
    "load_scene",
    "parse_scene",
    "parse_sweep",
    "sweep_values",
]
