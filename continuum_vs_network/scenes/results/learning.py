"""Results of the learning kind's measurement units: the coupling of every trained
network, its source sweeps, the rule's step against the exact gradient, and the fields
kept for mesh export."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["CouplingResult", "FieldsResult", "GradientResult", "SweepsResult"]


@dataclass(frozen=True)
class CouplingResult:
    """The coupling of every trial's trained network (a ``coupling/<run>`` unit).

    ``scales`` (n_scales,): the source strains' multiples solved; ``sweep`` (trials,
    n_scales, n_targets): the target strains there; ``initial_off`` and ``initial_on``
    (trials, n_targets): the untrained network's target strains with the sources off and
    on; ``desired`` (trials, n_targets); ``share`` (trials,): the source share (NaN: not
    measured); ``verdicts``: per trial, coupled / partially coupled / decoupled / not
    measured; ``failed``: why a trial was not measured.
    """

    scales: np.ndarray
    sweep: np.ndarray
    initial_off: np.ndarray
    initial_on: np.ndarray
    desired: np.ndarray
    share: np.ndarray
    verdicts: list[str]
    failed: list[str]


@dataclass(frozen=True)
class SweepsResult:
    """Source sweeps of every trial's final network (a ``sweeps/<solver>/<rule>`` unit):
    ``source_strain`` and ``target_strain`` (trials, points), the task's ``desired``
    target and ``task_source`` strains (trials,), and how many trials ``failed`` (every
    point NaN)."""

    source_strain: np.ndarray
    target_strain: np.ndarray
    desired: np.ndarray
    task_source: np.ndarray
    failed: int


@dataclass(frozen=True)
class GradientResult:
    """Cosine of a rule's step with the exact gradient step (a ``gradient/<rule>`` unit):
    ``cosine`` (trials, 2) at each trial's initial and final network; ``cost``: the task
    error the gradient descends ("strain" or "length")."""

    cosine: np.ndarray
    rule: str
    cost: str


@dataclass(frozen=True)
class FieldsResult:
    """Initial and final networks (and their trajectories) of a run's trials for mesh export
    (a ``fields/<solver>/<rule>`` unit): ``fields`` keyed ``t<k>/initial/...``,
    ``t<k>/final/...``, ``t<k>/series/...``, ``t<k>/sources`` and ``t<k>/targets``;
    ``trials``: the trials stored; ``failed``: what could not be solved."""

    trials: list[int]
    failed: list[str]
    fields: Mapping[str, np.ndarray] = field(default_factory=dict)
