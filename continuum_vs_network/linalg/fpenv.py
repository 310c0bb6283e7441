"""Subnormal floats flushed to zero for the duration of a block (x86-64 Linux; elsewhere a no-op).

A float32 factorisation of a spring network's Hessian can produce entries below float32's
smallest normal number (1.2e-38; float64's, 2.2e-308, is not reached). x86 processors
compute with such subnormal numbers up to ~100x slower, enough to make the float32 Newton
slower than the float64 one (``docs/solver-notes.md#fpenv``).
MKL and PARDISO flush them in their own code; SuperLU does not, so :func:`flushing_subnormals`
sets the SSE control register's flush-to-zero and denormals-are-zero bits (MXCSR bits 15
and 6) around the call and restores the caller's register afterwards. The register is per
thread, so other threads are not affected. Results change only where a value would have
been subnormal, far below float32's relative precision at any normal scale.

It goes through the C library's ``fegetenv`` / ``fesetenv``, whose ``fenv_t`` on x86-64
glibc holds MXCSR at byte 28; a register whose exception masks are not all set (not the
expected layout, or a caller that unmasked exceptions) is left alone.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import functools
import platform
from collections.abc import Iterator

__all__ = ["flushing_subnormals"]

_FENV_BYTES = 32  # sizeof(fenv_t) on x86-64 glibc
_MXCSR_AT = 28
_MASKS = 0x1F80  # MXCSR's six exception masks, all set by default
_FLUSH = 0x8040  # flush-to-zero (bit 15) and denormals-are-zero (bit 6)


@functools.cache
def _libm():
    """The C math library, or None off x86-64 glibc (looked up on first use, then kept)."""
    if platform.system() != "Linux" or platform.machine() not in ("x86_64", "AMD64"):
        return None
    if platform.libc_ver()[0] != "glibc":
        return None
    name = ctypes.util.find_library("m")
    return ctypes.CDLL(name) if name else None


@contextlib.contextmanager
def flushing_subnormals() -> Iterator[None]:
    """Run the block with subnormal floats flushed to zero (this thread; see module)."""
    libm = _libm()
    if libm is None:
        yield
        return
    saved = ctypes.create_string_buffer(_FENV_BYTES)
    if libm.fegetenv(saved) != 0:
        yield
        return
    mxcsr = int.from_bytes(saved.raw[_MXCSR_AT : _MXCSR_AT + 4], "little")
    if mxcsr & _MASKS != _MASKS:
        yield
        return
    flushed = ctypes.create_string_buffer(
        saved.raw[:_MXCSR_AT] + (mxcsr | _FLUSH).to_bytes(4, "little") + saved.raw[_MXCSR_AT + 4 :],
        _FENV_BYTES,
    )
    libm.fesetenv(flushed)
    try:
        yield
    finally:
        libm.fesetenv(saved)
