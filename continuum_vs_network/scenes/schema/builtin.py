"""Scene files: the built-in scenes (``scenes/builtin/<name>.toml``), reading a scene file,
and the key reference ``cvn scenes --keys`` prints.
"""

from __future__ import annotations

import dataclasses
import tomllib
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import _NAME, _NAME_MAX, SceneError, _short

if TYPE_CHECKING:
    from .scene import Scene

_FILE_MAX = 1 << 20  # bytes; a scene is a few dozen lines


def builtin_names() -> list[str]:
    """Names of the built-in scenes (files ``scenes/builtin/<name>.toml``), sorted."""
    folder = resources.files("continuum_vs_network.scenes") / "builtin"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_path(name: str) -> Path:
    """Path of the built-in scene ``name``."""
    folder = resources.files("continuum_vs_network.scenes") / "builtin"
    path = Path(str(folder / f"{name}.toml"))
    if not path.is_file():
        raise SceneError(
            f"{name}.toml",
            "",
            "",
            f"no built-in scene {name!r}; built-in scenes: {', '.join(builtin_names())}",
        )
    return path


def load_scene(scene: str | Path) -> Scene:
    """Read a scene: a path to a ``.toml`` file or the name of a built-in scene."""
    if not isinstance(scene, str | Path):
        raise SceneError(repr(scene), "", "", "a scene is a path or a built-in name")
    path = Path(scene)
    try:
        is_file = path.is_file()
    except OSError as err:  # a name too long, a symlink loop
        raise SceneError(_short(str(scene)), "", "", f"cannot read: {err.strerror}") from None
    if not is_file:
        if path.is_dir():
            raise SceneError(_short(str(scene)), "", "", "is a folder, not a scene file")
        if str(scene).endswith(".toml") or "/" in str(scene) or path.exists():
            raise SceneError(_short(str(scene)), "", "", "no such scene file")
        if not _NAME.fullmatch(str(scene)) or len(str(scene)) > _NAME_MAX:
            raise SceneError(
                _short(str(scene)),
                "",
                "",
                f"no such scene file or built-in scene; built-in scenes: "
                f"{', '.join(builtin_names())}",
            )
        path = builtin_path(str(scene))
    try:
        with open(path, "rb") as fh:
            raw = fh.read(_FILE_MAX + 1)
        if len(raw) > _FILE_MAX:
            raise SceneError(str(path), "", "", f"larger than {_FILE_MAX} bytes: not a scene file")
        data = tomllib.loads(raw.decode("utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise SceneError(str(path), "(syntax)", "", f"not valid TOML: {err}") from err
    except UnicodeDecodeError as err:
        raise SceneError(
            str(path), "(syntax)", "", f"not UTF-8 text (byte {err.start}): a scene is TOML"
        ) from None
    except RecursionError:
        raise SceneError(str(path), "(syntax)", "", "nested too deeply to be a scene") from None
    except OSError as err:
        raise SceneError(str(path), "", "", f"cannot read: {err.strerror or err}") from None
    from .parse import parse_scene  # the models (pydantic): imported by the first scene read

    return parse_scene(data, str(path))


def key_reference() -> str:
    """Every table and key with its type, default and meaning (plain text)."""
    from .keys import toml_type
    from .kinds import KIND_TABLES, KINDS
    from .tables import _TABLES

    lines = [
        f"(top level): name (str), description (str), seed (int, 0), kind ({' | '.join(KINDS)})"
    ]
    for table, cls in _TABLES.items():
        lines.append(f"\n[{table}]")
        for f in dataclasses.fields(cls):
            type_, options = toml_type(f.type)
            default = "required" if f.default is dataclasses.MISSING else repr(f.default)
            choices = f" one of {', '.join(map(repr, options))};" if options else ""
            lines.append(f"  {f.name} ({type_}, {default}):{choices} {f.metadata['doc']}")
    lines.append(
        "\n[sweep] (any kind; run with `cvn sweep`): <table>.<key> = [values] or seed = 'a..b' "
        "(a grid: cartesian product, first key slowest); zip = [[keys varied together]]; "
        "threshold (float, 0.1): steps_to_threshold counts steps to error <= threshold x initial"
    )
    lines.append("\nTables by kind (needed; also accepted):")
    for kind, (need, accept) in KIND_TABLES.items():
        lines.append(f"  {kind}: {', '.join(sorted(need))}; {', '.join(sorted(accept))}")
    return "\n".join(lines)
