"""Run a scene: compute only what it names, checkpoint every unit, resume after a kill.

A scene is split into *units* (one training trial, one lattice size, one solver on one
case, ...). Each unit writes its result atomically to ``<directory>/units/`` (an ``.npz``
payload and a ``.json`` record written last, holding a fingerprint of every setting the
unit depends on). Running the scene again skips the units whose record matches, so a run
that was killed resumes where it stopped, and a unit whose settings changed is recomputed.
Learning trials also checkpoint inside the trial (``train(..., checkpoint=...)``) so a
killed trial resumes at its last checkpoint; a resumed run returns the same numbers as an
uninterrupted one (wall-clock columns aside).

Units of a phase run in parallel with ``workers > 1`` or a Dask ``scheduler`` (learning
trials, transmission and relaxation sizes), through the executor of :mod:`.executor`;
timing scenes (stability, solvers) always run serially so their wall-clock times are not
measured under load. Results agree with a serial run: every unit draws its randomness from
its own seed, and its solver makes the same decisions wherever it runs.

Parts: :mod:`.store` (unit files: write, check, read back, merge trial histories) and
:mod:`.compute` (compute units serially or on an executor; the ``CVN_TEST_KILL_AFTER``
testing hook that kills the process to test resuming).
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..io.atomic import remove_stale_temporaries, write_text_atomic
from ..io.lock import folder_lock
from ..io.strict_json import dumps_record, loads_record
from .compute import _Killer, _run_parallel, _run_serial
from .executor import open_executor
from .provenance import Provenance, blas_threads, environment
from .store import _clean, _is_done, _merged_history, _read_record, _read_unit, _units_dir
from .units import Unit, UnitResult

if TYPE_CHECKING:
    from .schema import Scene

__all__ = ["SceneResult", "load_result", "plan", "run_scene"]


@dataclass(frozen=True, eq=False)
class SceneResult:
    """Everything a scene computed, read back from its result directory.

    Attributes
    ----------
    scene : Scene
    directory : pathlib.Path
    units : dict of key -> UnitResult
        Every unit, in plan order.
    histories : dict of str -> History
        Learning runs, trials merged: key ``"<solver>/<rule>/noise<i>"``.
    provenance : Provenance
    """

    scene: Scene
    directory: Path
    units: Mapping[str, UnitResult]
    histories: Mapping[str, Any]
    provenance: Provenance

    def select(self, prefix: str) -> dict[str, UnitResult]:
        """Units whose key starts with ``prefix``."""
        return {k: u for k, u in self.units.items() if k.startswith(prefix)}


# -- planning --------------------------------------------------------------------------------
def plan(scene: Scene) -> list[Unit]:
    """The units of ``scene``, in order (only what the scene names): its kind's planner."""
    from .schema import KINDS

    return KINDS[scene.kind].plan(scene)


# -- running ---------------------------------------------------------------------------------
def _log_unreadable(directory: Path, units: list[Unit], done: set[str], log) -> None:
    """Say which units are recomputed because their payload does not read back."""
    bad = [u.key for u in units if u.key not in done and _is_done(directory, u)]
    if bad and log:
        log(f"{len(bad)} unit(s) with an unreadable payload are computed again (first: {bad[0]})")


def run_scene(scene: Scene, directory: str | os.PathLike[str], **options: Any) -> SceneResult:
    """Compute every unit of ``scene`` not already in ``directory``; return the result.

    The folder is locked for the run (:func:`~continuum_vs_network.io.lock.folder_lock`): a
    second run on it raises :class:`~continuum_vs_network.io.lock.FolderBusyError` at once.
    Temporaries that killed runs left in it are removed first, and a unit whose stored
    payload does not read back is computed again. The keyword options (``workers``,
    ``scheduler``, ``progress``, ``fresh``, ``command``, ``log``, ``serial_fallback``) are
    described at :func:`_run_scene`.
    """
    with folder_lock(directory):
        remove_stale_temporaries(directory, locked=True)
        return _run_scene(scene, directory, **options)


