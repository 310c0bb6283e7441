"""Typed unit results: a unit returns a frozen dataclass, a report section reads it back.

One codec for every result class. A result is a frozen dataclass whose fields hold plain
values (numbers, strings, lists: the unit's JSON record), arrays (annotated ``np.ndarray``:
the unit's ``.npz`` payload) or, in one field named ``fields``, a mapping of further
arrays whose names carry a ``/`` (``"net/x"``, ``"cont/strain"``: what mesh export reads).
Each is stored under the field's name, or under ``field(metadata={"stored": name})``
(an array and a record value may share a stored name). A field with a default may be
absent from a stored unit (a continuum part a scene leaves out). A field left at None is
not stored, unless its metadata is :data:`KEEP_NONE` (a value the record holds as null).
The stored layout is the one untyped units write, so results computed before a kind was
typed read back as its class.

    arrays, meta = to_stored(TransmissionResult(...))   # what the store writes
    result = from_stored(unit, TransmissionResult)      # what a section reads
    runs = read_results(units, CLASSES)                 # a kind's units, each its class

The result classes live in one module per kind: :mod:`.physics` (transmission,
relaxation), :mod:`.solvers`, :mod:`.accuracy`, :mod:`.stability`, :mod:`.physical_time`,
:mod:`.mechanism` (continuum_mechanism), :mod:`.allostery`, :mod:`.learning`,
:mod:`.beyond_paper`, :mod:`.continuum_learning`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np

from ..units import UnitResult

__all__ = [
    "KEEP_NONE",
    "from_stored",
    "is_result",
    "read_result",
    "read_results",
    "to_stored",
]

T = TypeVar("T")

#: Field metadata of a record value stored even when None (``null`` in the record).
KEEP_NONE = {"keep_none": True}


def is_result(output: Any) -> bool:
    """True for an instance of a result dataclass (not a class, not a History)."""
    return dataclasses.is_dataclass(output) and not isinstance(output, type)


def _stored(f: dataclasses.Field) -> tuple[str, bool]:
    """A field's stored name and whether it is an array (in the payload, not the record)."""
    kind = str(f.type)
    return f.metadata.get("stored", f.name), "ndarray" in kind and "Mapping" not in kind


def to_stored(result: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, meta)`` of a result dataclass: array fields and the ``fields`` mapping
    to ``arrays``, every other field to ``meta``; fields left at None are not stored
    (unless their metadata is :data:`KEEP_NONE`)."""
    arrays: dict[str, np.ndarray] = {}
    meta: dict[str, Any] = {}
    for f in dataclasses.fields(result):
        value = getattr(result, f.name)
        name, is_array = _stored(f)
        if value is None and not f.metadata.get("keep_none"):
            continue
        if f.name == "fields":
            arrays.update(value)
        elif is_array:
            arrays[name] = np.asarray(value)
        else:
            meta[name] = value
    return arrays, meta


def from_stored(unit: UnitResult, cls: type[T]) -> T:
    """``unit``'s arrays and record read as ``cls`` (a result dataclass).

    Raises KeyError naming the unit and the field when a field without a default is not
    stored (a result of another kind, or of an older layout).
    """
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        name, is_array = _stored(f)
        stored = unit.arrays if is_array else unit.meta
        if f.name == "fields":
            values["fields"] = {k: v for k, v in unit.arrays.items() if "/" in k}
        elif name in stored:
            values[f.name] = stored[name]
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise KeyError(f"unit {unit.key!r} stores no {name!r} for {cls.__name__}")
    return cls(**values)


def read_result(unit: UnitResult, classes: Mapping[str, type]) -> Any:
    """``unit`` read as the class of the first key start in ``classes`` (in order) that its
    key begins with (a kind's ``CLASSES``); KeyError naming the key when none does."""
    for start, cls in classes.items():
        if unit.key.startswith(start):
            return from_stored(unit, cls)
    raise KeyError(f"unit {unit.key!r} begins with none of {', '.join(classes)}")


def read_results(units: Mapping[str, UnitResult], classes: Mapping[str, type]) -> dict[str, Any]:
    """The units of ``units`` (key -> stored unit) whose key begins with a key start of
    ``classes``, each read by :func:`read_result`, by key; the others are left out."""
    return {
        key: read_result(unit, classes)
        for key, unit in units.items()
        if any(key.startswith(start) for start in classes)
    }
