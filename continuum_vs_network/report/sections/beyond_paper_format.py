"""Formatting and verdict helpers shared by the parts of the ``beyond_paper`` section
(:mod:`.beyond_paper`)."""

from __future__ import annotations

from collections.abc import Iterable

from ..findings import NOT_COMPARABLE


def basis(runs: Iterable[dict]) -> str:
    """What a verdict rests on, from the metas of the runs it reads (``outcome`` and
    ``coupling``): ``"met trivially"`` when any met its task decoupled, ``"coupled"`` when
    every one is coupled, ``""`` otherwise (or when there are none)."""
    runs = list(runs)
    if any(str(m.get("outcome", "")).startswith("met trivially") for m in runs):
        return "met trivially"
    if runs and all(m.get("coupling") == "coupled" for m in runs):
        return "coupled"
    return ""


def reasoned(rule: str, verdict: str, reason: str) -> str:
    """``rule``, and for a *not comparable* verdict the one-line ``reason`` it has here."""
    if verdict != NOT_COMPARABLE:
        return rule
    return f"{rule.rstrip('.')}. Not comparable here: {reason}"
