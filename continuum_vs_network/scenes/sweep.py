"""Run a sweep: every grid point of a scene as one task, resumable, into one tidy table.

:func:`run_sweep` expands the scene (:mod:`.grid`), skips the points already stored in the
sweep's folder, and runs the others on an executor (:mod:`.executor`: serial, a local Dask
cluster, or a running Dask scheduler). A point is one task: it runs its variant with
:func:`~.runner.run_scene` in ``work/<fingerprint>/`` (so a killed point resumes from its
trials' checkpoints), reduces it to table rows and writes them atomically to
``points/<fingerprint>.json``; the work folder is then removed. A rerun skips every point
whose record is there, so a killed sweep resumes where it stopped, and a point's numbers
do not depend on where or with how many workers it ran.

Folder ``<directory>``::

    sweep.json       the scene, grid, executor and timing of the last completed run
    points/*.json    one record per completed point (rows of the table)
    table.parquet    the tidy table (one row per point, learning run and trial)
    table.csv        the same table as CSV

Columns of the table: the swept keys first, named by their key (top-level keys as
``scene.<key>``), then :data:`.sweep_rows.COLUMNS`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..io.atomic import atomic_path, write_text_atomic
from ..io.strict_json import dumps_record, loads_record
from .executor import TaskError, machine_workers, open_executor
from .grid import GridPoint, expand, grid_shape
from .provenance import environment
from .schema import Scene, SceneError
from .sweep_cost import estimate_cost
from .sweep_rows import COLUMNS, point_rows

__all__ = [
    "SweepResult",
    "SweepRunError",
    "load_sweep",
    "run_sweep",
    "training_only",
]


class SweepRunError(RuntimeError):
    """A grid point failed; carries the point and the cause (completed points are kept)."""

    def __init__(self, scene: str, point: GridPoint, cause: BaseException) -> None:
        self.scene, self.point, self.cause = scene, point, cause
        where = ", ".join(f"{k} = {v!r}" for k, v in point.values.items())
        super().__init__(
            f"sweep {scene!r}, point {point.index} ({where}): {type(cause).__name__}: {cause}"
        )


@dataclass(frozen=True, eq=False)
class SweepResult:
    """A completed sweep.

    Attributes
    ----------
    scene : Scene
        The swept scene (with its ``[sweep]`` table).
    directory : pathlib.Path
    points : tuple of GridPoint
    rows : tuple of dict
        The table, one dict per row (:data:`.sweep_rows.COLUMNS` plus the swept keys).
    columns : tuple of str
        Column order of the table.
    swept : tuple of str
        The table's columns of the swept keys.
    info : dict
        Contents of ``sweep.json`` (timing, executor, reused points).
    """

    scene: Scene
    directory: Path
    points: tuple[GridPoint, ...]
    rows: tuple[dict[str, Any], ...]
    columns: tuple[str, ...]
    swept: tuple[str, ...]
    info: Mapping[str, Any]

    def frame(self):
        """The table as a ``pandas.DataFrame`` (pandas imported here)."""
        import pandas as pd

        df = pd.DataFrame(list(self.rows), columns=list(self.columns))
        df["steps_to_threshold"] = df["steps_to_threshold"].astype("Int64")
        return df


def column_name(key: str) -> str:
    """Table column of swept key ``key`` (top-level keys get a ``scene.`` prefix)."""
    return key if "." in key else f"scene.{key}"


def _check_sweepable(scene: Scene) -> None:
    if scene.kind not in ("learning", "allostery"):
        raise SceneError(
            scene.source,
            "sweep",
            "",
            f"sweeps run learning and allostery scenes (a table row per trial or draw); this "
            f"scene is kind {scene.kind!r}",
        )


def training_only(scene: Scene) -> tuple[Scene, str]:
    """``scene`` without the per-scene outputs a sweep point does not produce, and a note
    naming those the scene asked for ("" when none): meshes, renders, source sweeps and the
    gradient comparison are drawn per scene, the sweep's report reads only its table."""
    if scene.kind == "allostery":  # the feasibility map is drawn per scene
        a = scene.allostery
        asked = [
            n
            for n, on in (
                ("[export]", scene.export is not None),
                ("[allostery] map_draws", a.map_draws > 0),
            )
            if on
        ]
        scene = dataclasses.replace(
            scene,
            export=None,
            report=dataclasses.replace(scene.report, images=False),
            allostery=dataclasses.replace(a, map_draws=0),
        )
        return scene, ", ".join(asked)
    L = scene.learning
    asked = [
        name
        for name, on in (
            ("[export]", scene.export is not None),
            ("[report] images", scene.report.images),
            ("[learning] sweeps", L.sweeps),
            ("[learning] compare_gradient", L.compare_gradient),
        )
        if on
    ]
    scene = dataclasses.replace(
        scene,
        export=None,
        report=dataclasses.replace(scene.report, images=False),
        learning=dataclasses.replace(L, sweeps=False, compare_gradient=False),
    )
    return scene, ", ".join(asked)


