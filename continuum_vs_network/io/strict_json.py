"""Stored records as strict JSON: a non-finite float is written as ``null`` and named.

Python's :mod:`json` writes ``NaN`` and ``Infinity`` by default, which strict parsers
(JavaScript, jq, ``json.loads(..., parse_constant=...)``) reject. Every record the package
stores (scene units, sweep points, run/scene/sweep/report metadata) goes through
:func:`dumps_record`:

- a non-finite float (NaN, +inf, -inf; also inside lists and numpy arrays) is written as
  ``null``;
- the record (a JSON object) gets one extra key, ``"non_finite"``, that maps the JSON pointer
  (RFC 6901) of each such value to ``"nan"``, ``"inf"`` or ``"-inf"``. NaN means "not
  available / not applicable"; an infinity keeps its meaning there (e.g. ``"inf"`` for an
  open upper end of a bracket: no instability found below the largest value tried). A
  ``null`` not named there is a genuine ``None`` (e.g. an unset option);
- the text is produced with ``allow_nan=False``: a non-finite value that escaped the
  conversion fails loudly instead of being written.

:func:`loads_record` is the inverse: it puts NaN / inf back at the named places, so readers
see exactly the in-memory values that were stored. Records written before this format
(bare ``NaN`` / ``Infinity`` tokens) still load: Python's parser accepts them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

__all__ = ["NON_FINITE_KEY", "dumps_record", "loads_record", "strict_copy"]

#: key of the map JSON pointer -> "nan" | "inf" | "-inf" added to a record with non-finite values
NON_FINITE_KEY = "non_finite"
_VALUES = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}


def _pointer_part(key: Any) -> str:
    return str(key).replace("~", "~0").replace("/", "~1")


def _name(x: float) -> str:
    return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")


def strict_copy(obj: Any) -> tuple[Any, dict[str, str]]:
    """``obj`` with every non-finite float as ``None``, and the map pointer -> kind.

    numpy scalars and arrays become Python numbers and lists; tuples become lists; mapping
    keys are kept as given (``json`` turns them into strings). Other objects are returned
    unchanged (the caller's ``default`` handles or refuses them).
    """
    found: dict[str, str] = {}

    def walk(v: Any, path: str) -> Any:
        if isinstance(v, np.ndarray):
            v = v.tolist()
        elif isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float):
            if math.isfinite(v):
                return v
            found[path] = _name(v)
            return None
        if isinstance(v, Mapping):
            return {k: walk(x, f"{path}/{_pointer_part(k)}") for k, x in v.items()}
        if isinstance(v, list | tuple):
            return [walk(x, f"{path}/{i}") for i, x in enumerate(v)]
        return v

    return walk(obj, ""), found


def dumps_record(
    record: Mapping[str, Any], *, default: Callable[[Any], Any] | None = None, **kwargs: Any
) -> str:
    """Strict JSON text of ``record`` (a mapping); see the module docstring.

    ``kwargs`` go to :func:`json.dumps` (``indent``, ``sort_keys``). Raises ``ValueError``
    when ``record`` is not a mapping or already has a ``"non_finite"`` key.
    """
    if not isinstance(record, Mapping):
        raise ValueError(f"record must be a mapping, not {type(record).__name__}")
    if NON_FINITE_KEY in record:
        raise ValueError(f"record must not have a key {NON_FINITE_KEY!r} (it is reserved)")
    clean, found = strict_copy(record)
    if found:
        clean[NON_FINITE_KEY] = found
    return json.dumps(clean, allow_nan=False, default=default, **kwargs)


def loads_record(text: str) -> Any:
    """Parse a record written by :func:`dumps_record` (or an older one with bare NaN tokens).

    The ``"non_finite"`` map is removed and its values put back (NaN, inf, -inf).
    """
    record = json.loads(text)
    if not isinstance(record, dict):
        return record
    found = record.pop(NON_FINITE_KEY, None)
    if not found:
        return record
    for pointer, kind in found.items():
        parts = [p.replace("~1", "/").replace("~0", "~") for p in pointer.split("/")[1:]]
        if not parts or kind not in _VALUES:
            raise ValueError(f"bad {NON_FINITE_KEY} entry {pointer!r}: {kind!r}")
        target = record
        for part in parts[:-1]:
            target = target[int(part)] if isinstance(target, list) else target[part]
        last = parts[-1]
        if isinstance(target, list):
            target[int(last)] = _VALUES[kind]
        else:
            target[last] = _VALUES[kind]
    return record
