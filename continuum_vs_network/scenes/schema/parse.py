"""Parsing a scene dict: its kind's model validates it (pydantic's errors said as scene
errors), then the kind's checks, the keys it uses and the memory it needs."""

import dataclasses
from collections.abc import Mapping
from typing import Any

import pydantic

from .keys import RENAMED
from .kinds import KINDS, SCENES
from .scene import _SEED_MAX, Scene
from .sweep import parse_sweep
from .tables import _TABLES
from .values import SceneError, table_error, value_problem

_TOP = ("name", "description", "seed", "kind")


def _scene_error(err: Mapping[str, Any], data: Mapping[str, Any], file: str) -> SceneError:
    """The scene error of one pydantic error of the scene union (see :func:`parse_scene`)."""
    kind, loc = data.get("kind"), err["loc"]
    if err["type"] == "union_tag_not_found":
        return SceneError(file, "(top level)", "kind", "is required")
    if err["type"] == "union_tag_invalid":
        return SceneError(
            file, "(top level)", "kind", f"{kind!r} is not one of {', '.join(map(repr, KINDS))}"
        )
    loc = loc[1:]  # the tag
    top = str(loc[0])
    if top in _TABLES:
        if len(loc) == 1 and err["type"] in ("missing", "missing_argument"):
            return SceneError(file, top, "", f"kind {kind!r} needs a [{top}] table")
        if len(loc) == 1 and err["type"] == "none_required":
            return SceneError(
                file, top, "", f"kind {kind!r} does not use a [{top}] table; remove it"
            )
        sub = {**err, "loc": loc[1:]}
        return table_error(sub, _TABLES[top], data[top], file, top)
    if top not in _TOP:
        known = sorted([*_TOP, *_TABLES, "sweep"])
        return SceneError(
            file, "(top level)", top, f"unknown key or table; a scene has {', '.join(known)}"
        )
    annotation = {f.name: f.type for f in dataclasses.fields(Scene)}[top]
    index, problem = value_problem(err, annotation, data.get(top), got=False)
    return SceneError(file, "(top level)", top + index, problem)


def parse_scene(data: Mapping[str, Any], file: str = "<scene>") -> Scene:
    """Validate a scene given as a dict (as ``tomllib`` returns it).

    Raises
    ------
    SceneError
        Naming ``file``, the table and the key.
    """
    given: dict[str, Any] = dict(data)
    for table, values in data.items():
        if table in _TABLES or table == "sweep":
            if not isinstance(values, Mapping):
                got = type(values).__name__
                raise SceneError(
                    file, "(top level)", table, f"must be a table [{table}], got {got}"
                )
        for key in values if table in _TABLES else ():
            if (table, key) in RENAMED:
                raise SceneError(file, table, key, f"renamed; use {RENAMED[table, key]} = ...")
    if "sweep" in data:
        given["sweep"] = parse_sweep(data["sweep"], file)
    try:
        scene = SCENES.validate_python({**given, "source": str(file)})
    except pydantic.ValidationError as exc:
        order = {k: i for i, k in enumerate(data)}
        errors = sorted(
            exc.errors(), key=lambda e: order.get(e["loc"][1] if len(e["loc"]) > 1 else "", 1e9)
        )
        raise _scene_error(errors[0], data, str(file)) from None
    KINDS[scene.kind].check(scene, str(file))
    _check_used(scene, data, str(file))
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


def _check_used(scene: Scene, data: Mapping[str, Any], file: str) -> None:
    """Every key given must be one the scene uses (tables: the kind's model)."""
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
