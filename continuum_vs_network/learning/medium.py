"""One rule, two media: what a learning medium other than a spring network provides.

The rule objects (:class:`~.rules.CoupledLearning`, :class:`~.rules.ProspectiveConfiguration`,
:class:`~.rules.ExactGradient`) and :func:`~.train.train` serve spring networks through
their own code path (unchanged) and any other medium through the small protocol below:
the rule asks the medium for its free and clamped states and for local quantities; the
medium knows its physics. :class:`~continuum_vs_network.continuum.LearnableBody` (an
elastic continuum with learnable eigenstrain and modulus fields) implements it.

A rule's ``dof`` names a role: ``"rest_length"`` (the rest state: a spring's rest length, a
material's eigenstrain) or ``"stiffness"`` (a spring's stiffness, a material's modulus); a
medium maps it to its own field (:meth:`Medium.learning_dof`).

Local rules, for a medium with energy ``E(u; theta)`` (envelope theorem, as for springs)::

    coupled learning      d theta = -(alpha / eta) [dE/dtheta(u^C) - dE/dtheta(u^F)]
    prospective config.   d theta = -alpha dE/dtheta(u^C)
    exact gradient        d theta = -alpha dC/dtheta

with every derivative per unit of the learning unit's size (per element area in a
continuum), so that a learning rate is a property of the material and not of the mesh.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Medium",
    "check_rule_on_medium",
    "is_medium",
    "learning_arrays",
    "medium_arrays",
    "medium_from_arrays",
    "with_learning_arrays",
]


@runtime_checkable
class Medium(Protocol):
    """A learning medium (see the module docstring). States carry ``target_strain``,
    ``energy``, ``residual`` and ``positions``."""

    def learning_dof(self, dof: str) -> str: ...

    def check_task(self, task: Any) -> None: ...

    def free_state(self, task: Any, *, tracker: Any = None) -> Any: ...

    def clamped_state(self, task: Any, target_strain: NDArray, *, tracker: Any = None) -> Any: ...

    def local_gradient(self, state: Any, dof: str, *, minus: Any = None) -> NDArray: ...

    def task_gradient(
        self, task: Any, free: Any, dof: str, *, cost: str = "strain", tracker: Any = None
    ) -> NDArray: ...

    def learning_mask(
        self, task: Any, *, learn_sources: bool = True, learn_targets: bool = True
    ) -> NDArray: ...

    def floor(self, dof: str, raw: NDArray, minimum: float | None) -> NDArray: ...

    def apply_update(self, dof: str, delta: NDArray) -> Any: ...

    def parameters(self, dof: str) -> NDArray: ...

    def measurements(self, task: Any, free: Any, dof: str, mask: NDArray) -> dict: ...

    def to_arrays(self) -> dict[str, NDArray]: ...


def is_medium(obj: object) -> bool:
    """Whether ``obj`` implements the :class:`Medium` protocol."""
    return isinstance(obj, Medium)


def check_rule_on_medium(medium: Any, task: Any, rule: Any) -> None:
    """Refuse a rule or task the medium cannot learn (strain convention, learned dof, task).

    Raises
    ------
    ValueError
        ``rule.strain_reference`` is not ``"initial"`` (a continuum's material springs
        measure strain against the undeformed body), or the medium refuses the rule's dof
        or the task.
    """
    if rule.strain_reference != "initial":
        raise ValueError(
            "a continuum's material springs measure strain against the undeformed body: "
            "use strain_reference='initial'"
        )
    medium.learning_dof(rule.dof)
    medium.check_task(task)


def learning_arrays(net: Any) -> dict[str, NDArray]:
    """The arrays that learn, by name: a network's ``rest_length`` and ``stiffness``, a
    continuum's ``eigenstrain`` and ``modulus``."""
    if is_medium(net):
        arrays = net.to_arrays()
        return {"eigenstrain": arrays["eigenstrain"], "modulus": arrays["modulus"]}
    return {"rest_length": net.rest_length, "stiffness": net.stiffness}


def with_learning_arrays(net: Any, arrays: dict[str, NDArray]) -> Any:
    """``net`` with the arrays of :func:`learning_arrays` replaced."""
    if is_medium(net):
        return net.with_eigenstrain(arrays["eigenstrain"]).with_modulus(arrays["modulus"])
    return net.with_rest_length(arrays["rest_length"]).with_stiffness(arrays["stiffness"])


_KINDS = {
    "LearnableBody": ("continuum_vs_network.continuum.learnable", "LearnableBody"),
    "FilteredModulus": ("continuum_vs_network.continuum.filtered", "FilteredModulus"),
}
_TASKS = {
    "MaterialTask": ("continuum_vs_network.continuum.material_task", "MaterialTask"),
    "TaskSet": ("continuum_vs_network.learning.examples", "TaskSet"),
    "NodeTask": ("continuum_vs_network.learning.node_tasks", "NodeTask"),
}


def medium_arrays(prefix: str, obj: Any) -> dict[str, NDArray]:
    """Arrays of a medium or a medium's task for a file, with the class name recorded."""
    out = {f"{prefix}/{k}": v for k, v in obj.to_arrays().items()}
    out[f"{prefix}/__kind__"] = np.array(type(obj).__name__)
    return out


def medium_from_arrays(files: dict[str, NDArray], prefix: str) -> Any:
    """Inverse of :func:`medium_arrays`."""
    import importlib

    kind = str(files[f"{prefix}/__kind__"])
    table = {**_KINDS, **_TASKS}
    if kind not in table:
        raise ValueError(f"unknown medium kind {kind!r} in the file")
    module, name = table[kind]
    cls = getattr(importlib.import_module(module), name)
    n = len(prefix) + 1
    arrays = {k[n:]: v for k, v in files.items() if k.startswith(prefix + "/")}
    arrays.pop("__kind__")
    return cls.from_arrays(arrays)
