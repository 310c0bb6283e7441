"""Modulus, eigenstrain or both, through one density filter, trained on several examples.

:class:`FilteredFields` is a learning medium (:mod:`~continuum_vs_network.learning.medium`)
on a :class:`~.filtered.FilteredModulus` that learns the modulus design ``rho`` (dof
``"modulus"``/``"stiffness"``), the eigenstrain design ``e`` (``"eigenstrain"``/
``"rest_length"``) or both (``"both"``), each through the same density filter ``H``:

    s = H rho,   eps0 = scale * H e     (e: (n, 3) Mandel components, units of ``scale``)

``scale`` is the task's largest strain, so ``e`` is O(1) as ``rho`` is and one raw rate
``alpha`` moves both by comparable fractions (the network rates scale a rest-length step by
the same strain). Per-area signals are carried back through the filter as in
:class:`~.filtered.FilteredModulus`; ``"both"`` stacks them as columns ``(rho, e_xx, e_yy,
e_xy)`` of an (n, 4) array, the shape the rule objects mask element by element.

Its task is a :class:`MaterialExamples`: one or more :class:`~.material_task.MaterialTask`
on the same springs (the task and its rest example, say). States are
:class:`ExamplesState` (one equilibrium per example; target strains side by side), the
error is the sum of the examples' errors, and the local and exact gradients are the sums of
the per-example ones: what a network's :class:`~continuum_vs_network.learning.TaskSet`
does, through the medium protocol (the rule objects take one task on a medium).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .element_operators import tensor
from .learning_states import free_state_measurements

__all__ = ["ExamplesState", "FilteredFields", "MaterialExamples", "filtered_fields"]

_FIELD = {
    "modulus": "modulus", "stiffness": "modulus", "eigenstrain": "eigenstrain",
    "rest_length": "eigenstrain", "both": "both",
}  # fmt: skip


@dataclass(frozen=True, eq=False)
class MaterialExamples:
    """Several MaterialTasks on the same material springs, trained together (``tasks``)."""

    tasks: tuple

    def __post_init__(self) -> None:
        if not self.tasks:
            raise ValueError("MaterialExamples needs at least one task")

    @property
    def n_sources(self) -> int:
        return sum(t.n_sources for t in self.tasks)

    @property
    def n_targets(self) -> int:
        return sum(t.n_targets for t in self.tasks)

    @property
    def source_strain(self) -> NDArray[np.float64]:
        return np.concatenate([t.source_strain for t in self.tasks])

    @property
    def target_strain(self) -> NDArray[np.float64]:
        return np.concatenate([t.target_strain for t in self.tasks])

    @property
    def target_length(self) -> NDArray[np.float64]:
        return np.concatenate([t.target_length for t in self.tasks])

    def split(self, values: ArrayLike) -> list[NDArray[np.float64]]:
        """Per-example parts of a per-target array (n_targets,)."""
        v = np.asarray(values, float)
        cuts = np.cumsum([t.n_targets for t in self.tasks])[:-1]
        return np.split(v, cuts)

    def error(self, target_strain: ArrayLike) -> float:
        """The sum of the examples' errors (Eq. 26 each)."""
        return float(sum(t.error(s) for t, s in zip(self.tasks, self.split(target_strain))))


@dataclass(frozen=True, eq=False)
class ExamplesState:
    """One equilibrium per example (``states``); what train reads, summed or side by side."""

    states: tuple

    @property
    def target_strain(self) -> NDArray[np.float64]:
        return np.concatenate([s.target_strain for s in self.states])

    @property
    def energy(self) -> float:
        return float(sum(s.energy for s in self.states))

    @property
    def residual(self) -> float:
        return float(max(s.residual for s in self.states))

    @property
    def positions(self) -> Any:
        return self.states[0].positions


