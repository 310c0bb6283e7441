"""Run a scene: compute only what it names, checkpoint every unit, resume after a kill.

A scene is split into *units* (one training trial, one lattice size, one solver on one
case, ...). Each unit writes its result atomically to ``<directory>/units/`` (an ``.npz``
payload and a ``.json`` record written last, holding a fingerprint of every setting the
unit depends on). Running the scene again skips the units whose record matches, so a run
that was killed resumes where it stopped, and a unit whose settings changed is recomputed.
Learning trials also checkpoint inside the trial (``train(..., checkpoint=...)``) so a
killed trial resumes at its last checkpoint; a resumed run returns the same numbers as an
uninterrupted one (wall-clock columns aside).

Records are strict JSON (:mod:`continuum_vs_network.io.strict_json`): a non-finite value
(NaN: not available, e.g. the error of an explicit step refused above its stability limit;
inf: an open end such as no instability below the largest value tried) is written as
``null`` and named in the record's ``"non_finite"`` map (JSON pointer -> ``"nan"``,
``"inf"`` or ``"-inf"``), and read back as it was; records written with bare ``NaN`` tokens
by earlier versions still load.

Units of a phase run in parallel with ``workers > 1`` or a Dask ``scheduler`` (learning
trials, transmission and relaxation sizes), through the executor of :mod:`.executor`;
timing scenes (stability, solvers) always run serially so their wall-clock times are not
measured under load. Results agree with a serial run: every unit draws its randomness from
its own seed, and its solver makes the same decisions wherever it runs.

Testing hook: the environment variable ``CVN_TEST_KILL_AFTER`` (``"units:N"`` or
``"steps:N"``) makes the process kill itself with SIGKILL after ``N`` completed units or
learning steps, to test resuming.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import shutil
import signal
import sys
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..io.atomic import atomic_path, remove_stale_temporaries, write_text_atomic
from ..io.lock import folder_lock
from ..io.strict_json import dumps_record, loads_record
from .executor import Executor, TaskError, open_executor
from .provenance import Provenance, blas_threads, environment
from .schema import Scene
from .units import Unit, UnitContext, UnitResult

__all__ = [
    "Provenance",
    "SceneResult",
    "SceneRunError",
    "Unit",
    "UnitContext",
    "UnitResult",
    "load_result",
    "plan",
    "run_scene",
]

KILL_ENV = "CVN_TEST_KILL_AFTER"


class SceneRunError(RuntimeError):
    """A unit of a scene failed; carries the scene name, the unit key and the cause."""

    def __init__(self, scene: str, unit: str, cause: BaseException) -> None:
        self.scene, self.unit, self.cause = scene, unit, cause
        super().__init__(f"scene {scene!r}, unit {unit!r}: {type(cause).__name__}: {cause}")


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
    """The units of ``scene``, in order (only what the scene names)."""
    if scene.kind == "learning":
        from .units_learning import plan_learning

        return plan_learning(scene)
    if scene.kind == "continuum_learning":
        from .units_continuum_learning import plan_continuum_learning

        return plan_continuum_learning(scene)
    if scene.kind == "beyond_paper":
        from .units_beyond import plan_beyond_paper

        return plan_beyond_paper(scene)
    if scene.kind in ("transmission", "relaxation"):
        from .units_physics import plan_physics

        return plan_physics(scene)
    if scene.kind == "stability":
        from .units_stability import plan_stability

        return plan_stability(scene)
    if scene.kind == "accuracy":
        from .units_accuracy import plan_accuracy

        return plan_accuracy(scene)
    if scene.kind == "physical_time":
        from .units_time import plan_time

        return plan_time(scene)
    from .units_solvers import plan_solvers

    return plan_solvers(scene)


# -- storage ---------------------------------------------------------------------------------
def _units_dir(directory: Path) -> Path:
    return directory / "units"


def _record_path(directory: Path, key: str) -> Path:
    return _units_dir(directory) / (key.replace("/", "__") + ".json")


def _payload_path(directory: Path, key: str) -> Path:
    return _units_dir(directory) / (key.replace("/", "__") + ".npz")


def _is_done(directory: Path, unit: Unit, *, verify: bool = False) -> bool:
    """The unit's record matches its fingerprint (and, with ``verify``, its payload loads)."""
    rec = _record_path(directory, unit.key)
    if not (rec.exists() and _payload_path(directory, unit.key).exists()):
        return False
    try:
        record = json.loads(rec.read_text())
        if record["fingerprint"] != unit.fingerprint:
            return False
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return not verify or _payload_loads(directory, unit.key, bool(record.get("history")))


