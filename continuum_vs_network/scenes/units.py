"""The shared types of a scene's work: :class:`Unit`, :class:`UnitContext`, :class:`UnitResult`.

The runner (:mod:`.runner`) plans and stores units; the ``units_*`` modules define them.
Both import this module and neither imports the other at module level, so there is no
import circle between the runner and the units it runs.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from numpy.typing import NDArray

__all__ = ["Unit", "UnitContext", "UnitResult"]


@dataclass(frozen=True, eq=False)
class Unit:
    """One piece of a scene's work.

    Attributes
    ----------
    key : str
        Unique within the scene, ``/``-separated (``"train/newton/gcl/noise0/trial3"``).
    func : callable ``f(scene, params, ctx) -> (arrays, meta)``, a result dataclass
        (:mod:`.results`) or a ``History``
        A module-level function (it is sent to worker processes by reference).
    params : dict
        JSON-able parameters of this unit.
    depends : dict
        JSON-able settings the result depends on besides ``params`` (fingerprinted).
    phase : int
        Units of phase ``p`` run after every unit of the phases before.
    weight : int
        Progress-bar weight (learning steps of a trial, 1 otherwise).
    parallel : bool
        May run in a worker process (False for timed units).
    """

    key: str
    func: Callable[..., Any]
    params: Mapping[str, Any]
    depends: Mapping[str, Any] = field(default_factory=dict)
    phase: int = 0
    weight: int = 1
    parallel: bool = True

    @property
    def fingerprint(self) -> str:
        text = json.dumps(
            {
                "func": f"{self.func.__module__}.{self.func.__qualname__}",
                "params": self.params,
                "depends": self.depends,
            },
            sort_keys=True,
            default=str,
        )
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    @property
    def stem(self) -> str:
        return self.key.replace("/", "__")


@dataclass(frozen=True, eq=False)
class UnitResult:
    """The stored result of one unit.

    Attributes
    ----------
    key : str
    arrays : dict of str -> array
        Empty for units that return a history (see ``SceneResult.histories``).
    meta : dict
        Plain values (numbers, strings, lists).
    seconds : float
        Wall-clock time of the unit when it was computed.
    """

    key: str
    arrays: Mapping[str, NDArray]
    meta: Mapping[str, Any]
    seconds: float


@dataclass
class UnitContext:
    """What a unit function may use besides its scene and parameters.

    Attributes
    ----------
    key : str
        The unit's key.
    directory : pathlib.Path
        The scene's result directory.
    checkpoint : pathlib.Path
        A file the unit may use to checkpoint itself (removed when the unit completes).
    on_step : callable or None
        Call once per learning step (progress bar, kill hook).
    read_unit : callable ``key -> UnitResult``
        Reads the stored result of an earlier unit (supplied by the runner).
    read_history : callable ``group -> History``
        Reads the merged history of a learning group (supplied by the runner).
    """

    key: str
    directory: Path
    checkpoint: Path
    on_step: Callable[[], None] | None = None
    read_unit: Callable[[str], UnitResult] | None = None
    read_history: Callable[[str], Any] | None = None

    def history(self, group: str):
        """The merged history of the learning group ``"<solver>/<rule>/noise<i>"``."""
        if self.read_history is None:
            raise RuntimeError(f"unit {self.key!r}: no stored histories to read")
        return self.read_history(group)

    def unit(self, key: str) -> UnitResult:
        """The stored result of an earlier unit."""
        if self.read_unit is None:
            raise RuntimeError(f"unit {self.key!r}: no stored units to read")
        return self.read_unit(key)
