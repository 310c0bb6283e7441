"""Checks of public arguments: one typed error naming the argument, the value and what is allowed.

The bottom of the layer stack (imports only numpy and the standard library): every public
entry point (``SpringNetwork``, ``relax``, the builders, the learning rules, ``train``,
tasks, scenes, the CLI) checks its arguments here before any numpy or scipy call can fail
on them with a message that names nothing the user wrote.

:class:`ArgumentError` subclasses both ``ValueError`` and ``TypeError``, so code that
caught either for a bad argument keeps working. Memory estimates compare a planned
allocation with :func:`available_memory` before it is made (:func:`memory`).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "INT64_MAX",
    "ArgumentError",
    "available_memory",
    "boolean",
    "choice",
    "float_array",
    "format_bytes",
    "index_array",
    "integer",
    "mapping",
    "memory",
    "real",
    "seed",
    "show",
]

INT64_MAX = 2**63 - 1


class ArgumentError(ValueError, TypeError):
    """A bad argument of a public function.

    Attributes
    ----------
    argument : str
        The argument's name as the caller wrote it (``"tol"``, ``"clamped"``, ``"seeds[2]"``).
    value : object
        The value given.
    allowed : str
        What is allowed, in words.
    """

    def __init__(
        self, argument: str, value: Any, allowed: str, *, detail: str = "", message: str = ""
    ) -> None:
        self.argument, self.value, self.allowed = argument, value, allowed
        msg = message or f"{argument} must be {allowed}, got {show(value)}"
        super().__init__(msg + (f"; {detail}" if detail else ""))


def show(value: Any, width: int = 80) -> str:
    """A short description of ``value`` for an error message: its repr and type, cut to fit."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        if value.size <= 6:
            body = np.array2string(value.ravel(), threshold=6, separator=", ")
            return f"array of shape {value.shape} and dtype {value.dtype} ({body})"
        return f"array of shape {value.shape} and dtype {value.dtype}"
    try:
        text = repr(value)
    except Exception:  # a hostile __repr__ must not hide the real error
        text = f"<{type(value).__name__}>"
    if len(text) > width:
        text = text[: width - 3] + "..."
    kind = type(value).__name__
    if isinstance(value, bool | int | float | str) or value is None:
        return f"{text} ({kind})" if isinstance(value, bool | str) else text
    return f"{text} ({kind})"


# -- scalars --------------------------------------------------------------------------------
def _is_real(value: Any) -> bool:
    if type(value) is float or type(value) is int:  # the common case, before the ABC checks
        return True
    if isinstance(value, bool | np.bool_):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def integer(
    name: str, value: Any, *, low: int | None = None, high: int | None = None, what: str = ""
) -> int:
    """``value`` as a Python int in ``[low, high]``.

    Accepted: Python and numpy integers, and floats with an integral value (``1e3``).
    Refused: bools, strings, None, non-integral or non-finite floats, complex numbers.
    """
    ok = _is_real(value)
    if ok:
        if isinstance(value, numbers.Integral) or (
            isinstance(value, np.ndarray) and value.dtype.kind in "iu"
        ):
            out = int(value)
        else:
            f = float(value)
            ok = math.isfinite(f) and f.is_integer()
            out = int(f) if ok else 0
        ok = ok and not ((low is not None and out < low) or (high is not None and out > high))
    if not ok:  # the message is built only on failure
        raise ArgumentError(name, value, what or _int_range(low, high))
    return out


def _int_range(low: int | None, high: int | None) -> str:
    if low is not None and high is not None:
        return f"an integer in {low}..{high}"
    if low is not None:
        return f"an integer >= {low}"
    if high is not None:
        return f"an integer <= {high}"
    return "an integer"


def real(
    name: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    what: str = "",
) -> float:
    """``value`` as a finite Python float in the given range (open or closed at each end).

    Refused: bools, strings, None, complex numbers, NaN and infinities, arrays of size > 1.
    """
    ok = _is_real(value)
    if ok:
        f = float(value)
        ok = math.isfinite(f)
        if ok and low is not None:
            ok = f > low if low_open else f >= low
        if ok and high is not None:
            ok = f < high if high_open else f <= high
    if not ok:  # the message is built only here: relax checks several reals per call
        raise ArgumentError(name, value, what or _real_range(low, high, low_open, high_open))
    return f


def _real_range(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    parts = ["a finite number"]
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return " ".join(parts[:2]) + (f" and {parts[2]}" if len(parts) > 2 else "")


def boolean(name: str, value: Any) -> bool:
    """``value`` as a bool: only ``True``/``False`` (and numpy bools) are accepted."""
    if not isinstance(value, bool | np.bool_):
        raise ArgumentError(name, value, "True or False")
    return bool(value)


def choice(name: str, value: Any, choices: Iterable[str]) -> str:
    """``value`` when it is one of the strings ``choices``."""
    choices = tuple(choices)
    if not (isinstance(value, str) and value in choices):
        raise ArgumentError(name, value, "one of " + ", ".join(map(repr, choices)))
    return value


def seed(name: str, value: Any) -> int:
    """A random seed: an integer in ``0..2**63 - 1`` (it is stored as int64)."""
    return integer(name, value, low=0, high=INT64_MAX, what="an integer in 0..2**63-1")


def mapping(name: str, value: Any, allowed: str) -> Mapping:
    """``value`` when it is a mapping (``dict``)."""
    if not isinstance(value, Mapping):
        raise ArgumentError(name, value, allowed)
    return value


# -- arrays ---------------------------------------------------------------------------------
def _as_array(name: str, value: Any, allowed: str) -> NDArray:
    if isinstance(value, str | bytes | Mapping) or value is None:
        raise ArgumentError(name, value, allowed)
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError, OverflowError) as err:  # ragged lists and the like
        raise ArgumentError(name, value, allowed, detail=str(err)) from None
    return arr


