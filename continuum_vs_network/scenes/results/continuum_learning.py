"""Results of the continuum_learning units: a rule trained on the lattice and on the
continuum of the same shape, and the trained media's relaxation after the sources switch
on."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["CLASSES", "ContinuumRun", "LearnedRelaxationResult", "NetworkRun"]


@dataclass(frozen=True)
class _Training:
    """What a training run records: ``error`` (steps + 1,) C against the initial state,
    ``seconds_trace`` (steps + 1,) wall-clock (stored as ``seconds``); steps ``completed``
    and why it stopped; factorisations and solves of the last step; the rule's settings;
    the coupling measurement (``source_share``, ``coupling``) and the verdict
    (``outcome``)."""

    error: np.ndarray
    seconds_trace: np.ndarray = field(metadata={"stored": "seconds"})
    completed: int
    stop_reason: str
    factorisations: float
    solves: float
    rule: dict[str, Any]
    source_share: float
    coupling: str
    outcome: str


@dataclass(frozen=True)
class NetworkRun(_Training):
    """The lattice trained with the rule (a ``continuum_learning/network/<rule>`` unit):
    ``coarse`` (n_triangles, 3) the learned rest strain of each lattice triangle (Mandel
    components), on ``points`` (n_nodes, 2) and ``triangles`` (n_triangles, 3);
    ``rest_change`` (n_springs,) L / L0 - 1; ``sources``, ``targets`` and ``springs``."""

    coarse: np.ndarray
    points: np.ndarray
    triangles: np.ndarray
    rest_change: np.ndarray
    sources: np.ndarray
    targets: np.ndarray
    springs: np.ndarray
    n_nodes: int
    n_springs: int


@dataclass(frozen=True)
class ContinuumRun(_Training):
    """The continuum trained with the rule at one refinement (a
    ``continuum_learning/refine<r>/<rule>`` or ``continuum_learning/paper/refine<r>`` unit):
    ``field`` (n_elements, 3) the learned eigenstrain, ``coarse`` (n_triangles, 3) its
    average on the lattice triangles, element ``area`` and ``frozen`` (the elements the
    rule does not change), on ``points`` and ``triangles``; the mesh's ``refine``, element
    ``order``, DOFs and elements; ``build_seconds`` of the bodies; the ``task`` ("stern" or
    "paper") and its source and target strains."""

    field: np.ndarray
    coarse: np.ndarray
    area: np.ndarray
    frozen: np.ndarray
    points: np.ndarray
    triangles: np.ndarray
    refine: int
    order: int
    n_dofs: int
    n_elements: int
    build_seconds: float
    task: str
    source_strain: list[float]
    target_strain: list[float]


@dataclass(frozen=True)
class LearnedRelaxationResult:
    """Target strains after the sources switch on, the trained network (strain-clamped and
    node-clamped) and the trained continuum (the ``continuum_learning/relaxation`` unit).

    Traces (T,) and (T, n_targets): ``times`` / ``continuum_strain``, ``network_times`` /
    ``network_strain``, ``network_nodes_times`` / ``network_nodes_strain`` (node clamps);
    ``*_final`` (n_targets,): the static equilibrium's strains. ``*_settle``: when the
    strains settle at their last value; ``*_gap``: the last value's distance from the
    static one; ``rod_strain_error``: the largest strain error of the clamping rods (of
    stiffness ``rod_factor`` times the springs'); wall-clock seconds; ``dt`` and ``t_end``
    in units of drag / stiffness. The node-clamped run and the rods' values are None in
    results stored before the network was strain-clamped.
    """

    times: np.ndarray
    continuum_strain: np.ndarray
    continuum_final: np.ndarray
    network_times: np.ndarray
    network_strain: np.ndarray
    network_final: np.ndarray
    rule: str
    continuum_settle: float
    network_settle: float
    continuum_gap: float
    network_gap: float
    continuum_seconds: float
    network_seconds: float
    dt: float
    t_end: float
    network_nodes_times: np.ndarray | None = None
    network_nodes_strain: np.ndarray | None = None
    network_nodes_settle: float | None = None
    network_nodes_gap: float | None = None
    network_nodes_seconds: float | None = None
    rod_factor: float | None = None
    rod_strain_error: float | None = None


#: the result class of a unit, by the start of its key (:func:`~.read_result`; the first
#: that matches)
CLASSES = {
    "continuum_learning/relaxation": LearnedRelaxationResult,
    "continuum_learning/network/": NetworkRun,
    "continuum_learning/": ContinuumRun,
}
