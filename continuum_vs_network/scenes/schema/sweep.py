"""``[sweep]``: a scene as a grid of variants; each axis's values checked like the key itself."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Annotated, Any

import pydantic

from .keys import RENAMED, Float, Int, _non_negative, toml_type
from .tables import _TABLES
from .values import SceneError, value_problem

#: Tables whose keys a sweep may vary (besides the top-level ``seed``).
_SWEEPABLE = tuple(t for t in _TABLES if t not in ("export", "report"))
_RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")


@dataclass(frozen=True)
class SweepSpec:
    """``[sweep]``: the scene as a grid of variants (expanded by :func:`.grid.expand`).

    In the file, each key names a scene key (``learning.eta = [0.03, 0.1]``, or quoted
    ``"learning.eta"``, or ``seed = "0..9"`` for the integers 0 to 9) and lists its values;
    a single value sets the key for every point. Keys that take a list (``learning.noise``)
    take one list per value, or plain values that each become a one-entry list.

    Attributes
    ----------
    axes : tuple of (key, values)
        In the order given; the grid is their cartesian product, first key slowest.
    zip : tuple of tuple of str
        Groups of axes varied together instead (equal lengths): one grid dimension each.
    threshold : float
        ``steps_to_threshold`` in the sweep table is the first step whose error is at most
        ``threshold`` times the trial's initial error.
    """

    axes: tuple[tuple[str, tuple[Any, ...]], ...]
    zip: tuple[tuple[str, ...], ...] = ()
    threshold: float = 0.1

    def to_dict(self) -> dict[str, Any]:
        """Plain (TOML-like) dict of the table."""
        out: dict[str, Any] = {
            k: [list(v) if isinstance(v, tuple) else v for v in vals] for k, vals in self.axes
        }
        if self.zip:
            out["zip"] = [list(g) for g in self.zip]
        out["threshold"] = self.threshold
        return out


def sweep_values(key: str, raw: Any, file: str) -> tuple[Any, ...]:
    """The values of sweep axis ``key``, each converted and checked like the key itself.

    ``raw``: a list of values, one value, or ``"a..b"`` (the integers a to b) for an
    integer key. Raises :class:`SceneError` naming ``file``, ``[sweep]`` and the key.
    """
    where = (file, "sweep", key)
    if key == "seed":
        annotation: object = Annotated[Int, _non_negative]
    else:
        table, _, name = key.partition(".")
        if table not in _SWEEPABLE:
            allowed = ", ".join(["seed", *(f"{t}.<key>" for t in _SWEEPABLE)])
            raise SceneError(file, "sweep", key, f"unknown sweep key; a sweep varies {allowed}")
        fields = {f.name: f for f in dataclasses.fields(_TABLES[table])}
        if (table, name) in RENAMED:
            new_key = f"{table}.{RENAMED[table, name]}"
            raise SceneError(file, "sweep", key, f"renamed; use {new_key}")
        if name not in fields:
            raise SceneError(
                file,
                "sweep",
                key,
                f"unknown key; [{table}] accepts {', '.join(sorted(fields))}",
            )
        annotation = fields[name].type
    type_ = toml_type(annotation)[0]
    match = _RANGE.match(raw) if isinstance(raw, str) else None
    if match and type_ == "int":
        lo, hi = int(match[1]), int(match[2])
        if hi < lo or hi - lo >= 100_000:
            raise SceneError(*where, f"range {raw!r} must run upwards, at most 100000 values")
        items: list[Any] = list(range(lo, hi + 1))
    elif isinstance(raw, list):
        items = raw
    else:
        items = [raw]
    if not items:
        raise SceneError(*where, "must list at least one value")
    out = []
    for i, item in enumerate(items):
        if type_.startswith("list[") and not isinstance(item, list):
            item = [item]
        label = key if len(items) == 1 else f"{key}[{i}]"
        try:
            out.append(_adapter(annotation).validate_python(item))
        except pydantic.ValidationError as exc:
            index, problem = value_problem(exc.errors()[0], annotation, item)
            raise SceneError(file, "sweep", label + index, problem) from None
    if len(set(map(repr, out))) != len(out):
        raise SceneError(*where, f"must not repeat values (got {raw!r})")
    return tuple(out)


@cache
def _adapter(annotation: object) -> pydantic.TypeAdapter:
    """The validator of one key's values (its annotation: type and checks)."""
    return pydantic.TypeAdapter(annotation, config=pydantic.ConfigDict(allow_inf_nan=False))


def parse_sweep(data: Any, file: str) -> SweepSpec:
    """Validate a ``[sweep]`` table (see :class:`SweepSpec`)."""
    if not isinstance(data, Mapping):
        raise SceneError(file, "(top level)", "sweep", "must be a table [sweep]")
    axes: dict[str, tuple] = {}
    zip_groups: Any = []
    threshold: Any = 0.1
    for key, value in data.items():
        if key == "zip":
            zip_groups = value
        elif key == "threshold":
            threshold = value
        elif isinstance(value, Mapping):  # learning.eta = [...] is {"learning": {"eta": ...}}
            for sub, v in value.items():
                axes[f"{key}.{sub}"] = sweep_values(f"{key}.{sub}", v, file)
        else:
            axes[key] = sweep_values(key, value, file)
    try:
        threshold = _adapter(Float).validate_python(threshold)
    except pydantic.ValidationError as exc:
        _, problem = value_problem(exc.errors()[0], Float, threshold)
        raise SceneError(file, "sweep", "threshold", problem) from None
    if not 0 < threshold < 1:
        raise SceneError(file, "sweep", "threshold", "must lie strictly between 0 and 1")
    if not axes:
        raise SceneError(file, "sweep", "", "names no key to vary")
    groups = check_zip(zip_groups, axes, file)
    return SweepSpec(axes=tuple(axes.items()), zip=groups, threshold=threshold)


def check_zip(groups: Any, axes: Mapping[str, tuple], file: str) -> tuple[tuple[str, ...], ...]:
    """Validated zip groups: lists of two or more axes of equal length, each in one group."""
    where = (file, "sweep", "zip")
    if not isinstance(groups, list) or not all(isinstance(g, list) for g in groups):
        raise SceneError(*where, "must be a list of lists of sweep keys")
    seen: set[str] = set()
    out = []
    for g in groups:
        if len(g) < 2:
            raise SceneError(*where, f"a group needs two or more keys, got {g!r}")
        for k in g:
            if k not in axes:
                raise SceneError(*where, f"{k!r} is not a key of the sweep")
            if k in seen:
                raise SceneError(*where, f"{k!r} is in two groups")
            seen.add(k)
        lengths = {len(axes[k]) for k in g}
        if len(lengths) != 1:
            sizes = ", ".join(f"{k}: {len(axes[k])}" for k in g)
            raise SceneError(*where, f"zipped keys need equally many values ({sizes})")
        out.append(tuple(g))
    return tuple(out)