def _shape_text(shape: tuple[int | None, ...]) -> str:
    dims = ["n" if s is None else str(s) for s in shape]
    return f"({dims[0]},)" if len(dims) == 1 else "(" + ", ".join(dims) + ")"


def float_array(
    name: str, value: Any, shape: tuple[int | None, ...] | None = None, *, finite: bool = True
) -> NDArray[np.float64]:
    """``value`` as a new float64 array of ``shape`` (None: any length along that axis).

    Refused: complex values (even with a zero imaginary part), strings, objects, bools,
    arrays of another shape, and (with ``finite``) NaN or infinite entries.
    """
    want = "an array of real numbers" + (f" of shape {_shape_text(shape)}" if shape else "")
    arr = _as_array(name, value, want)
    if arr.dtype.kind not in "iuf":
        raise ArgumentError(name, arr, want)
    if shape is not None and not (
        arr.ndim == len(shape) and all(s is None or s == d for s, d in zip(shape, arr.shape))
    ):
        raise ArgumentError(name, arr, f"an array of shape {_shape_text(shape)}")
    out = np.array(arr, dtype=np.float64, copy=True)
    if finite and out.size and not np.all(np.isfinite(out)):
        bad = np.argwhere(~np.isfinite(out))[0]
        where = f"{name}[{', '.join(map(str, bad))}]" if out.ndim else name
        raise ArgumentError(where, out[tuple(bad)], "finite")
    return out


def index_array(
    name: str, value: Any, n: int, *, what: str = "indices", shape: tuple[int | None, ...] = (None,)
) -> NDArray[np.int64]:
    """``value`` as an int64 array of indices in ``0..n-1`` (a new array).

    Integer-valued floats are accepted; bools, strings, non-integral floats and integers
    beyond int64 are refused with the first offending entry named.
    """
    allowed = f"{what} in 0..{n - 1}" if n > 0 else f"{what} (there are none to name)"
    want = f"an integer array of shape {_shape_text(shape)} holding {allowed}"
    arr = _as_array(name, value, want)
    if arr.size == 0:
        arr = arr.astype(np.int64)
    if arr.ndim != len(shape) or not all(s is None or s == d for s, d in zip(shape, arr.shape)):
        raise ArgumentError(name, value, want)
    if arr.dtype.kind == "O":  # Python ints beyond int64, or mixed objects
        flat = arr.ravel()
        for i, v in enumerate(flat):
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not 0 <= v < n:
                raise ArgumentError(_entry(name, arr.shape, i), v, allowed)
        arr = arr.astype(np.int64)
    if arr.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(arr.ravel()) | (arr.ravel() != np.round(arr.ravel())))
        if bad.size:
            raise ArgumentError(_entry(name, arr.shape, bad[0]), arr.ravel()[bad[0]], allowed)
    elif arr.dtype.kind not in "iu":
        raise ArgumentError(name, value, want)
    flat = arr.ravel()
    bad = np.flatnonzero((flat < 0) | (flat >= n))
    if bad.size:
        raise ArgumentError(_entry(name, arr.shape, bad[0]), flat[bad[0]].item(), allowed)
    return np.array(arr, dtype=np.int64, copy=True)


def _entry(name: str, shape: tuple[int, ...], flat_index: int) -> str:
    idx = np.unravel_index(int(flat_index), shape) if shape else ()
    return f"{name}[{', '.join(str(int(i)) for i in idx)}]" if idx else name


# -- memory ---------------------------------------------------------------------------------
def available_memory() -> int:
    """Bytes of memory this process can still allocate without swapping.

    ``MemAvailable`` of ``/proc/meminfo`` (Linux), else the free physical pages
    (``os.sysconf``); a cgroup memory limit (containers) lowers it. Without any of these
    the answer is ``2**63 - 1`` (no limit known, nothing is refused).
    """
    avail = None
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        avail = None
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (AttributeError, ValueError, OSError):
            avail = INT64_MAX
    for limit_file, usage_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        (
            "/sys/fs/cgroup/memory/memory.limit_in_bytes",
            "/sys/fs/cgroup/memory/memory.usage_in_bytes",
        ),
    ):
        try:
            with open(limit_file, encoding="ascii") as fh:
                limit = fh.read().strip()
            with open(usage_file, encoding="ascii") as fh:
                usage = int(fh.read().strip())
        except (OSError, ValueError):
            continue
        if limit.isdigit() and int(limit) < 2**60:
            avail = min(avail, max(int(limit) - usage, 0))
        break
    return int(avail)


def format_bytes(n: float) -> str:
    """``n`` bytes in words: ``"3.2 GiB"``, ``"1.5e+06 TiB"``."""
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            value = n / size
            return f"{value:.3g} {unit}" if value < 1e4 else f"{value:.2e} {unit}"
    return f"{int(n)} bytes"


def memory(name: str, value: Any, needed: float, what: str) -> None:
    """Refuse ``value`` of ``name`` when ``what`` would need more memory than is available.

    ``needed`` is an estimate in bytes (Python ints or floats: no overflow however large).

    Raises
    ------
    ArgumentError
        Naming the argument, its value, the estimate and the memory available.
    """
    avail = available_memory()
    if needed > avail:
        raise ArgumentError(
            name,
            value,
            f"small enough for {what} to fit in the {format_bytes(avail)} of memory available",
            message=f"{name} = {show(value)} is too large: {what} needs about "
            f"{format_bytes(needed)} of memory but {format_bytes(avail)} are available",
        )
