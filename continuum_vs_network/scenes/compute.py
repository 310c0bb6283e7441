"""Compute the units of a scene: one in this process, or many on an executor.

Each computed unit stores its own result (:mod:`.store`) and removes its checkpoints; a
failure is raised as :class:`SceneRunError` naming the scene and the unit.

Testing hook: the environment variable ``CVN_TEST_KILL_AFTER`` (``"units:N"`` or
``"steps:N"``) makes the process kill itself with SIGKILL after ``N`` completed units or
learning steps, to test resuming.
"""

from __future__ import annotations

import functools
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .executor import Executor, TaskError
from .store import _merged_history, _read_unit, _save_unit
from .units import Unit, UnitContext

if TYPE_CHECKING:
    from .schema import Scene

__all__ = ["KILL_ENV", "SceneRunError"]

KILL_ENV = "CVN_TEST_KILL_AFTER"


class SceneRunError(RuntimeError):
    """A unit of a scene failed; carries the scene name, the unit key and the cause."""

    def __init__(self, scene: str, unit: str, cause: BaseException) -> None:
        self.scene, self.unit, self.cause = scene, unit, cause
        super().__init__(f"scene {scene!r}, unit {unit!r}: {type(cause).__name__}: {cause}")


class _Killer:
    """The ``CVN_TEST_KILL_AFTER`` hook: SIGKILL this process after N units or steps."""

    def __init__(self) -> None:
        spec = os.environ.get(KILL_ENV, "")
        self.what, _, n = spec.partition(":")
        self.limit = int(n) if n.isdigit() else -1
        self.count = 0

    def tick(self, what: str) -> None:
        if self.limit < 0 or what != self.what:
            return
        self.count += 1
        if self.count >= self.limit:
            os.kill(os.getpid(), signal.SIGKILL)


def _compute(scene: Scene, unit: Unit, directory: Path, on_step: Callable | None) -> float:
    """Run one unit and store its result; returns its wall-clock seconds."""
    ckpt = directory / "checkpoints" / f"{unit.stem}-{unit.fingerprint[:12]}.npz"
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    ctx = UnitContext(
        key=unit.key,
        directory=directory,
        checkpoint=ckpt,
        on_step=on_step,
        read_unit=functools.partial(_read_unit, directory),
        read_history=functools.partial(_merged_history, directory),
    )
    t0 = time.perf_counter()
    output = unit.func(scene, dict(unit.params), ctx)
    seconds = time.perf_counter() - t0
    _save_unit(directory, unit, output, seconds)
    for stale in ckpt.parent.glob(f"{unit.stem}-*"):
        stale.unlink(missing_ok=True)
    return seconds


def _worker(scene: Scene, unit: Unit, directory: str) -> tuple[str, float]:
    killer = _Killer()
    seconds = _compute(scene, unit, Path(directory), lambda: killer.tick("steps"))
    killer.tick("units")
    return unit.key, seconds


def _run_serial(scene: Scene, unit: Unit, directory: Path, bar, killer: _Killer) -> None:
    ticks = 0

    def on_step() -> None:
        nonlocal ticks
        ticks += 1
        if bar is not None:
            bar.update(1)
        killer.tick("steps")

    try:
        _compute(scene, unit, directory, on_step)
    except Exception as err:
        raise SceneRunError(scene.name, unit.key, err) from err
    if bar is not None:
        bar.update(max(unit.weight - ticks, 0))
    killer.tick("units")


def _run_parallel(
    executor: Executor, scene: Scene, units: list[Unit], directory: Path, bar
) -> None:
    """Units on ``executor`` (each stores its own result); the first failure stops the rest."""

    def done(i: int, _value: Any) -> None:
        if bar is not None:
            bar.update(units[i].weight)

    try:
        executor.run(
            _worker,
            [(scene, u, str(directory)) for u in units],
            on_result=done,
            label=f"{scene.name}-unit",
        )
    except TaskError as err:
        raise SceneRunError(scene.name, units[err.index].key, err.cause) from err.cause