@dataclass(frozen=True, eq=False)
class FilteredFields:
    """Filtered modulus and eigenstrain designs of a body (see the module).

    Build with :func:`filtered_fields`. Attributes: ``filtered`` (the FilteredModulus that
    holds ``rho``, ``H`` and the body), ``strain_design`` (n, 3) ``e``, ``scale``.
    """

    filtered: Any
    strain_design: NDArray[np.float64]
    scale: float

    # -- what callers read of a body --------------------------------------------------
    @property
    def body(self) -> Any:
        return self.filtered.body

    @property
    def n_elements(self) -> int:
        return self.filtered.n_elements

    @property
    def area(self) -> NDArray[np.float64]:
        return self.filtered.area

    @property
    def modulus(self) -> NDArray[np.float64]:
        return self.filtered.modulus

    @property
    def eigenstrain(self) -> NDArray[np.float64]:
        return self.filtered.eigenstrain

    @property
    def _cache(self) -> dict:
        return self.body._cache

    def with_designs(self, rho: ArrayLike | None = None, e: ArrayLike | None = None):
        """A copy with a new modulus design ``rho`` and/or eigenstrain design ``e``."""
        f = self.filtered if rho is None else self.filtered.with_design(rho)
        e = self.strain_design if e is None else np.array(e, dtype=float).reshape(-1, 3)
        if not np.all(np.isfinite(e)):
            raise ValueError("eigenstrain design must be finite")
        e.setflags(write=False)
        body = f.body.with_eigenstrain(tensor(self.scale * (f.weights @ e)))
        return dataclasses.replace(self, filtered=dataclasses.replace(f, body=body),
                                   strain_design=e)  # fmt: skip

    def _signal(self, dof: str, grad) -> NDArray[np.float64]:
        """``grad(field)`` (the body's per-area signal) pulled back to ``dof``'s designs."""
        d, parts = self.learning_dof(dof), {}
        if d in ("modulus", "both"):
            parts["modulus"] = self.filtered.pull_back(grad("modulus"))
        if d in ("eigenstrain", "both"):
            parts["eigenstrain"] = self.scale * self.filtered.pull_back(grad("eigenstrain"))
        if d == "both":
            return np.column_stack([parts["modulus"], parts["eigenstrain"]])
        return parts[d]

    # -- the learning-medium protocol --------------------------------------------------
    def learning_dof(self, dof: str) -> str:
        """``"modulus"`` (``"stiffness"``), ``"eigenstrain"`` (``"rest_length"``) or
        ``"both"``; the field that learns."""
        if dof not in _FIELD:
            raise ValueError(f"dof must be one of {sorted(_FIELD)} on FilteredFields, got {dof!r}")
        return _FIELD[dof]

    def parameters(self, dof: str) -> NDArray[np.float64]:
        d = self.learning_dof(dof)
        if d == "modulus":
            return self.filtered.design
        if d == "eigenstrain":
            return self.strain_design
        return np.column_stack([self.filtered.design, self.strain_design])

    def with_parameters(self, dof: str, values: ArrayLike) -> FilteredFields:
        d, v = self.learning_dof(dof), np.asarray(values, float)
        if d == "modulus":
            return self.with_designs(rho=v)
        if d == "eigenstrain":
            return self.with_designs(e=v)
        return self.with_designs(rho=v[:, 0], e=v[:, 1:])

    def check_task(self, task: Any) -> None:
        if not isinstance(task, MaterialExamples):
            raise ValueError(f"FilteredFields learns MaterialExamples, got {type(task).__name__}")
        for t in task.tasks:
            self.body.check_task(t)

    def free_state(self, task: Any, *, tracker: Any = None) -> ExamplesState:
        return ExamplesState(tuple(self.body.free_state(t, tracker=tracker) for t in task.tasks))

    def clamped_state(self, task: Any, target_strain: ArrayLike, *, tracker: Any = None):
        parts = task.split(target_strain)
        return ExamplesState(
            tuple(self.body.clamped_state(t, s, tracker=tracker) for t, s in zip(task.tasks, parts))
        )

    def local_gradient(self, state: Any, dof: str, *, minus: Any = None) -> NDArray[np.float64]:
        others = [None] * len(state.states) if minus is None else minus.states
        return sum(
            self._signal(dof, lambda f, s=s, m=m: self.body.local_gradient(s, f, minus=m))
            for s, m in zip(state.states, others)
        )

    def task_gradient(
        self, task: Any, free: Any, dof: str, *, cost: str = "strain", tracker: Any = None
    ) -> NDArray[np.float64]:
        return sum(
            self._signal(dof, lambda f, t=t, s=s: self.body.task_gradient(t, s, f, cost=cost,
                                                                     tracker=tracker))
            for t, s in zip(task.tasks, free.states)
        )  # fmt: skip

    def learning_mask(
        self, task: Any, *, learn_sources: bool = True, learn_targets: bool = True
    ) -> NDArray[np.bool_]:
        """The body's mask of the examples' springs (a MaterialExamples or one task)."""
        one = task.tasks[0] if isinstance(task, MaterialExamples) else task
        return self.body.learning_mask(
            one, learn_sources=learn_sources, learn_targets=learn_targets
        )

    def floor(self, dof: str, raw: NDArray, minimum: float | None) -> NDArray:
        """``raw`` with decreases of the modulus design stopped at ``minimum``."""
        d = self.learning_dof(dof)
        if minimum is None or d == "eigenstrain":
            return raw
        if d == "modulus":
            return self.filtered.floor("modulus", raw, minimum)
        out = np.array(raw, dtype=float)
        out[:, 0] = self.filtered.floor("modulus", out[:, 0], minimum)
        return out

    def apply_update(self, dof: str, delta: ArrayLike) -> FilteredFields:
        d = self.learning_dof(dof)
        new = self.parameters(d) + np.asarray(delta, float)
        rho = new if d == "modulus" else new[:, 0] if d == "both" else None
        if rho is not None and np.any(rho < 0):
            raise ValueError("the modulus design would become < 0; set min_stiffness")
        return self.with_parameters(d, new)

    def measurements(self, task: Any, free: Any, dof: str, mask: NDArray) -> dict[str, Any]:
        """What train records of a free state (every example's targets side by side;
        the gradient is this medium's, on the designs)."""
        return free_state_measurements(self, task, free, dof, mask)

    def vertex_positions(self, u: ArrayLike) -> NDArray[np.float64]:
        return self.body.vertex_positions(u)

    def to_arrays(self) -> dict[str, NDArray]:
        return {
            **self.filtered.to_arrays(),
            "strain_design": self.strain_design,
            "scale": np.array(self.scale),
        }

    def __repr__(self) -> str:
        return f"FilteredFields({self.filtered!r}, scale={self.scale:g})"


def filtered_fields(filtered: Any, scale: float) -> FilteredFields:
    """:class:`FilteredFields` on a FilteredModulus, eigenstrain design 0, strain unit
    ``scale`` (> 0: the task's largest strain)."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a finite number > 0, got {scale!r}")
    out = FilteredFields(filtered, np.zeros((filtered.n_elements, 3)), float(scale))
    return out.with_designs(e=out.strain_design)
