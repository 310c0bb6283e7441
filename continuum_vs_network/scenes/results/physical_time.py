"""Results of the physical_time units: the task of one size and draw, and the runs of one
rule and medium against the ratio (:mod:`~continuum_vs_network.scenes.units_time`).

Times are in the dynamics' unit (node drag over spring stiffness, k = 1); errors are
relative to the run's initial error; ratios are ``rho`` (``alpha k tau``, or ``step tau /
step_time`` learning stiffnesses). Values stored as None in the record (a verdict not
measured, no reference) are kept as None (``keep_none``), as the untyped units wrote them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import KEEP_NONE

__all__ = ["MEDIA", "TimeRunResult", "TimeTaskResult"]

#: The media a physical_time scene may run.
MEDIA = ("network", "continuum")


@dataclass(frozen=True)
class TimeTaskResult:
    """The task of one size and draw and each medium's relaxation times (a
    ``physical_time/n<n>/d<d>/task`` unit).

    Arrays: ``sources`` and ``targets`` (spring indices), ``source_strain`` and
    ``target_strain`` (the task's strains, one per spring), ``pinned`` ((n_nodes, 2) bool).
    ``network`` and ``continuum`` (None: medium not run): ``tau`` (the target strains' 1 %
    settling time after the source step), ``tau_force`` (the net force's), ``modes`` (the
    linear modes behind ``tau``, :mod:`~..units_time_modes`' keys; empty with Maxwell
    arms) and, learning stiffnesses, the quasi-static reference (``steps_qs``, ``error_qs``,
    ``source_share``, ``coupling``, ``learned``, ``seconds``,
    :func:`~..units_time_reference.reference_run`). ``global_step`` (stored ``global``,
    draw 0 only): the relaxation scene's drive on the same lattice, the same modal keys.
    """

    n: int
    draw: int
    n_nodes: int
    sources: np.ndarray
    source_strain: np.ndarray
    targets: np.ndarray
    target_strain: np.ndarray
    pinned: np.ndarray
    kind: str = "task"
    network: dict[str, Any] | None = None
    continuum: dict[str, Any] | None = None
    global_step: dict[str, float] | None = field(default=None, metadata={"stored": "global"})

    def medium_times(self, medium: str) -> dict[str, Any] | None:
        """``network`` or ``continuum`` (None when that medium was not run)."""
        if medium not in MEDIA:
            raise ValueError(f"medium must be one of {MEDIA}, got {medium!r}")
        return getattr(self, medium)

    def modes(self, medium: str) -> dict[str, float]:
        """The medium's modes (empty when it was not run or has none)."""
        times = self.medium_times(medium)
        return {} if times is None else times.get("modes", {})


@dataclass(frozen=True)
class TimeRunResult:
    """One rule on one medium of one size and draw against the ratio (a
    ``physical_time/n<n>/d<d>/<rule>[/continuum]`` unit).

    ``tau``, ``tau_force``: the medium's relaxation times (from the task unit). ``runs``
    (one per grid ratio, in the scene's order) and ``bisection`` (the ratios bisected, in
    the order run): dicts with ``ratio``, ``alpha`` (NaN learning stiffnesses),
    ``step_time`` (NaN learning rest lengths), ``unit`` (the learning time unit), ``dt``,
    ``dt_learn``, ``duration``, ``T`` and ``T_qs`` (learning times of the run and its
    quasi-static limit), ``slowdown`` (``T / T_qs``), ``error_final``, ``error_at_qs_end``
    (None where diverged), ``error_qs_end``, ``error_qs_window_end``, ``rebound``,
    ``rebound_raw``, ``rebound_qs``, ``seconds``, ``seconds_qs``, ``diverged``,
    ``error0`` (absolute initial error), ``source_share`` and ``coupling`` (None: not
    measured). The critical ratio: the bracket ``(critical_low, critical_high]`` (NaN
    where no ratio was run), ``critical_ratio`` (its geometric mean, or the open end),
    ``critical_by`` (what the bracket's high end met: ``"oscillation"``, ``"slowdown"``,
    ``"both"``, ``"divergence"``, ``"none"``, ``"not learned"``), ``non_monotone`` (ratios
    below ``critical_low`` past). ``coupling`` and ``source_share``: the smallest share over
    every run and its verdict. Learning stiffnesses: ``steps_qs`` and
    ``reference_coupling`` of the quasi-static reference, ``learned_qs`` False when it did
    not learn (no ratio run; ``error_qs`` its final error). ``error0``: the first run's
    absolute initial error. ``series_ratio``: the ratio whose frames are stored (None:
    none). ``fields``: per grid ratio ``i`` ``r<i>/times``, ``r<i>/error``,
    ``r<i>/times_qs``, ``r<i>/error_qs`` and, when it did not diverge, the final learned
    ``r<i>/rest_length`` and ``r<i>/stiffness`` (a body: eigenstrain (n_elements, 3) and
    modulus); with a series, ``series/*`` frames and the ``net/*`` or ``body/*`` mesh.
    """

    n: int
    n_nodes: int
    rule: str
    tau: float
    tau_force: float
    critical_low: float
    critical_high: float
    critical_ratio: float
    critical_by: str
    runs: list[dict[str, Any]]
    kind: str = "run"
    draw: int = 0
    medium: str = "network"
    dof: str = "rest_length"
    non_monotone: int = 0
    bisection: list[dict[str, Any]] = field(default_factory=list)
    learned_qs: bool = True
    steps_qs: float | None = field(default=None, metadata=KEEP_NONE)
    reference_coupling: str | None = field(default=None, metadata=KEEP_NONE)
    coupling: str | None = field(default=None, metadata=KEEP_NONE)
    source_share: float | None = field(default=None, metadata=KEEP_NONE)
    series_ratio: float | None = field(default=None, metadata=KEEP_NONE)
    error0: float | None = None
    error_qs: float | None = None
    fields: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def rule_key(self) -> str:
        """``"gcl"`` on the network, ``"gcl/continuum"`` on the continuum."""
        return self.rule if self.medium == "network" else f"{self.rule}/{self.medium}"

    @property
    def every_run(self) -> list[dict[str, Any]]:
        """The grid runs, then the bisection runs."""
        return [*self.runs, *self.bisection]

    def bracket_closed(self) -> bool:
        """Whether the critical ratio is bracketed on both sides."""
        return self.critical_low > 0 and bool(np.isfinite(self.critical_high))

    def curve(self, i: int) -> dict[str, np.ndarray]:
        """Grid ratio ``i``'s ``times``, ``error``, ``times_qs`` and ``error_qs``."""
        return {k: self.fields[f"r{i}/{k}"] for k in ("times", "error", "times_qs", "error_qs")}
