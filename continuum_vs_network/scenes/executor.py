"""Where independent tasks run: in this process, on a local Dask cluster, or on a running one.

Every parallel computation of the package (a scene's parallel units with ``--workers``, the
grid points of a sweep) goes through :func:`open_executor`:

* ``workers=1`` and no scheduler: :class:`SerialExecutor`, in this process (Dask is not
  imported);
* ``workers=N > 1``: a :class:`DaskExecutor` on a ``dask.distributed.LocalCluster`` of ``N``
  single-threaded worker processes on this machine (closed with the executor);
* ``scheduler="tcp://host:8786"``: a :class:`DaskExecutor` on an existing Dask cluster (for
  example one started by dask-jobqueue on SLURM or PBS). Its workers must be able to import
  this package and to write the result folder (a shared file system).

Tasks are module-level functions with picklable arguments. On Dask workers each task runs
with BLAS pinned to one thread (``threadpoolctl``), so that ``N`` workers use ``N`` cores and
a worker computes what a serial run computes. Dask (``pip install
continuum_vs_network[sweep]``) is imported only when a Dask executor is opened.
"""

from __future__ import annotations

import logging
import os
import uuid
from collections.abc import Callable, Sequence
from typing import Any

__all__ = [
    "DaskExecutor",
    "Executor",
    "ExecutorUnavailable",
    "SerialExecutor",
    "TaskError",
    "machine_workers",
    "open_executor",
]


#: How long to try reaching a scheduler before giving up.
CONNECT_TIMEOUT = "20s"


class ExecutorUnavailable(RuntimeError):
    """The executor asked for cannot be opened: Dask is not installed, or the scheduler
    cannot be reached. The message says which and what to do."""


class TaskError(RuntimeError):
    """Task ``index`` of :meth:`Executor.run` raised ``cause`` (the other tasks are cancelled)."""

    def __init__(self, index: int, cause: BaseException) -> None:
        self.index, self.cause = index, cause
        super().__init__(f"task {index}: {type(cause).__name__}: {cause}")


def machine_workers() -> int:
    """Cores this process may use (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


DEFAULT_WORKERS_MAX = 8  # each worker process imports the package (~0.2 GB)


def default_workers() -> int:
    """Worker processes when none are asked for: one per core this process may use, up to
    :data:`DEFAULT_WORKERS_MAX`, when dask.distributed is installed; else 1 (serial)."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        return 1
    return min(machine_workers(), DEFAULT_WORKERS_MAX)


def pinned_call(func: Callable[..., Any], args: tuple) -> Any:
    """``func(*args)`` with BLAS and OpenMP pools limited to one thread."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        return func(*args)


class Executor:
    """Runs independent tasks; a context manager (closing releases its workers).

    Attributes
    ----------
    workers : int
        Tasks that can run at once (0 when a remote cluster has no workers yet).
    description : str
        One line for messages and provenance (``"serial"``, ``"local Dask, 2 workers"``).
    """

    workers: int = 1
    description: str = "serial"

    def run(
        self,
        func: Callable[..., Any],
        args: Sequence[tuple],
        *,
        on_result: Callable[[int, Any], None] | None = None,
        label: str = "cvn",
    ) -> None:
        """Call ``func(*args[i])`` for every ``i``; ``on_result(i, value)`` as each finishes.

        Results arrive in completion order (in order for the serial executor). The first
        task that raises stops the run: the remaining tasks are cancelled and
        :class:`TaskError` is raised carrying the task's index and its exception.
        """
        raise NotImplementedError

    def close(self) -> None:
        """Release the workers (a no-op for the serial executor)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialExecutor(Executor):
    """Every task in this process, one after another, in order."""

    def run(self, func, args, *, on_result=None, label="cvn") -> None:
        for i, a in enumerate(args):
            try:
                value = func(*a)
            except Exception as err:
                raise TaskError(i, err) from err
            if on_result is not None:
                on_result(i, value)


class DaskExecutor(Executor):
    """Tasks on a Dask cluster through ``client`` (a ``dask.distributed.Client``).

    ``cluster``, when given, is closed with the executor (a cluster this executor started).
    """

    def __init__(self, client: Any, *, cluster: Any = None, description: str = "Dask") -> None:
        self.client, self.cluster = client, cluster
        info = client.scheduler_info()
        self.workers = int(sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()))
        self.description = f"{description}, {self.workers} worker thread(s)"

    def run(self, func, args, *, on_result=None, label="cvn") -> None:
        from distributed import as_completed

        tag = uuid.uuid4().hex[:8]
        futures = [
            self.client.submit(pinned_call, func, tuple(a), key=f"{label}-{i}-{tag}", pure=False)
            for i, a in enumerate(args)
        ]
        index = {f.key: i for i, f in enumerate(futures)}
        try:
            for fut in as_completed(futures):
                i = index[fut.key]
                if fut.status != "finished":
                    err = fut.exception()
                    raise TaskError(i, err) from err
                value = fut.result()
                fut.release()
                if on_result is not None:
                    on_result(i, value)
        finally:
            pending = [f for f in futures if f.status == "pending"]
            if pending:
                self.client.cancel(pending)

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def open_executor(
    *,
    workers: int = 1,
    scheduler: str | None = None,
    serial_fallback: bool = False,
    log: Callable[[str], None] | None = None,
) -> Executor:
    """The executor for ``workers`` local processes or an existing Dask ``scheduler``.

    Parameters
    ----------
    workers : int
        1: serial, in this process; N > 1: a LocalCluster of N single-threaded workers.
        Ignored when ``scheduler`` is given.
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://10.0.0.5:8786"``).
    serial_fallback : bool
        When the local cluster cannot be started (Dask missing, no worker process), return
        the serial executor with a message to ``log`` instead of raising: for a worker count
        the caller chose by default. A ``scheduler`` that cannot be reached still raises.

    Raises
    ------
    ValueError
        ``workers`` is not an integer >= 1.
    ExecutorUnavailable
        Dask is needed and not installed (the message says how to install it), or the
        scheduler cannot be reached (the message names the address).
    """
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if scheduler is None and workers == 1:
        return SerialExecutor()
    if scheduler is None:
        try:
            return _local(int(workers))
        except (ExecutorUnavailable, OSError, RuntimeError, TimeoutError) as err:
            if not serial_fallback:
                raise
            if log:
                log(f"{workers} local worker processes did not start ({err}); serial")
            return SerialExecutor()
    try:
        from distributed import Client
    except ImportError as err:
        raise _no_dask(err) from err
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as err:
        raise ExecutorUnavailable(
            f"cannot reach the Dask scheduler at {scheduler!r}: {err}"
        ) from err
    return DaskExecutor(client, description=f"Dask at {scheduler}")


def _no_dask(err: ImportError) -> ExecutorUnavailable:
    return ExecutorUnavailable(
        f"parallel runs need dask.distributed: pip install 'continuum_vs_network[sweep]' ({err})"
    )


def _local(workers: int) -> DaskExecutor:
    """A LocalCluster of ``workers`` single-threaded worker processes and its executor."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as err:
        raise _no_dask(err) from err
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=logging.ERROR,
        # no per-worker cap: Dask's default splits the memory evenly and restarts a worker
        # past its share, which would kill a large unit that runs fine serially (8 workers
        # on 16 GB: 2 GB each); the units hold small results, so there is nothing to spill
        memory_limit=0,
    )
    try:
        client = Client(cluster)
    except BaseException:
        cluster.close()
        raise
    return DaskExecutor(client, cluster=cluster, description="local Dask")
