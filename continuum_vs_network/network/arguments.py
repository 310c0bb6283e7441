"""Argument checks of the network layer's public functions (``relax``, pins, clamps).

Each function returns the normalised value or raises
:class:`~continuum_vs_network._validate.ArgumentError` naming the argument, the value and
what is allowed, before any array operation can fail on it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from .model import SpringNetwork

__all__ = [
    "MAX_RAMP",
    "RelaxArguments",
    "clamp_arrays",
    "lone_nodes",
    "network",
    "pin_mask_or_indices",
    "relax_arguments",
    "solver_arguments",
]


#: most continuation steps of one ``relax`` call (each is a full solve)
MAX_RAMP = 10_000


def network(value: Any, name: str = "net") -> SpringNetwork:
    """``value`` when it is a :class:`SpringNetwork` with at least one spring."""
    if not isinstance(value, SpringNetwork):
        raise check.ArgumentError(name, value, "a SpringNetwork")
    return value


@dataclass(frozen=True)
class RelaxArguments:
    """The scalar options of ``relax``, checked."""

    method: str
    tol: float
    ramp: int
    max_iter: int | None
    max_seconds: float
    rod_stiffness: float


def relax_arguments(
    net: Any,
    *,
    methods: tuple[str, ...],
    method: Any,
    tol: Any,
    clamp: Any,
    rod_stiffness: Any,
    ramp: Any,
    max_iter: Any,
    max_seconds: Any,
) -> RelaxArguments:
    """Check every scalar argument of ``relax`` and the network's fitness for a solve.

    A network without springs has no equilibrium to find and is refused here; a free node
    that no spring touches is refused by :func:`lone_nodes` once the pins are known.
    """
    net = network(net)
    if net.n_springs == 0:
        raise check.ArgumentError("net", net, "a network with at least one spring")
    method = check.choice("method", method, methods)
    check.choice("clamp", clamp, ("exact", "rod"))
    tol = check.real("tol", tol, low=0, low_open=True)
    rod_stiffness = check.real("rod_stiffness", rod_stiffness, low=0, low_open=True)
    ramp = check.integer("ramp", ramp, low=1, high=MAX_RAMP)
    if max_iter is not None:
        max_iter = check.integer("max_iter", max_iter, low=1, what="None or an integer >= 1")
    max_seconds = check.real("max_seconds", max_seconds, low=0, low_open=True)
    return RelaxArguments(method, tol, ramp, max_iter, max_seconds, rod_stiffness)


def pin_mask_or_indices(net: SpringNetwork, pinned: Any) -> NDArray:
    """``pinned`` as a (n_nodes, 2) bool mask or a (k,) int64 array of node indices.

    Allowed: a bool mask of shape ``(n_nodes, 2)`` (an ndarray of dtype bool or nested
    lists of Python bools), one integer node index, or a 1-D sequence of integer node
    indices. Everything else is refused, not guessed at: a 2-D array that is not bool (a
    0/1 integer or float mask, say: read as indices it would pin nodes 0 and 1, which is
    never what was meant), any float array or float entry (``[0.0, 7.0]`` is neither
    indices nor a mask), and a 1-D sequence of 0s and 1s with a repeat (a flattened or
    per-node 0/1 mask, not a list of nodes).
    """
    if (isinstance(pinned, np.ndarray) and pinned.dtype == bool) or _is_bool_nested(pinned):
        arr = np.asarray(pinned)
        if arr.shape != (net.n_nodes, 2):
            raise check.ArgumentError(
                "pinned", pinned, f"a bool mask of shape ({net.n_nodes}, 2) or node indices"
            )
        return arr.astype(bool, copy=True)
    if isinstance(pinned, int | np.integer) and not isinstance(pinned, bool):
        pinned = [pinned]
    arr = np.asarray(pinned, dtype=object) if _is_nested(pinned) else None
    if arr is not None and arr.ndim == 2:
        raise check.ArgumentError(
            "pinned",
            pinned,
            _pins_allowed(net),
            detail="an integer or float 2-D array is ambiguous; use dtype=bool for a mask",
        )
    if _has_float(pinned):
        raise check.ArgumentError(
            "pinned",
            pinned,
            _pins_allowed(net),
            detail="floats are neither node indices nor a mask; use integers for indices "
            "or dtype=bool for a mask",
        )
    try:
        idx = check.index_array("pinned", pinned, net.n_nodes, what="node indices")
    except check.ArgumentError as err:
        if err.argument != "pinned":  # one entry named (pinned[1]: out of range, say)
            raise
        raise check.ArgumentError("pinned", pinned, _pins_allowed(net)) from None
    if 1 < idx.size and idx.max() <= 1 and np.unique(idx).size < idx.size:
        raise check.ArgumentError(
            "pinned",
            pinned,
            _pins_allowed(net),
            detail="repeated 0s and 1s read as indices would pin nodes 0 and 1 only; "
            "for a mask use a bool array of shape "
            f"({net.n_nodes}, 2), for nodes list each index once",
        )
    return idx


def _pins_allowed(net: SpringNetwork) -> str:
    return f"node indices (a 1-D sequence of integers) or a bool mask of shape ({net.n_nodes}, 2)"


def _has_float(value: Any) -> bool:
    """True when ``value`` is a non-empty float (or complex) array or holds a float entry."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "O":
            return any(isinstance(v, float | complex | np.inexact) for v in value.ravel())
        return value.dtype.kind in "fc" and value.size > 0
    if isinstance(value, float | complex | np.inexact):
        return True
    if isinstance(value, list | tuple):
        return any(isinstance(v, float | complex | np.inexact) for v in value)
    return False


