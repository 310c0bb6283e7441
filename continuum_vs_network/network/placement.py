"""Rigid motion under default pins: the frame a solve runs in, and placement on the pins.

Default pins (:func:`~.constraints.default_pins`: one node ``a`` fully, one coordinate of a
far node ``b``) only remove rigid motion, and must carry no load. They do while the lever
``b - a`` has a component along ``b``'s free coordinate; a network that shrinks until
that lever is no longer than ``b``'s offset from ``a`` along its pinned coordinate turns
the pin into a strut. Prestressed networks (rest lengths 0.3-3x the geometry) shrink that
far: a solve then converges against such a strut, finds the pins loaded, and relaxes
again with new ones.

:func:`lever_frame` removes the offset: the solve runs with the network turned about ``a``
so that the lever is the x axis, ``b``'s y pinned. ``b`` then stays on the line through
``a`` in the lever's start direction, free to approach ``a`` until they meet.
:func:`place_on_pins` moves the result rigidly back onto the default pins. The frame's
origin is ``a``'s start, so the solve also works in coordinates of the network's size,
whose round-off is that of the network, not of its distance from 0 (a network far from
0 converges in the frame, and a tolerance below float64's reach there is found soon).
Measurements: ``docs/solver-notes.md#placement``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .constraints import Problem

__all__ = ["LeverFrame", "lever_frame", "place_on_pins"]


def _pins(free: NDArray) -> tuple[list[int], list[int]]:
    """The nodes a pin mask ``free`` (n_nodes, 2) pins fully, and its other pinned flat
    coordinates."""
    pins = np.flatnonzero(~free.ravel()).tolist()  # scalars: math, not numpy (overhead)
    nodes = [p // 2 for p in pins]
    full = [i for i in dict.fromkeys(nodes) if nodes.count(i) == 2]
    return full, [p for p in pins if nodes.count(p // 2) == 1]


@dataclass(frozen=True)
class LeverFrame:
    """The frame of :func:`lever_frame`: node ``a``'s start position ``origin`` (2,) and
    the turn ``rotation`` (2, 2) that takes the lever onto the x axis."""

    origin: NDArray
    rotation: NDArray

    def into(self, x: NDArray) -> NDArray:
        """Positions (n_nodes, 2) in the frame: turned about ``origin``, which becomes 0
        (coordinates of the network's size round less than those far from 0 would)."""
        return (x - self.origin) @ self.rotation.T

    def back(self, x: NDArray) -> NDArray:
        """Positions (n_nodes, 2) in the frame turned and moved back out of it."""
        return x @ self.rotation + self.origin


def lever_frame(problem: Problem, x: NDArray) -> tuple[Problem, LeverFrame] | None:
    """For ``problem`` under default pins (node ``a`` fully, one coordinate of ``b``), the
    problem pinned at ``a`` fully and at ``b``'s y, and the frame in which ``b - a`` is the
    x axis at ``x`` (n_nodes, 2); None for other pins, or ``b`` on ``a``."""
    full, part = _pins(problem.free)
    if len(full) != 1 or len(part) != 1:
        return None
    a, b = full[0], part[0] // 2
    dx, dy = (x[b] - x[a]).tolist()
    r = math.hypot(dx, dy)
    if not r > 0.0 or not math.isfinite(r):
        return None
    cos, sin = dx / r, dy / r
    rotation = np.array([[cos, sin], [-sin, cos]])  # turns (dx, dy) onto (r, 0)
    free = np.ones_like(problem.free)
    free[a] = False
    free[b, 1] = False
    return problem.with_free(free), LeverFrame(x[a].copy(), rotation)


def place_on_pins(x: NDArray, start: NDArray, free: NDArray) -> NDArray:
    """``x`` (n_nodes, 2) moved rigidly onto the pins of ``free`` (one node fully, one
    coordinate of another, as :func:`~.constraints.default_pins` gives) at ``start``.

    The fully pinned node goes to its start position; the network is turned about it so
    that the other pinned coordinate keeps its start value (of the two such turns, the one
    closer to the start's orientation), or, when the network has shrunk too much for that,
    so that the pair has its start orientation.
    """
    full, part = _pins(free)
    if not full:
        return x
    a = full[0]
    start_a = start[a]
    y = x - x[a] + start_a
    if not part:
        return y
    b, c = divmod(part[0], 2)
    (dx, dy), (d0x, d0y) = (y[b] - y[a]).tolist(), (start[b] - start_a).tolist()
    r = math.hypot(dx, dy)
    want = math.atan2(d0y, d0x)
    t = (d0x, d0y)[c] / max(r, 1e-300)
    if abs(t) <= 1.0:
        base = math.asin(t) if c == 1 else math.acos(t)
        options = (base, math.pi - base) if c == 1 else (base, -base)
        want = min(options, key=lambda o: abs(math.remainder(o - want, 2 * math.pi)))
    turn = want - math.atan2(dy, dx)
    cos, sin = math.cos(turn), math.sin(turn)
    y = (y - y[a]) @ np.array([[cos, sin], [-sin, cos]]) + start_a
    y[b, c] = start[b, c] if abs(t) <= 1.0 else y[b, c]  # exact, not to round-off
    y[a] = start_a
    return y
