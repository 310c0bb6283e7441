"""Findings: a claim, the metric it refers to, what was measured and the verdict of a rule.

A report section judges a claim (the paper's, the README's, the package's own) against the
numbers of the same run and registers the result with
:meth:`~continuum_vs_network.report.document.Document.finding`. Every finding lands in the
scene's ``report.json`` (key ``"findings"``) and in the findings table that opens
``reports/README.md``. A verdict is never written by hand: ``rule`` states how it follows
from ``measured``.

>>> f = Finding(
...     claim="GCL lowers the task error",
...     metric="final C/C0, median over trials",
...     measured={"C/C0": 3e-4},
...     verdict=REPRODUCED,
...     rule="reproduced when the median final C/C0 < 1e-2",
... )
>>> f.to_dict()["verdict"]
'reproduced'
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "BASES",
    "CONTRADICTED",
    "NOT_COMPARABLE",
    "NOT_REPRODUCED",
    "REPRODUCED",
    "SOURCES",
    "VERDICTS",
    "Finding",
    "reasoned",
    "runs_basis",
]

#: The claim holds by the stated rule.
REPRODUCED = "reproduced"
#: The data does not show the claim (e.g. too weak an effect), without showing its opposite.
NOT_REPRODUCED = "not reproduced"
#: The data shows the opposite of the claim.
CONTRADICTED = "contradicted"
#: The run does not measure what the claim is about (another metric, setting or scale).
NOT_COMPARABLE = "not comparable"
#: Every verdict a finding may carry.
VERDICTS = (REPRODUCED, NOT_REPRODUCED, CONTRADICTED, NOT_COMPARABLE)

#: Whose claim a finding judges: the paper's, the field's (published work other than the
#: paper), or the package's own check of its numerics.
SOURCES = ("paper", "field", "check")

#: What a learning finding's verdict rests on: runs where the sources drive the target
#: (``"coupled"``), runs that met the task by prestress alone (``"met trivially"``); ``""``
#: for a finding that is not about learning.
BASES = ("", "coupled", "met trivially")


@dataclass(frozen=True)
class Finding:
    """One claim and its computed verdict.

    Attributes
    ----------
    claim : str
        What is claimed, in one sentence (whose claim, e.g. "paper, Fig. 4: ...").
    metric : str
        The quantity the claim refers to, e.g. "final C/C0 (Eq. 26, strains against the
        initial rest lengths), median over trials".
    measured : mapping of str to float
        The measured value(s) the verdict follows from, by name; non-finite values are
        stored as ``None`` in JSON.
    verdict : str
        One of :data:`VERDICTS`.
    rule : str
        The stated rule that turns ``measured`` into ``verdict``.
    section : str
        Where in the report the finding is shown (a heading); filled in by the document
        when empty.
    source : str
        Whose claim it is, one of :data:`SOURCES` (default ``"check"``).
    basis : str
        For a learning claim, what the verdict rests on, one of :data:`BASES`.
    """

    claim: str
    metric: str
    measured: Mapping[str, float]
    verdict: str
    rule: str
    section: str = ""
    source: str = "check"
    basis: str = ""
    _values: tuple[tuple[str, float], ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        for name in ("claim", "metric", "rule"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name).strip():
                raise ValueError(f"Finding.{name} must be a non-empty string")
        if self.verdict not in VERDICTS:
            raise ValueError(
                f"Finding.verdict must be one of {', '.join(map(repr, VERDICTS))}, "
                f"not {self.verdict!r}"
            )
        for name, allowed in (("source", SOURCES), ("basis", BASES)):
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"Finding.{name} must be one of {', '.join(map(repr, allowed))}, "
                    f"not {getattr(self, name)!r}"
                )
        if not isinstance(self.measured, Mapping) or not self.measured:
            raise ValueError("Finding.measured must be a non-empty mapping of name to number")
        values = []
        for k, v in self.measured.items():
            try:
                values.append((str(k), float(v)))
            except (TypeError, ValueError):
                raise ValueError(
                    f"Finding.measured[{k!r}] must be a number, not {type(v).__name__}"
                ) from None
        object.__setattr__(self, "_values", tuple(values))
        object.__setattr__(self, "measured", dict(values))

    def to_dict(self) -> dict[str, Any]:
        """A strict-JSON-ready dict.

        Non-finite measured values become ``None`` (NaN: not available); an infinite one is
        also named in ``"infinite"`` (name -> ``"inf"`` or ``"-inf"``), so it is not read
        back as missing.
        """
        d = {
            "claim": self.claim,
            "metric": self.metric,
            "measured": {k: (v if math.isfinite(v) else None) for k, v in self._values},
            "verdict": self.verdict,
            "rule": self.rule,
            "section": self.section,
            "source": self.source,
            "basis": self.basis,
        }
        infinite = {k: ("inf" if v > 0 else "-inf") for k, v in self._values if math.isinf(v)}
        if infinite:
            d["infinite"] = infinite
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Finding:
        """Inverse of :meth:`to_dict` (``None`` measured values become NaN, or the infinity
        named in ``"infinite"``)."""
        infinite = d.get("infinite", {})
        measured = {
            k: (float(infinite.get(k, "nan")) if v is None else v) for k, v in d["measured"].items()
        }
        return cls(
            claim=d["claim"],
            metric=d["metric"],
            measured=measured,
            verdict=d["verdict"],
            rule=d["rule"],
            section=d.get("section", ""),
            source=d.get("source", "check"),
            basis=d.get("basis", ""),
        )

    def measured_text(self, digits: int = 3) -> str:
        """``name = value`` pairs, comma-separated."""
        return ", ".join(
            f"{k} = {v:.{digits}g}" if math.isfinite(v) else f"{k} = -" for k, v in self._values
        )


def runs_basis(runs: Iterable[Any]) -> str:
    """What a verdict rests on, from the learning runs it reads (results with ``outcome``
    and ``coupling``, None where a run has none): ``"met trivially"`` when any met its
    task decoupled, ``"coupled"`` when every one is coupled, ``""`` otherwise (or when
    there are none)."""
    runs = list(runs)
    if any(str(getattr(m, "outcome", None) or "").startswith("met trivially") for m in runs):
        return "met trivially"
    if runs and all(getattr(m, "coupling", None) == "coupled" for m in runs):
        return "coupled"
    return ""


def reasoned(rule: str, verdict: str, reason: str) -> str:
    """``rule``, and for a *not comparable* verdict the one-line ``reason`` it has here."""
    if verdict != NOT_COMPARABLE:
        return rule
    return f"{rule.rstrip('.')}. Not comparable here: {reason}"