def _payload_loads(directory: Path, key: str, history: bool) -> bool:
    """True when the unit's payload reads back completely (every array, every CRC)."""
    path = _payload_path(directory, key)
    try:
        if history:
            from ..learning.history import History

            History.load(path)
        else:
            with np.load(path, allow_pickle=False) as z:
                for name in z.files:
                    z[name]
    except Exception:  # any failure to read back means: compute the unit again
        return False
    return True


def _save_unit(directory: Path, unit: Unit, output: Any, seconds: float) -> None:
    from ..learning.history import History

    payload = _payload_path(directory, unit.key)
    if isinstance(output, History):
        with atomic_path(payload) as tmp:
            output.save(tmp)
        record = {"history": True, "meta": {}}
    else:
        arrays, meta = output
        with atomic_path(payload) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **{k: np.asarray(v) for k, v in arrays.items()})
        record = {"history": False, "meta": meta}
    record.update(key=unit.key, fingerprint=unit.fingerprint, seconds=float(seconds))
    write_text_atomic(
        _record_path(directory, unit.key),
        dumps_record(record, sort_keys=True, default=_json_default),
    )


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _read_record(directory: Path, key: str) -> dict:
    return loads_record(_record_path(directory, key).read_text())


def _read_unit(directory: Path, key: str) -> UnitResult:
    rec = _read_record(directory, key)
    if rec["history"]:
        return UnitResult(key, {}, {}, rec["seconds"])
    with np.load(_payload_path(directory, key), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return UnitResult(key, arrays, rec["meta"], rec["seconds"])


def _trial_keys(directory: Path, group: str) -> list[str]:
    prefix = "train/" + group + "/trial"
    keys = []
    for rec in _units_dir(directory).glob("train__*.json"):
        key = json.loads(rec.read_text())["key"]
        if key.startswith(prefix):
            keys.append(key)
    return sorted(keys, key=lambda k: int(k.rsplit("trial", 1)[1]))


def _merged_history(directory: Path, group: str, keys: Iterable[str] | None = None):
    """Concatenate the one-trial histories of a learning group along the trial axis."""
    from ..learning.history import History

    keys = list(keys) if keys is not None else _trial_keys(directory, group)
    if not keys:
        raise KeyError(f"no trials of {group!r} in {directory}")
    parts = [History.load(_payload_path(directory, k)) for k in keys]
    first = parts[0]
    return dataclasses.replace(
        first,
        seeds=np.concatenate([h.seeds for h in parts]),
        completed=np.concatenate([h.completed for h in parts]),
        stop_reason=tuple(r for h in parts for r in h.stop_reason),
        data={name: np.concatenate([h.data[name] for h in parts]) for name in first.data},
        initial=tuple(n for h in parts for n in h.initial),
        final=tuple(n for h in parts for n in h.final),
        tasks=tuple(t for h in parts for t in h.tasks),
    )


# -- running ---------------------------------------------------------------------------------
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
    ``scheduler``, ``progress``, ``fresh``, ``command``, ``log``) are described at
    :func:`_run_scene`.
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
                executor = executor or open_executor(workers=workers, scheduler=scheduler)
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
    compute = sum(_read_record(directory, k)["seconds"] for k in keys)
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
    )
    write_text_atomic(
        directory / "run.json", dumps_record(dataclasses.asdict(prov), indent=1, sort_keys=True)
    )
    return load_result(scene, directory, units=units)


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


def _clean(directory: Path, units: list[Unit]) -> None:
    """Remove unit files and checkpoints that belong to no unit of the plan."""
    stems = {u.stem for u in units}
    for path in _units_dir(directory).iterdir():
        if path.name.startswith("."):
            continue
        stem = path.name.rsplit(".", 1)[0]
        if stem not in stems:
            path.unlink(missing_ok=True)
    ckpts = directory / "checkpoints"
    if ckpts.exists():
        for path in ckpts.iterdir():
            path.unlink(missing_ok=True)
        ckpts.rmdir()


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
