"""Sweeps: a scene expanded into a grid of variants (pure functions, nothing runs here).

A sweep is declared by a scene's ``[sweep]`` table (:class:`~.schema.SweepSpec`) and/or on
the command line (``cvn sweep SCENE --set learning.eta=0.03,0.1 --set seed=0..9``, parsed
by :func:`parse_set`). :func:`expand` turns the scene and its sweep into
:class:`GridPoint` s: the cartesian product of the axes (zipped axes count as one), each a
complete scene validated by :func:`~.schema.parse_scene`, so a value that is wrong for its
key, or a combination the scene's kind rejects, is an error naming the file, the key and
the point before anything runs.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .limits import check_grid
from .schema import Scene, SceneError, SweepSpec, check_zip, parse_scene, sweep_values

__all__ = ["GridPoint", "expand", "grid_shape", "parse_set", "with_overrides"]

#: The ``file`` of errors in command-line sweep settings.
COMMAND_LINE = "command line (--set)"


@dataclass(frozen=True)
class GridPoint:
    """One variant of a swept scene.

    Attributes
    ----------
    index : int
        Position in the grid (first axis slowest).
    values : dict of str -> value
        This point's value of every swept key (``"learning.eta"``, ``"seed"``).
    scene : Scene
        The complete variant (no ``[sweep]`` table), validated.
    fingerprint : str
        Hash of every setting of the variant: the name of its stored result.
    """

    index: int
    values: Mapping[str, Any]
    scene: Scene
    fingerprint: str


def _parse_value(text: str) -> Any:
    """One ``--set`` value: a TOML value (``0.1``, ``true``, ``[0.0, 0.1]``, ``"a"``) or a
    bare word taken as a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text.strip()


def _split_top(text: str) -> list[str]:
    """Split at commas outside brackets and quotes."""
    parts, depth, quote, cur = [], 0, "", []
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "[":
            depth += 1
        elif ch == "]":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur))
    return parts


def parse_set(items: Sequence[str]) -> dict[str, tuple[Any, ...]]:
    """Sweep axes from ``--set KEY=V1,V2,...`` settings (``KEY=a..b`` for integer ranges).

    Raises :class:`~.schema.SceneError` naming the setting.
    """
    axes: dict[str, tuple[Any, ...]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key or not text.strip():
            raise SceneError(COMMAND_LINE, "sweep", item, "must be KEY=VALUE[,VALUE...]")
        if key in axes:
            raise SceneError(COMMAND_LINE, "sweep", key, "is set twice")
        if ".." in text and "," not in text and not text.strip().startswith(("[", '"', "'")):
            raw: Any = text.strip()  # an integer range a..b
        else:
            raw = [_parse_value(p) for p in _split_top(text)]
        axes[key] = sweep_values(key, raw, COMMAND_LINE)
    return axes


def with_overrides(
    scene: Scene,
    axes: Mapping[str, tuple[Any, ...]],
    *,
    zip_groups: Sequence[Sequence[str]] = (),
    threshold: float | None = None,
) -> Scene:
    """``scene`` with command-line axes added to (or replacing) its ``[sweep]`` axes.

    ``zip_groups`` adds groups of keys varied together; ``threshold`` replaces the sweep's.
    """
    base = scene.sweep or SweepSpec(axes=())
    merged = dict(base.axes)
    merged.update(axes)
    if not merged:
        raise SceneError(
            scene.source or COMMAND_LINE,
            "sweep",
            "",
            "nothing to sweep: give a [sweep] table or --set KEY=V1,V2",
        )
    groups = [list(g) for g in base.zip if all(k not in axes for k in g)]
    groups += [list(g) for g in zip_groups]
    spec = SweepSpec(
        axes=tuple(merged.items()),
        zip=check_zip(groups, merged, COMMAND_LINE),
        threshold=base.threshold if threshold is None else float(threshold),
    )
    if not 0 < spec.threshold < 1:
        raise SceneError(COMMAND_LINE, "sweep", "threshold", "must lie strictly between 0 and 1")
    return dataclasses.replace(scene, sweep=spec)


def _dimensions(spec: SweepSpec) -> list[list[dict[str, Any]]]:
    """One list of assignments per grid dimension (a zipped group is one dimension)."""
    axes = dict(spec.axes)
    grouped = {k: g for g in spec.zip for k in g}
    dims, done = [], set()
    for key, values in spec.axes:
        if key in done:
            continue
        group = grouped.get(key, (key,))
        done.update(group)
        dims.append([{k: axes[k][i] for k in group} for i in range(len(values))])
    return dims


def grid_shape(spec: SweepSpec) -> tuple[int, ...]:
    """Length of every grid dimension; the grid size is their product."""
    return tuple(len(d) for d in _dimensions(spec))


def _plain(v: Any) -> Any:
    return list(v) if isinstance(v, tuple) else v


def expand(scene: Scene) -> tuple[GridPoint, ...]:
    """The variants of a scene with a ``[sweep]`` table, in grid order.

    Raises
    ------
    SceneError
        A variant is not a valid scene (names the file, the key and the point), or two
        points are the same scene.
    """
    if scene.sweep is None:
        raise SceneError(scene.source, "sweep", "", "the scene has no [sweep] table")
    file = scene.source or "<scene>"
    check_grid(math.prod(grid_shape(scene.sweep)), file)
    base = {
        k: ({kk: vv for kk, vv in v.items() if vv is not None} if isinstance(v, dict) else v)
        for k, v in scene.to_dict().items()
        if k != "sweep"
    }
    points: list[GridPoint] = []
    seen: dict[str, int] = {}
    for index, combo in enumerate(itertools.product(*_dimensions(scene.sweep))):
        values = {k: v for part in combo for k, v in part.items()}
        data = json.loads(json.dumps(base))
        for key, value in values.items():
            table, _, name = key.rpartition(".")
            target = data.setdefault(table, {}) if table else data
            target[name] = _plain(value)
        try:
            variant = parse_scene(data, file)
        except SceneError as err:
            where = ", ".join(f"{k} = {_plain(v)!r}" for k, v in values.items())
            raise SceneError(
                err.file, err.table, err.key, f"{err.problem} (sweep point {index}: {where})"
            ) from err
        fp = fingerprint(variant)
        if fp in seen:
            raise SceneError(file, "sweep", "", f"points {seen[fp]} and {index} are the same scene")
        seen[fp] = index
        points.append(GridPoint(index=index, values=values, scene=variant, fingerprint=fp))
    return tuple(points)


def fingerprint(scene: Scene) -> str:
    """Hash of every setting of ``scene`` that can change its results (not its name)."""
    data = scene.to_dict()
    for key in ("name", "description", "sweep", "report", "export"):
        data.pop(key, None)
    text = json.dumps(data, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:20]
