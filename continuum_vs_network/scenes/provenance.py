"""Where a result comes from: package and library versions, machine, threads, git commit.

:func:`environment` is read once per process and cached, so every scene of one ``cvn report``
reports the same source state. The git ``+dirty`` mark looks only at the package's source
(``continuum_vs_network/`` and ``pyproject.toml``): the run's own outputs (``reports/``,
``meshes/``, result folders) never make a result "dirty". Nothing here imports an optional
library: versions come from the installed distributions' metadata.
"""

from __future__ import annotations

import functools
import os
import platform
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["LIBRARIES", "Provenance", "blas_threads", "cpu_model", "environment", "git_commit"]

#: The distributions whose versions a result records (those the package may use).
LIBRARIES = (
    "numpy",
    "scipy",
    "threadpoolctl",
    "torch",
    "scikit-fem",
    "meshio",
    "pyvista",
    "vtk",
    "matplotlib",
    "dask",
    "distributed",
    "pandas",
    "pyarrow",
)

#: Source paths whose changes mark a commit ``+dirty`` (relative to the repository root).
SOURCE_PATHS = ("continuum_vs_network", "pyproject.toml")


@dataclass(frozen=True)
class Provenance:
    """Where a result comes from.

    Attributes
    ----------
    version : str
        Package version.
    commit : str
        Git commit of the package source ("unknown" outside a git checkout), with
        ``+dirty`` when tracked source files (:data:`SOURCE_PATHS`) differ from it.
    python, numpy, scipy, platform : str
    command : str
        The command line of the run that completed the result.
    seeds : tuple of int
        The seeds the scene used.
    started : str
        ISO time the completing run started.
    wall_seconds : float
        Wall-clock time of the completing run (units reused from earlier runs excluded).
    compute_seconds : float
        Sum of every unit's own wall-clock time (across resumed runs).
    units : int
    reused : int
        Units taken from an earlier (interrupted or finished) run.
    workers : int
    libraries : dict of str to str
        Installed version of every distribution in :data:`LIBRARIES` ("not installed" for
        the absent ones).
    cpu : str
        CPU model and logical core count.
    threads : str
        BLAS / OpenMP thread pools as threadpoolctl reports them, and the environment's
        thread variables.
    unit_commits : dict of str to int
        How many of the scene's units were computed at each commit (units are reused
        across runs whatever the code is then; "not recorded": stored before units
        recorded their commit).
    """

    version: str
    commit: str
    python: str
    numpy: str
    scipy: str
    platform: str
    command: str
    seeds: tuple[int, ...]
    started: str
    wall_seconds: float
    compute_seconds: float
    units: int
    reused: int
    workers: int
    libraries: dict[str, str] = field(default_factory=dict)
    cpu: str = "unknown"
    threads: str = "unknown"
    unit_commits: dict[str, int] = field(default_factory=dict)


def library_versions() -> dict[str, str]:
    """Installed version of each of :data:`LIBRARIES` (nothing is imported)."""
    from importlib import metadata

    out = {}
    for name in LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def cpu_model() -> str:
    """CPU model name (from ``/proc/cpuinfo`` where there is one) and logical cores."""
    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    model = model or platform.processor() or platform.machine() or "unknown"
    return f"{model}, {os.cpu_count()} logical cores"


def blas_threads() -> str:
    """Thread pools loaded in this process (threadpoolctl), e.g. ``"openblas 0.3.31: 2"``."""
    try:
        from threadpoolctl import threadpool_info

        pools = [
            f"{p.get('internal_api', '?')} {p.get('version') or ''}".strip()
            + f": {p.get('num_threads')}"
            for p in threadpool_info()
        ]
    except Exception as exc:  # pragma: no cover - threadpoolctl is a dependency
        pools = [f"threadpoolctl failed ({type(exc).__name__})"]
    env = [
        f"{k}={os.environ[k]}"
        for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
        if k in os.environ
    ]
    return "; ".join(pools or ["no BLAS pool loaded"]) + (f" ({', '.join(env)})" if env else "")


def git_commit(root: str | os.PathLike[str] | None = None) -> str:
    """``HEAD`` of the repository holding the package, ``+dirty`` when its source changed.

    Only :data:`SOURCE_PATHS` count: reports, meshes and results a run writes do not.
    "unknown" outside a git checkout.
    """
    src = Path(root) if root is not None else Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=src,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", *SOURCE_PATHS],
            cwd=src,
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


@functools.cache
def environment() -> dict[str, object]:
    """The parts of :class:`Provenance` that describe the process, read once and cached.

    Keys: ``commit``, ``python``, ``platform``, ``libraries``, ``cpu``. (Threads are read
    per run: a library imported later brings its own pool.)
    """
    return {
        "commit": git_commit(),
        "python": platform.python_version(),
        "platform": platform.platform(terse=True),
        "libraries": library_versions(),
        "cpu": cpu_model(),
    }
