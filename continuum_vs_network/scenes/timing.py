"""Timed units run with one BLAS thread.

On a shared machine a second BLAS (OpenMP) thread that spins while other processes hold the
cores makes small dense solves many times slower, and the slow-down follows the machine's
load, not the method. Measured on this project's 2-core machine at load 15: Newton on an
8 x 8 lattice clamped at strain 5 (38 iterations) took 0.39 s with one OpenBLAS thread and
11-22 s with two. Every unit whose wall-clock time is reported (equilibrium solvers,
stability cases, accuracy studies) therefore runs under :func:`single_threaded`; the report's
provenance lists the thread pools of the process.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["single_threaded"]

F = TypeVar("F", bound=Callable[..., Any])


def single_threaded(func: F) -> F:
    """``func`` run with every BLAS / OpenMP pool limited to one thread (threadpoolctl)."""

    @functools.wraps(func)
    def run(*args: Any, **kwargs: Any) -> Any:
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):
            return func(*args, **kwargs)

    return run  # type: ignore[return-value]
