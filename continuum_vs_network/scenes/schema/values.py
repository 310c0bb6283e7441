"""The scene error and the conversion of one TOML value to its declared type."""

from __future__ import annotations

import dataclasses
import math
from typing import Any


class SceneError(ValueError):
    """A scene file that cannot be used: names the file, the table and the key.

    Attributes
    ----------
    file : str
    table : str
        ``"(top level)"`` for the top-level keys, ``"(syntax)"`` for a TOML syntax error.
    key : str
        The offending key ("" when the problem is the whole table or file).
    problem : str
    """

    def __init__(self, file: str, table: str, key: str, problem: str) -> None:
        self.file, self.table, self.key, self.problem = str(file), table, key, problem
        where = f"[{table}]" if table and not table.startswith("(") else table
        loc = f"{where} {key}".strip() if key else where
        super().__init__(f"{self.file}: {loc}: {problem}" if loc else f"{self.file}: {problem}")


def _convert(value: Any, type_: str, where: tuple[str, str, str]) -> Any:
    file, table, key = where

    def fail(want: str) -> SceneError:
        got = type(value).__name__
        return SceneError(file, table, key, f"must be {want}, got {got} {value!r}")

    if type_ == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise fail("an integer")
        return int(value)
    if type_ == "float":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise fail("a number")
        value = float(value)
        if not math.isfinite(value):
            raise SceneError(file, table, key, f"must be finite, got {value}")
        return value
    if type_ == "bool":
        if not isinstance(value, bool):
            raise fail("true or false")
        return value
    if type_ == "str":
        if not isinstance(value, str):
            raise fail("a string")
        return value
    if type_.startswith("list["):
        inner = type_[5:-1]
        if not isinstance(value, list):
            raise fail(f"a list of {inner}s")
        out = []
        for i, item in enumerate(value):
            out.append(_convert(item, inner, (file, table, f"{key}[{i}]")))
        return tuple(out)
    raise AssertionError(type_)  # pragma: no cover


def _value(f: dataclasses.Field, value: Any, where: tuple[str, str, str]) -> Any:
    """One key's value converted to its type and checked against its choices and rules."""
    file, table, key = where
    meta = f.metadata
    converted = _convert(value, meta["type"], where)
    choices = meta["choices"]
    if choices is not None:
        items = converted if isinstance(converted, tuple) else (converted,)
        for item in items:
            if item not in choices:
                raise SceneError(
                    file, table, key, f"{item!r} is not one of {', '.join(map(repr, choices))}"
                )
    if meta["check"] is not None:
        msg = meta["check"](converted)
        if msg:
            raise SceneError(file, table, key, f"{msg} (got {value!r})")
    return converted


def _short(value: Any, width: int = 60) -> str:
    """``repr(value)`` (strings: the text itself) cut to ``width`` characters."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."