def _is_nested(value: Any) -> bool:
    if isinstance(value, np.ndarray):
        return True
    return isinstance(value, list | tuple) and any(isinstance(v, list | tuple) for v in value)


def _is_bool_nested(value: Any) -> bool:
    if not isinstance(value, list | tuple) or not value:
        return False
    first = value[0]
    return isinstance(first, list | tuple) and bool(first) and isinstance(first[0], bool)


#: clamp lengths allowed, as a factor of the clamped spring's rest length either way
CLAMP_RATIO = 1e6


def clamp_arrays(net: SpringNetwork, clamped: Any) -> tuple[NDArray, NDArray]:
    """``clamped`` ``{spring_index: length}`` as (m,) int64 indices and (m,) float lengths.

    Keys must be integers (a float key like 1.7 or a bool is refused, not truncated) naming
    springs in range; lengths finite, within :data:`CLAMP_RATIO` of the spring's rest length
    either way (strain -0.999999 .. 1e6): beyond that the forces of a clamp overflow or drown
    the local balance in round-off, so no method could meet ``tol``.
    """
    if clamped is None:
        return np.empty(0, np.int64), np.empty(0)
    clamped = check.mapping("clamped", clamped, "a mapping {spring_index: length}")
    idx = np.empty(len(clamped), dtype=np.int64)
    length = np.empty(len(clamped), dtype=np.float64)
    top = net.n_springs - 1
    for i, (k, v) in enumerate(clamped.items()):
        idx[i] = check.integer(
            "clamped key", k, low=0, high=top, what=f"a spring index in 0..{top}"
        )
        rest = float(net.rest_length[idx[i]])
        low, high = rest / CLAMP_RATIO, rest * CLAMP_RATIO
        length[i] = check.real(
            f"clamped[{idx[i]}]",
            v,
            low=low,
            high=high,
            what=f"a length in {low:.3g}..{high:.3g} (1e-6..1e6 x the spring's rest length)",
        )
    return idx, length


def solver_arguments(solver: Any, methods: tuple[str, ...]) -> tuple[int, ...]:
    """Check the fields of a learning ``Solver``; returns ``retry_ramps`` as a tuple of ints."""
    check.choice("method", solver.method, methods)
    check.choice("clamp", solver.clamp, ("exact", "rod"))
    check.real("tol", solver.tol, low=0, low_open=True)
    check.real("rod_stiffness", solver.rod_stiffness, low=0, low_open=True)
    if solver.max_iter is not None:
        check.integer("max_iter", solver.max_iter, low=1, what="None or an integer >= 1")
    check.integer("ramp", solver.ramp, low=1, high=MAX_RAMP)
    check.boolean("reuse", solver.reuse)
    check.real(
        "refactor_ratio", solver.refactor_ratio, low=0, high=1, low_open=True, high_open=True
    )
    check.boolean("accept_unconverged", solver.accept_unconverged)
    check.real("max_seconds", solver.max_seconds, low=0, low_open=True)
    ramps = solver.retry_ramps
    if isinstance(ramps, str) or not isinstance(ramps, tuple | list):
        raise check.ArgumentError("retry_ramps", ramps, "a tuple of integers >= 1")
    ramps = tuple(
        check.integer(f"retry_ramps[{i}]", r, low=1, high=MAX_RAMP) for i, r in enumerate(ramps)
    )
    check.integer("anderson", solver.anderson, low=0)
    check.boolean("trust_region", solver.trust_region)
    check.integer("trust_region_max_free", solver.trust_region_max_free, low=0)
    return ramps


def lone_nodes(net: SpringNetwork, free: NDArray[np.bool_]) -> None:
    """Refuse a network with a free coordinate on a node that no spring touches.

    Such a node can sit anywhere (its equilibrium is not unique); the Maxwell count does
    not always see it when the rest of the network has redundant springs.
    """
    touched = np.zeros(net.n_nodes, dtype=bool)
    touched[net.springs.ravel()] = True
    lone = np.flatnonzero(~touched & free.any(axis=1))
    if lone.size:
        raise check.ArgumentError(
            "net",
            net,
            "a network whose every free node has a spring",
            detail=f"node {lone[0]} ({lone.size} node(s) in all) has none; remove or pin it",
        )
