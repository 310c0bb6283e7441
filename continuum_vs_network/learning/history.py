"""The record of a training run: per-step measurements of every trial, saved as ``.npz``.

Conventions
-----------
``steps`` learning steps give ``steps + 1`` *measurements* (index ``t`` is the network
after ``t`` steps, index 0 the initial one) and ``steps`` *updates* (index ``t`` is the
step from network ``t`` to ``t + 1``). Arrays are ``(trials, steps + 1)`` or
``(trials, steps)``, with a trailing ``n_targets`` axis for per-target values.

Entries that do not exist are NaN, and only those: the steps after a trial stopped early
(``completed[i] < steps``, the reason in ``stop_reason[i]``) and quantities a rule does
not produce (``energy_clamped`` of the exact gradient, which uses no clamped state).

The task error is recorded in both strain conventions under explicit names,
``error_initial`` and ``error_current``; there is no convention-dependent ``error``
(``history.task_error(strain_reference)`` picks one by name, and ``history.strain_reference``
is the convention the rule trained in). A :class:`~.node_tasks.NodeTask` measures no
strain: both hold its error, and ``target_length`` / ``target_strain`` / ``desired_length``
hold the target coordinates, their displacements and the desired coordinates
(``target_rest_length`` stays NaN: there are no target springs).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..network.model import SpringNetwork
from .tasks import AllosteryTask

__all__ = ["LEGACY", "MEASUREMENTS", "UPDATES", "History"]

#: arrays of older files that are no longer recorded (dropped on load): ``error``, the task
#: error in the rule's convention, whose meaning changed with the rule
LEGACY = frozenset({"error"})

#: per-measurement arrays, shape (trials, steps + 1[, n_targets])
MEASUREMENTS = {
    "error_current": "Eq. 26 with strains against the current (learning) rest lengths",
    "error_initial": "Eq. 26 with strains against the task's initial rest lengths",
    "target_strain": "free-state target strains in the rule's strain_reference (n_targets)",
    "target_length": "free-state target lengths r_T (n_targets)",
    "target_rest_length": "target rest lengths L_T (n_targets)",
    "desired_length": "lengths L_ref (S_T + 1) giving the desired strains, L_ref in the "
    "rule's strain_reference (n_targets)",
    "energy_free": "elastic energy of the free state",
    "energy_gradient_free": "|dE^F/dtheta| over the learning springs",
    "residual": "largest net force on a free coordinate in the free state",
    "seconds": "cumulative wall-clock seconds of the trial",
    "measure_seconds": "cumulative seconds spent on free states the rule itself did not need",
    "solves": "cumulative equilibrium solves",
    "factorisations": "cumulative Hessian factorisations (fast path and adjoint)",
    "iterations": "cumulative solver iterations",
}
#: per-update arrays, shape (trials, steps[, n_targets])
UPDATES = {
    "energy_clamped": "elastic energy of the rule's clamped (GCL: nudged) state",
    "energy_gradient_clamped": "|dE^C/dtheta| over the learning springs",
    "clamp_length": "lengths the targets were clamped at (n_targets)",
    "update_norm": "|delta theta|, Euclidean norm of the step",
}


# (substring of a trial's stop reason, its cause), the first match wins
_CAUSES = (
    ("float64's reach", "tol below float64's reach"),
    ("EquilibriumError", "no equilibrium found"),
    ("rest length of spring", "a rest length would reach 0"),
    ("stiffness of spring", "a stiffness would turn negative"),
    ("nudged target length", "a nudged target length would reach 0"),
    ("is not finite", "an update overflowed"),
)


def stop_cause(reason: str) -> str:
    """The cause of an early stop, read off a trial's ``stop_reason`` (``"step t: Error:
    message"``): one of the phrases of ``_CAUSES``, else the error's name (the reason
    itself when it names none)."""
    for text, cause in _CAUSES:
        if text in reason:
            return cause
    parts = reason.split(": ")
    return parts[1] if len(parts) > 2 else reason


@dataclass(frozen=True, eq=False)
class History:
    """Measurements of one training call (several trials); see the module docstring.

    Attributes
    ----------
    steps : int
    seeds : (trials,) int array
    completed : (trials,) int array
        Learning steps done by each trial (``steps`` unless it stopped).
    stop_reason : tuple of str
        Why a trial stopped early ("" when it did not).
    settings : dict
        The rule's and the training call's parameters (plain values).
    data : dict of str -> array
        The arrays named in :data:`MEASUREMENTS` and :data:`UPDATES`; also reachable as
        attributes (``history.error_initial``).
    initial, final : tuple of SpringNetwork
        Each trial's network before and after training.
    tasks : tuple of AllosteryTask
    """

    steps: int
    seeds: NDArray[np.int64]
    completed: NDArray[np.int64]
    stop_reason: tuple[str, ...]
    settings: dict
    data: dict[str, NDArray]
    initial: tuple[SpringNetwork, ...]
    final: tuple[SpringNetwork, ...]
    tasks: tuple[AllosteryTask, ...]

    def __post_init__(self) -> None:
        n = len(self.seeds)
        for name, arr in self.data.items():
            want = self.steps + 1 if name in MEASUREMENTS else self.steps
            if name not in MEASUREMENTS and name not in UPDATES:
                raise ValueError(f"unknown history array {name!r}")
            if arr.shape[:2] != (n, want):
                raise ValueError(f"{name} must start with shape ({n}, {want}), got {arr.shape}")
            arr.setflags(write=False)
        if not (len(self.initial) == len(self.final) == len(self.tasks) == n):
            raise ValueError("initial, final and tasks need one entry per trial")

    def __getattr__(self, name: str) -> NDArray:
        data = self.__dict__.get("data", {})
        if name in data:
            return data[name]
        raise AttributeError(name)

    @property
    def trials(self) -> int:
        return len(self.seeds)

    @property
    def strain_reference(self) -> str:
        """The strain convention the rule trained in (``"initial"`` or ``"current"``)."""
        return str(self.settings.get("strain_reference", "initial"))

    def stop_causes(self) -> dict[str, int]:
        """How many trials stopped early for each :func:`stop_cause` (most frequent first)."""
        causes: dict[str, int] = {}
        for done, reason in zip(self.completed, self.stop_reason):
            if done < self.steps:
                cause = stop_cause(reason)
                causes[cause] = causes.get(cause, 0) + 1
        return dict(sorted(causes.items(), key=lambda item: -item[1]))

    def task_error(self, strain_reference: str) -> NDArray:
        """Eq. 26 with strains against the ``"initial"`` or the ``"current"`` rest lengths,
        (trials, steps + 1): ``error_initial`` or ``error_current``."""
        if strain_reference not in ("initial", "current"):
            raise ValueError(
                f"strain_reference must be 'initial' or 'current', got {strain_reference!r}"
            )
        return self.data[f"error_{strain_reference}"]

    def __repr__(self) -> str:
        return (
            f"History(rule={self.settings.get('rule')!r}, trials={self.trials}, "
            f"steps={self.steps}, completed={self.completed.tolist()})"
        )

    def trial(self, i: int) -> History:
        """A history holding trial ``i`` only."""
        return dataclasses.replace(
            self,
            seeds=self.seeds[i : i + 1],
            completed=self.completed[i : i + 1],
            stop_reason=self.stop_reason[i : i + 1],
            data={k: v[i : i + 1].copy() for k, v in self.data.items()},
            initial=self.initial[i : i + 1],
            final=self.final[i : i + 1],
            tasks=self.tasks[i : i + 1],
        )

    # -- files ------------------------------------------------------------------------
    def save(self, path: str | Path) -> Path:
        """Write the history to ``path`` (``.npz``); returns the path written."""
        path = Path(path)
        arrays: dict[str, NDArray] = {f"data/{k}": v for k, v in self.data.items()}
        arrays["steps"] = np.array(self.steps)
        arrays["seeds"] = self.seeds
        arrays["completed"] = self.completed
        arrays["meta"] = np.array(
            json.dumps({"settings": self.settings, "stop_reason": list(self.stop_reason)})
        )
        for i in range(self.trials):
            arrays.update(_net_arrays(f"initial/{i}", self.initial[i]))
            arrays.update(_net_arrays(f"final/{i}", self.final[i]))
            arrays.update(_task_arrays(f"task/{i}", self.tasks[i]))
        with open(path, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        return path

    @classmethod
    def load(cls, path: str | Path) -> History:
        """Read a history written by :meth:`save`."""
        with np.load(Path(path), allow_pickle=False) as z:
            files = {k: z[k] for k in z.files}
        meta = json.loads(str(files["meta"]))
        n = len(files["seeds"])
        return cls(
            steps=int(files["steps"]),
            seeds=files["seeds"],
            completed=files["completed"],
            stop_reason=tuple(meta["stop_reason"]),
            settings=meta["settings"],
            data={
                k[5:]: v for k, v in files.items() if k.startswith("data/") and k[5:] not in LEGACY
            },
            initial=tuple(_net_from(files, f"initial/{i}") for i in range(n)),
            final=tuple(_net_from(files, f"final/{i}") for i in range(n)),
            tasks=tuple(_task_from(files, f"task/{i}") for i in range(n)),
        )


_NET_FIELDS = ("positions", "springs", "stiffness", "rest_length")
_TASK_FIELDS = (
    "sources",
    "source_strain",
    "targets",
    "target_strain",
    "source_rest_length",
    "target_rest_length",
    "pinned",
)


def _net_arrays(prefix: str, net: SpringNetwork) -> dict[str, NDArray]:
    if not isinstance(net, SpringNetwork):  # another learning medium (.medium)
        from .medium import medium_arrays

        return medium_arrays(prefix, net)
    return {f"{prefix}/{f}": getattr(net, f) for f in _NET_FIELDS}


def _net_from(files: dict, prefix: str) -> SpringNetwork:
    if f"{prefix}/__kind__" in files:
        from .medium import medium_from_arrays

        return medium_from_arrays(files, prefix)
    return SpringNetwork(*(files[f"{prefix}/{f}"] for f in _NET_FIELDS))


def _task_arrays(prefix: str, task: AllosteryTask) -> dict[str, NDArray]:
    if not isinstance(task, AllosteryTask):
        from .medium import medium_arrays

        return medium_arrays(prefix, task)
    return {f"{prefix}/{f}": getattr(task, f) for f in _TASK_FIELDS}


def _task_from(files: dict, prefix: str) -> AllosteryTask:
    if f"{prefix}/__kind__" in files:
        from .medium import medium_from_arrays

        return medium_from_arrays(files, prefix)
    return AllosteryTask(**{f: files[f"{prefix}/{f}"] for f in _TASK_FIELDS})
