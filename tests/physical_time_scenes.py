"""Tiny physical_time scenes for tests: one builder of their TOML instead of a copy per file."""

import json
import tomllib

from continuum_vs_network.scenes.schema import parse_scene


def tiny_physical_time(
    name: str = "pt",
    *,
    sizes=(5,),
    n_sources: int = 2,
    n_targets: int = 1,
    series: bool = False,
    **physical_time,
):
    """A parsed physical_time scene on ``sizes`` x ``sizes`` triangular lattices with a
    Stern task; ``physical_time``: the entries of its ``[physical_time]`` table (strings,
    numbers and lists of them); ``series``: ``[export] series = true``."""
    lines = [
        f'name = "{name}"',
        'description = "tiny"',
        'kind = "physical_time"',
        "[network]",
        'builder = "triangular"',
        f"sizes = {json.dumps(list(sizes))}",
        "[task]",
        'kind = "stern"',
        f"n_sources = {n_sources}",
        f"n_targets = {n_targets}",
        "[physical_time]",
        *(f"{key} = {json.dumps(value)}" for key, value in physical_time.items()),
    ]
    if series:
        lines += ["[export]", "series = true"]
    return parse_scene(tomllib.loads("\n".join(lines) + "\n"), f"{name}.toml")