def _record_path(directory: Path, point: GridPoint) -> Path:
    return directory / "points" / f"{point.fingerprint}.json"


def _is_done(directory: Path, point: GridPoint) -> bool:
    path = _record_path(directory, point)
    try:
        return json.loads(path.read_text())["fingerprint"] == point.fingerprint
    except (OSError, ValueError, KeyError):
        return False


# -- one grid point ---------------------------------------------------------------------
def run_point(scene: Scene, fingerprint: str, directory: str, threshold: float) -> float:
    """Run one variant and store its rows in ``points/<fingerprint>.json``; returns seconds.

    A module-level task (sent to Dask workers by reference).
    """
    from .runner import run_scene

    root = Path(directory)
    work = root / "work" / fingerprint
    t0 = time.perf_counter()
    result = run_scene(scene, work, workers=1, progress=False, command="cvn sweep (point)")
    rows = point_rows(result, threshold)
    seconds = time.perf_counter() - t0
    record = {"fingerprint": fingerprint, "rows": rows, "seconds": seconds}
    write_text_atomic(
        root / "points" / f"{fingerprint}.json", dumps_record(record, sort_keys=True, indent=0)
    )
    shutil.rmtree(work, ignore_errors=True)
    return seconds


# -- the sweep ------------------------------------------------------------------------------
def run_sweep(
    scene: Scene, directory: str | os.PathLike[str], **options: Any
) -> SweepResult | None:
    """Compute every grid point of ``scene`` not already in ``directory``; write the table.

    The folder is locked for the run (a second run on it raises
    :class:`~continuum_vs_network.io.lock.FolderBusyError` at once) and temporaries that
    killed runs left in it are removed first (a dry run writes nothing and takes no lock).
    The keyword options are described at :func:`_run_sweep`.
    """
    from ..io.atomic import remove_stale_temporaries
    from ..io.lock import folder_lock

    if options.get("dry_run"):  # writes nothing: no folder, no lock
        return _run_sweep(scene, directory, **options)
    Path(directory).mkdir(parents=True, exist_ok=True)
    with folder_lock(directory):
        remove_stale_temporaries(directory, locked=True)
        return _run_sweep(scene, directory, **options)


def _run_sweep(
    scene: Scene,
    directory: str | os.PathLike[str],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = True,
    fresh: bool = False,
    dry_run: bool = False,
    log: Callable[[str], None] | None = None,
    serial_fallback: bool = False,
) -> SweepResult | None:
    """Compute every grid point of ``scene`` not already in ``directory``; write the table.

    Parameters
    ----------
    scene : Scene
        A learning scene with a ``[sweep]`` table (see :func:`.grid.with_overrides`).
    directory : path
        The sweep's folder, e.g. ``results/<scene>``.
    workers : int, optional
        Local worker processes (default: the cores of this machine; 1: serial, no Dask).
    scheduler : str, optional
        Address of a running Dask scheduler to run on instead.
    progress : bool
        A tqdm progress bar over the points.
    fresh : bool
        Discard earlier points of this sweep first.
    dry_run : bool
        Print the grid size and estimated cost (through ``log``) and return None.
    log : callable, optional
        Receives one-line messages: the grid and cost before anything runs, resumed points.
    serial_fallback : bool
        Run serially when the local cluster cannot start (:func:`.executor.open_executor`).

    Raises
    ------
    SceneError
        The scene cannot be swept or a variant is invalid (before anything runs).
    SweepRunError
        A point failed (the points completed before it are kept).
    ExecutorUnavailable
        Dask is not installed or the scheduler cannot be reached.
    """
    say = log or (lambda _m: None)
    _check_sweepable(scene)
    scene, dropped = training_only(scene)
    if dropped:
        say(f"{scene.name}: sweep points compute the training runs only, not {dropped}")
    points = expand(scene)
    _require_table_libraries()
    directory = Path(directory)
    workers = machine_workers() if workers is None else workers
    if fresh and not dry_run:
        for sub in ("points", "work"):
            shutil.rmtree(directory / sub, ignore_errors=True)
    todo = [p for p in points if not _is_done(directory, p)]
    shape = " x ".join(map(str, grid_shape(scene.sweep)))
    keys = ", ".join(k for k, _ in scene.sweep.axes)
    say(f"{scene.name}: grid {shape} over {keys}")
    cost = estimate_cost(points, todo)
    if scheduler:
        say(f"{scene.name}: {cost.text(0)} (on the Dask scheduler at {scheduler})")
    else:
        say(f"{scene.name}: {cost.text(workers)}")
    if dry_run:
        return None
    if len(todo) < len(points):
        say(f"{scene.name}: resuming, {len(points) - len(todo)} of {len(points)} points stored")
    started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    t0 = time.perf_counter()
    env = environment()
    (directory / "points").mkdir(parents=True, exist_ok=True)
    description, n_workers = "serial", 1
    if todo:
        description, n_workers = _dispatch(
            scene, todo, directory, workers, scheduler, progress, serial_fallback, say
        )
    shutil.rmtree(directory / "work", ignore_errors=True)
    info = {
        "scene": scene.to_dict(),
        "grid": list(grid_shape(scene.sweep)),
        "points": len(points),
        "reused": len(points) - len(todo),
        "executor": description,
        "workers": n_workers,
        "started": started,
        "wall_seconds": time.perf_counter() - t0,
        "commit": env["commit"],
        "libraries": dict(env["libraries"]),
    }
    result = _collect(scene, directory, points, info)
    _write_table(result)
    write_text_atomic(directory / "sweep.json", dumps_record(info, indent=1, sort_keys=True))
    return result


