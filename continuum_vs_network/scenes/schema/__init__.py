"""Scene files: TOML validated into frozen dataclasses.

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
:data:`KIND_TABLES`; a table a kind does not use is an error (a scene never carries settings
that are silently ignored). Every key of every table is
listed, with its type, default and meaning, in the table dataclasses (``cvn scenes --keys``
prints them).

Unknown keys, wrong types and impossible values raise :class:`SceneError`, a ``ValueError``
whose message and attributes name the file, the table and the key.

Modules: :mod:`.keys` (vocabulary and key declarations), :mod:`.values` (:class:`SceneError`,
value conversion), :mod:`.tables_learning`, :mod:`.tables_physics` and :mod:`.tables_allostery` (one
dataclass per table), :mod:`.tables` (tables by name), :mod:`.sweep` (``[sweep]``), :mod:`.scene`
(:class:`Scene`, parsing, per-kind checks), :mod:`.builtin` (files, built-in scenes, key
reference).
"""

from __future__ import annotations

from .builtin import builtin_names, builtin_path, key_reference, load_scene
from .keys import (
    BEYOND_RULES,
    CONTINUUM_RULES,
    KIND_TABLES,
    KINDS,
    PAPER_RULES,
    RENAMED,
    RULES,
    SOLVER_METHODS,
    STERN_RULES,
)
from .scene import Scene, parse_scene
from .sweep import SweepSpec, check_zip, parse_sweep, sweep_values
from .tables import _TABLES as _TABLES
from .tables_allostery import ALLOSTERY_RULES, AllosterySpec
from .tables_learning import LearningSpec, NetworkSpec, SolverSpec, TaskSpec
from .tables_mechanism import MechanismSpec
from .tables_physics import (
    TIME_RULES,
    AccuracySpec,
    ContinuumSpec,
    DynamicsSpec,
    ExportSpec,
    PhysicalTimeSpec,
    ReportSpec,
    StabilitySpec,
)
from .values import SceneError

__all__ = [
    "ALLOSTERY_RULES",
    "BEYOND_RULES",
    "CONTINUUM_RULES",
    "KINDS",
    "KIND_TABLES",
    "PAPER_RULES",
    "RENAMED",
    "RULES",
    "SOLVER_METHODS",
    "STERN_RULES",
    "TIME_RULES",
    "AccuracySpec",
    "AllosterySpec",
    "ContinuumSpec",
    "DynamicsSpec",
    "ExportSpec",
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
