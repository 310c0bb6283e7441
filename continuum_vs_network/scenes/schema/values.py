"""Pydantic's validation errors said as scene errors (file, table, key, what is allowed)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from .errors import SceneError as SceneError
from .errors import _short as _short
from .keys import toml_type

_WANT = {
    "int_type": "an integer",
    "float_type": "a number",
    "bool_type": "true or false",
    "string_type": "a string",
}


def value_problem(
    err: Mapping[str, Any], annotation: Any, raw: Any, *, got: bool = True
) -> tuple[str, str]:
    """``(index, problem)`` of one pydantic error on a key's value: ``index`` is ``"[i]"``
    when the error is a list entry's type, "" otherwise; ``raw`` the value as given; ``got``:
    whether a check's problem ends with ``(got <raw>)``."""
    kind, loc, value = err["type"], err["loc"], err["input"]
    index = f"[{loc[-1]}]" if loc and isinstance(loc[-1], int) else ""
    if kind in _WANT:
        return index, f"must be {_WANT[kind]}, got {type(value).__name__} {value!r}"
    if kind == "finite_number":
        return index, f"must be finite, got {value}"
    if kind == "tuple_type":
        inner = toml_type(annotation)[0][5:-1]
        return "", f"must be a list of {inner}s, got {type(value).__name__} {value!r}"
    if kind == "literal_error":
        choices = toml_type(annotation)[1] or ()
        return "", f"{value!r} is not one of {', '.join(map(repr, choices))}"
    if kind == "value_error":
        msg = str(err["ctx"]["error"])
        return "", f"{msg} (got {raw!r})" if got else msg
    if kind in ("missing", "missing_argument"):
        return "", "is required"
    return index, err["msg"]  # pragma: no cover - a pydantic error not said above


def table_error(
    err: Mapping[str, Any], cls: type, data: Mapping[str, Any], file: str, table: str
) -> SceneError:
    """The scene error of one pydantic error inside table ``table`` (class ``cls``)."""
    key = str(err["loc"][0])
    fields = {f.name: f for f in dataclasses.fields(cls)}
    if err["type"] == "unexpected_keyword_argument" or key not in fields:
        return SceneError(
            file, table, key, f"unknown key; [{table}] accepts {', '.join(sorted(fields))}"
        )
    index, problem = value_problem(err, fields[key].type, data.get(key))
    return SceneError(file, table, key + index, problem)