def _run_scene(
    scene: Scene,
    directory: str | os.PathLike[str],
    *,
    workers: int = 1,
    scheduler: str | None = None,
    progress: bool = True,
    fresh: bool = False,
    command: str | None = None,
    log: Callable[[str], None] | None = None,
    serial_fallback: bool = False,
) -> SceneResult:
    """Compute every unit of ``scene`` not already in ``directory``; return the result.

    Parameters
    ----------
    scene : Scene
    directory : path
        The scene's result folder (created), e.g. ``results/<scene>``.
    workers : int
        Worker processes for the parallel units (1: everything in this process; N > 1: a
        local Dask cluster of N workers, see :func:`.executor.open_executor`).
    scheduler : str, optional
        Address of a running Dask scheduler to run the parallel units on instead (its
        workers must see ``directory``).
    progress : bool
        Show a tqdm progress bar (tqdm is imported only then).
    fresh : bool
        Discard earlier results and checkpoints of this scene first.
    command : str, optional
        Recorded in the provenance (default: this process's command line).
    log : callable, optional
        Receives one-line messages (resumed units, ...).
    serial_fallback : bool
        When the local Dask cluster of ``workers`` cannot be started, run serially (with
        a message) instead of failing: for a worker count the caller chose by default.

    Raises
    ------
    SceneRunError
        A unit failed (the units completed before it are kept).
    """
    if int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers}")
    directory = Path(directory)
    if fresh:
        for sub in ("units", "checkpoints", "frames"):
            shutil.rmtree(directory / sub, ignore_errors=True)
        (directory / "run.json").unlink(missing_ok=True)
    env = environment()  # before this run writes anything (cached for the process)
    _units_dir(directory).mkdir(parents=True, exist_ok=True)
    write_text_atomic(
        directory / "scene.json", dumps_record(scene.to_dict(), indent=1, sort_keys=True)
    )
    units = plan(scene)
    keys = [u.key for u in units]
    if len(set(keys)) != len(keys):  # pragma: no cover - a planning bug
        raise AssertionError("duplicate unit keys")
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    t_start = time.perf_counter()
    done = {u.key for u in units if _is_done(directory, u, verify=True)}
    _log_unreadable(directory, units, done, log)
    reused = len(done)
    if log and done:
        log(f"{scene.name}: resuming, {len(done)} of {len(units)} units already computed")
    bar = _bar(progress, scene.name, units, done)
    killer = _Killer()
    executor = None
    try:
        for phase in sorted({u.phase for u in units}):
            todo = [u for u in units if u.phase == phase and u.key not in done]
            parallel = workers > 1 or scheduler is not None
            serial = [u for u in todo if not (parallel and u.parallel)]
            pooled = [u for u in todo if parallel and u.parallel]
            if pooled:
                executor = executor or open_executor(
                    workers=workers,
                    scheduler=scheduler,
                    serial_fallback=serial_fallback,
                    log=log and (lambda m: log(f"{scene.name}: {m}")),
                )
                _run_parallel(executor, scene, pooled, directory, bar)
            for unit in serial:
                _run_serial(scene, unit, directory, bar, killer)
    finally:
        if executor is not None:
            executor.close()
        if bar is not None:
            bar.close()
    _clean(directory, units)
    wall = time.perf_counter() - t_start
    records = [_read_record(directory, k) for k in keys]
    compute = sum(r["seconds"] for r in records)
    commits: dict[str, int] = {}
    for r in records:
        c = str(r.get("commit", "not recorded"))
        commits[c] = commits.get(c, 0) + 1
    prov = Provenance(
        version=_version(),
        commit=env["commit"],
        python=env["python"],
        numpy=env["libraries"]["numpy"],
        scipy=env["libraries"]["scipy"],
        platform=env["platform"],
        command=command
        if command is not None
        else " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]),
        seeds=_seeds(scene),
        started=started,
        wall_seconds=wall,
        compute_seconds=compute,
        units=len(units),
        reused=reused,
        workers=int(workers) if executor is None else executor.workers,
        libraries=dict(env["libraries"]),
        cpu=env["cpu"],
        threads=blas_threads(),
        unit_commits=commits,
    )
    write_text_atomic(
        directory / "run.json", dumps_record(dataclasses.asdict(prov), indent=1, sort_keys=True)
    )
    return load_result(scene, directory, units=units)


def _bar(progress: bool, name: str, units: list[Unit], done: set[str]):
    if not progress:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # progress bars are optional
        return None
    total = sum(u.weight for u in units)
    initial = sum(u.weight for u in units if u.key in done)
    return tqdm(
        total=total, initial=initial, desc=name, unit="step", leave=True, dynamic_ncols=True
    )


def load_result(
    scene: Scene, directory: str | os.PathLike[str], *, units: list[Unit] | None = None
) -> SceneResult:
    """Read a completed scene's results from ``directory``.

    Raises ``FileNotFoundError`` when a unit of the scene's plan is missing or out of date
    (run the scene first).
    """
    directory = Path(directory)
    units = plan(scene) if units is None else units
    missing = [u.key for u in units if not _is_done(directory, u)]
    if missing:
        raise FileNotFoundError(
            f"{directory}: {len(missing)} unit(s) of scene {scene.name!r} missing or out of "
            f"date (first: {missing[0]}); run the scene"
        )
    results = {u.key: _read_unit(directory, u.key) for u in units}
    groups: dict[str, list[str]] = {}
    for u in units:
        if u.key.startswith("train/"):
            groups.setdefault(u.key[len("train/") :].rsplit("/trial", 1)[0], []).append(u.key)
    histories = {g: _merged_history(directory, g, ks) for g, ks in groups.items()}
    prov = loads_record((directory / "run.json").read_text())
    prov["seeds"] = tuple(prov["seeds"])
    return SceneResult(scene, directory, results, histories, Provenance(**prov))


# -- provenance --------------------------------------------------------------------------
def _version() -> str:
    from importlib import metadata

    try:
        return metadata.version("continuum_vs_network")
    except metadata.PackageNotFoundError:  # pragma: no cover - not installed
        return "unknown"


def _seeds(scene: Scene) -> tuple[int, ...]:
    if scene.learning is not None:
        return tuple(range(scene.seed, scene.seed + scene.learning.trials))
    return (scene.seed,)
