"""Results of the ``continuum_mechanism`` units (:mod:`..units_mechanism`).

Common to them: ``ratio`` is the final C/C0 (the error against the untrained uniform body);
``error`` (steps + 1,) or (evaluations,) is C/C0 along the run; ``seconds`` and ``solves``
are the run's wall-clock seconds and linear solves, ``seconds_trace`` and ``solves_trace``
the same, cumulative, along ``error`` (stored as ``seconds`` and ``solves``); ``response``
is the target's strain over the source's (``S_T / S_S``; asked: the scene's ``ratio``);
``n_elements`` counts the mesh's triangles. ``first_below``: the first step with C/C0 <=
``LEVEL`` (None: none; stored as null); ``source_share``: the share of the trained
target's strain due to the source, ``coupling`` its verdict and ``outcome`` the run's
(coupling vocabulary). A field on a mesh (learn, optimum, SIMP, inverter) comes with it:
``field`` (n_elements,) per element, ``coarse`` the same averaged onto the ``refine = 0``
mesh, ``points`` (n_points, 2), ``triangles`` (n_elements, 3) and the elements' ``area``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from . import KEEP_NONE

__all__ = [
    "CLASSES",
    "DofOptimumResult",
    "DofResult",
    "InverterResult",
    "LatticeResult",
    "LearnResult",
    "OptimumResult",
    "SimpResult",
]


@dataclass(frozen=True)
class _OnMesh:
    """A learned field on its mesh: ``field`` (n_elements,), its ``coarse`` average on the
    lattice triangles, element ``area``, and the mesh's ``points`` (n_points, 2) and
    ``triangles`` (n_elements, 3): for the figures and mesh export."""

    field: np.ndarray
    coarse: np.ndarray
    points: np.ndarray
    triangles: np.ndarray
    area: np.ndarray


@dataclass(frozen=True)
class _Training:
    """What a trained body records: final C/C0 ``ratio``; the first step at C/C0 <= LEVEL
    (``first_below``, None: never, stored as null); the trained ``response`` S_T / S_S
    and the ratio ``asked``; ``rest_error``: the rest example's error, trained; the
    coupling (``source_share``, ``coupling``) and the verdict (``outcome``); elements;
    wall-clock ``seconds`` and linear ``solves`` in all; traces (steps + 1,): ``error``
    (C), ``seconds_trace`` and ``solves_trace`` (stored as ``seconds`` and ``solves``)."""

    ratio: float
    first_below: int | None = dataclasses.field(metadata=KEEP_NONE)
    response: float
    asked: float
    rest_error: float
    source_share: float
    coupling: str
    outcome: str
    n_elements: int
    seconds: float
    solves: float
    error: np.ndarray
    seconds_trace: np.ndarray = dataclasses.field(metadata={"stored": "seconds"})
    solves_trace: np.ndarray = dataclasses.field(metadata={"stored": "solves"})


@dataclass(frozen=True)
class LearnResult(_Training, _OnMesh):
    """The filtered modulus field trained by ``rule`` at ``rate`` on the mesh ``h /
    2^refine`` (a ``continuum_mechanism/learn/...`` unit). ``field``: the learned modulus;
    ``frozen`` (n_elements,) bool: the elements the rule leaves (the springs' discs);
    ``response_initial``: S_T / S_S of the uniform body; ``contrast``: max / min modulus;
    ``coarse`` and ``area``, on ``points`` and ``triangles``: for the figures and mesh
    export."""

    refine: int
    rule: str
    rate: str
    response_initial: float
    contrast: float
    frozen: np.ndarray


@dataclass(frozen=True)
class DofResult(_Training):
    """GCL of the filtered eigenstrain field, or of both fields (``dof``), on ``h /
    2^refine``, with the rest example (``rest``) or on the task alone (a
    ``continuum_mechanism/dof/...`` unit). ``completed``: steps run; ``eigenstrain_unit``:
    the eigenstrain design's strain unit; ``modulus`` and ``dilation`` (n_elements,): the
    trained modulus and mean normal eigenstrain."""

    refine: int
    dof: str
    rest: bool
    completed: int
    eigenstrain_unit: float
    modulus: np.ndarray
    dilation: np.ndarray


@dataclass(frozen=True)
class _Search:
    """What an exact optimum records: its C/C0 ``ratio``, L-BFGS-B's ``evaluations``, the
    linear ``solves``, wall-clock ``seconds``, ``converged`` and its ``message``, the
    design's ``contrast`` (max / min modulus) and ``response`` S_T / S_S, elements, and per
    evaluation ``error`` (C) and ``seconds_trace`` (stored as ``seconds``)."""

    ratio: float
    evaluations: int
    solves: int
    seconds: float
    converged: bool
    message: str
    contrast: float
    response: float
    n_elements: int
    error: np.ndarray
    seconds_trace: np.ndarray = dataclasses.field(metadata={"stored": "seconds"})


@dataclass(frozen=True)
class OptimumResult(_Search, _OnMesh):
    """The exact optimum of the filtered modulus field on ``h / 2^refine`` (a
    ``continuum_mechanism/optimum/...`` unit; ``evaluations`` = ``solves``); ``field`` the
    optimal modulus."""

    refine: int


@dataclass(frozen=True)
class DofOptimumResult(_Search):
    """The exact optimum of the eigenstrain field, or of both (``dof``), on ``h / 2^refine``
    with the task and its rest example (a ``continuum_mechanism/dof_optimum/...`` unit).
    ``feasible``: its C/C0 <= ``MET_AT``; ``solves``: one free state per example per
    evaluation; ``rest_error``: the rest example's error at the optimum; ``modulus`` and
    ``dilation`` as :class:`DofResult`."""

    refine: int
    dof: str
    feasible: bool
    rest_error: float
    eigenstrain_unit: float
    modulus: np.ndarray
    dilation: np.ndarray


@dataclass(frozen=True)
class SimpResult(_OnMesh):
    """SIMP on the allosteric task on the ``refine = 0`` mesh (a ``continuum_mechanism/simp``
    or ``simp_solid`` unit): modulus ``e_min + x^3 (e_max - e_min)``, ``method`` (``"mma"``
    or ``"oc"``), ``iterations``, the final ``volume`` fraction; ``density`` (n_elements,)
    the design ``x``, ``field`` its modulus; ``error`` the objective C/C0 per evaluation.
    Records from before ``method`` and the range were stored read as OC over ``1e-4 .. 1``."""

    ratio: float
    solves: int
    seconds: float
    iterations: int
    volume: float
    response: float
    n_elements: int
    error: np.ndarray
    seconds_trace: np.ndarray = dataclasses.field(metadata={"stored": "seconds"})
    density: np.ndarray
    method: str = "oc"
    e_min: float = 1e-4
    e_max: float = 1.0


@dataclass(frozen=True)
class InverterResult(_OnMesh):
    """SIMP + OC on Sigmund's force inverter (the ``continuum_mechanism/inverter`` unit):
    output ``u_out`` optimised and ``u_out_initial`` of the uniform plate, input ``u_in``,
    ``advantage`` -u_out / u_in; the springs ``k_in``, ``k_out`` and input ``force``; the
    final ``volume`` fraction. ``output`` (iterations + 1,): u_out per iteration;
    ``density`` and ``field`` (n_elements,): the SIMP density (both)."""

    u_out: float
    u_out_initial: float
    u_in: float
    advantage: float
    volume: float
    solves: int
    seconds: float
    n_elements: int
    k_in: float
    k_out: float
    force: float
    output: np.ndarray
    seconds_trace: np.ndarray = dataclasses.field(metadata={"stored": "seconds"})
    density: np.ndarray


@dataclass(frozen=True)
class LatticeResult:
    """GCL of a triangular lattice's stiffnesses on the same task at lattice constant
    ``spacing`` = h / 2^refine (a ``continuum_mechanism/lattice/...`` unit): ``n_nodes``,
    ``n_springs``, ``completed`` steps; ``positions`` (n_nodes, 2), ``springs`` (n_springs,
    2) and the learned stiffnesses ``k`` (n_springs,)."""

    refine: int
    ratio: float
    first_below: int | None = dataclasses.field(metadata=KEEP_NONE)
    source_share: float
    coupling: str
    outcome: str
    n_nodes: int
    n_springs: int
    spacing: float
    completed: int
    seconds: float
    solves: float
    error: np.ndarray
    seconds_trace: np.ndarray = dataclasses.field(metadata={"stored": "seconds"})
    solves_trace: np.ndarray = dataclasses.field(metadata={"stored": "solves"})
    positions: np.ndarray
    springs: np.ndarray
    k: np.ndarray


#: the result class of a unit, by the start of its key (:func:`~.read_result`)
CLASSES = {
    "continuum_mechanism/learn/": LearnResult,
    "continuum_mechanism/dof/": DofResult,
    "continuum_mechanism/optimum/": OptimumResult,
    "continuum_mechanism/dof_optimum/": DofOptimumResult,
    "continuum_mechanism/simp": SimpResult,
    "continuum_mechanism/inverter": InverterResult,
    "continuum_mechanism/lattice/": LatticeResult,
}
