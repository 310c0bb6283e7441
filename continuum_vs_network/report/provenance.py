"""Every report's closing sections: the settings (the scene as TOML, :func:`settings`) and
the provenance of the run (:func:`provenance_table`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .document import Document


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def scene_toml(scene_dict: dict[str, Any]) -> str:
    """The scene as TOML text (every key, defaults included; unset keys left out)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in scene_dict.items() if not isinstance(v, dict)]
    for table, values in scene_dict.items():
        if isinstance(values, dict):
            lines.append(f"\n[{table}]")
            lines += [f"{k} = {_toml_value(v)}" for k, v in values.items() if v is not None]
    return "\n".join(lines)


def settings(doc: Document, scene) -> None:
    """The "Settings" heading and the scene as TOML."""
    doc.heading("Settings")
    doc.add("```toml", scene_toml(scene.to_dict()), "```")


def provenance_table(doc: Document, result) -> None:
    """The provenance table of a run."""
    p = result.provenance
    doc.heading("Provenance")
    doc.table(
        ["item", "value"],
        [
            ["package version", p.version],
            ["git commit", f"`{p.commit}`"],
            ["python", p.python],
            [
                "libraries (installed versions)",
                ", ".join(f"{k} {v}" for k, v in p.libraries.items() if v != "not installed")
                or f"numpy {p.numpy}, scipy {p.scipy}",
            ],
            ["platform", p.platform],
            ["CPU", p.cpu],
            ["thread pools (threadpoolctl)", p.threads],
            ["command", f"`{p.command}`"],
            [
                "seeds",
                ", ".join(map(str, p.seeds))
                if len(p.seeds) <= 12
                else f"{p.seeds[0]} ... {p.seeds[-1]} ({len(p.seeds)})",
            ],
            ["started", p.started],
            ["wall time of the completing run", f"{p.wall_seconds:.1f} s"],
            ["compute time (sum over units)", f"{p.compute_seconds:.1f} s"],
            ["units (reused from an earlier run)", f"{p.units} ({p.reused})"],
            ["units computed at", unit_commits(p.commit, p.unit_commits)],
            ["worker processes", str(p.workers)],
            ["scene file", f"`{short_source(result.scene.source)}`"],
        ],
    )


def unit_commits(commit: str, counts: dict[str, int]) -> str:
    """Where the units were computed, against the report's ``commit``: "this commit" when
    all were; else the counts per commit (units are reused whatever the code is now: a
    stale one is recomputed with ``--fresh``)."""
    if not counts:
        return "not recorded"
    if set(counts) == {commit}:
        return "this commit (all)"
    parts = [
        ("this commit" if c == commit else c if c == "not recorded" else f"`{c[:12]}`") + f": {n}"
        for c, n in sorted(counts.items(), key=lambda kv: (kv[0] != commit, -kv[1]))
    ]
    return "; ".join(parts) + " (units are reused whatever the code is now; `--fresh` recomputes)"


def short_source(source: str) -> str:
    """A scene file path from the package folder on (built-in scenes), else as given."""
    parts = Path(source).parts
    if "continuum_vs_network" in parts:
        i = len(parts) - 1 - parts[::-1].index("continuum_vs_network")
        return "/".join(parts[i:])
    return source
