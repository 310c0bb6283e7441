"""The scene error, and what a scene's name may be (no pydantic here: importing the package
and reading a scene's name need neither)."""

from __future__ import annotations

import re
from typing import Any

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.\-]*")
_NAME_MAX = 100  # it names folders and files (file systems allow 255 bytes per name)


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


def _short(value: Any, width: int = 60) -> str:
    """``repr(value)`` (strings: the text itself) cut to ``width`` characters."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."
