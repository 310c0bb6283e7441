"""Scenes: TOML files that say what to build, compute, export and report.

* :mod:`.schema`: the file format, validated into frozen dataclasses
  (:func:`load_scene`, :class:`Scene`, :class:`SceneError`);
* :mod:`.runner`: :func:`run_scene` computes only what a scene names, in units
  (:mod:`.units`) that are checkpointed and resumed, optionally in parallel; :class:`SceneResult`;
  unit files are kept by :mod:`.store`, units computed by :mod:`.compute`;
* :mod:`.executor`: where parallel work runs (serial, a local Dask cluster, a running Dask
  scheduler);
* :mod:`.grid` and :mod:`.sweep`: a scene's ``[sweep]`` expanded into a grid of variants and
  run point by point into one tidy table (``cvn sweep``);
* :mod:`.meshes`: the meshes of a result (:func:`export_meshes`);
* :mod:`.replication`, :mod:`.paper_setting` and :mod:`.stern`: the learning studies the
  learning units compute (the paper's runs, the runs of the author's notebooks and what each
  draw of the paper's task allows, Stern-scale allostery);
* ``builtin/*.toml``: the built-in scenes (:func:`builtin_names`).

Importing this package needs only numpy and scipy (the scene models, pydantic, load with
the first scene read); Dask and pandas are imported only by
parallel runs and sweeps.
"""

from __future__ import annotations

from .compute import SceneRunError
from .runner import SceneResult, load_result, run_scene
from .schema import SceneError, builtin_names, builtin_path, load_scene


def __getattr__(name: str):
    if name in ("Scene", "parse_scene"):  # the models: pydantic, imported when first used
        from . import schema

        return getattr(schema, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "Scene",
    "SceneError",
    "SceneResult",
    "SceneRunError",
    "builtin_names",
    "builtin_path",
    "load_result",
    "load_scene",
    "parse_scene",
    "run_scene",
]