def _require_table_libraries() -> None:
    try:
        import pandas  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as err:
        raise ImportError(
            f"the sweep table needs pandas and pyarrow: pip install "
            f"'continuum_vs_network[sweep]' ({err})"
        ) from err


def _dispatch(
    scene, todo, directory, workers, scheduler, progress, serial_fallback, say
) -> tuple[str, int]:
    from .compute import _Killer

    bar = _bar(progress, scene.name, len(todo))
    killer = _Killer()

    def done(i: int, _seconds: float) -> None:
        if bar is not None:
            bar.update(1)
        killer.tick("points")

    args = [(p.scene, p.fingerprint, str(directory), scene.sweep.threshold) for p in todo]
    try:
        with open_executor(
            workers=workers,
            scheduler=scheduler,
            serial_fallback=serial_fallback,
            log=lambda m: say(f"{scene.name}: {m}"),
        ) as executor:
            try:
                executor.run(run_point, args, on_result=done, label=f"{scene.name}-point")
            except TaskError as err:
                raise SweepRunError(scene.name, todo[err.index], err.cause) from err.cause
            return executor.description, executor.workers
    finally:
        if bar is not None:
            bar.close()


def _bar(progress: bool, name: str, total: int):
    if not progress:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # progress bars are optional
        return None
    return tqdm(total=total, desc=name, unit="point", leave=True, dynamic_ncols=True)


def _table_value(v: Any) -> Any:
    if isinstance(v, tuple | list):
        return v[0] if len(v) == 1 else json.dumps(list(v))
    return v


def _collect(scene: Scene, directory: Path, points, info: Mapping[str, Any]) -> SweepResult:
    swept = tuple(column_name(k) for k, _ in scene.sweep.axes)
    rows = []
    for p in points:
        record = loads_record(_record_path(directory, p).read_text())
        params = {column_name(k): _table_value(v) for k, v in p.values.items()}
        for row in record["rows"]:
            rows.append({**params, "point": p.index, **row})
    columns = (*swept, *COLUMNS)
    return SweepResult(scene, directory, tuple(points), tuple(rows), columns, swept, dict(info))


def _write_table(result: SweepResult) -> None:
    df = result.frame()
    with atomic_path(result.directory / "table.parquet") as tmp:
        df.to_parquet(tmp, index=False)
    with atomic_path(result.directory / "table.csv") as tmp:
        df.to_csv(tmp, index=False)


def load_sweep(scene: Scene, directory: str | os.PathLike[str]) -> SweepResult:
    """Read a completed sweep's points from ``directory``.

    Raises ``FileNotFoundError`` when a point is missing (run the sweep first).
    """
    directory = Path(directory)
    points = expand(scene)
    missing = [p.index for p in points if not _is_done(directory, p)]
    if missing:
        raise FileNotFoundError(
            f"{directory}: {len(missing)} point(s) of sweep {scene.name!r} missing (first: "
            f"point {missing[0]}); run the sweep"
        )
    info = loads_record((directory / "sweep.json").read_text())
    return _collect(scene, directory, points, info)
