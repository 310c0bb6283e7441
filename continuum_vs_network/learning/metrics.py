"""Quantities computed from histories and trained networks.

Error curves (Fig. 4, 6, 8-10 of the paper) are per-trial arrays scaled by their initial
value; :func:`summary` reduces the final values over trials; :func:`source_sweep` is the
response of a trained network to other source strains (Fig. 5, appendix A.2 / A.3);
:func:`tail_change` and :func:`bound` tell whether a curve has settled (the plateau test).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..network.model import SpringNetwork
from .history import History
from .states import Solver, Tracker
from .tasks import AllosteryTask, StrainReference

__all__ = [
    "PLATEAU",
    "bound",
    "cosine",
    "final_values",
    "first_below",
    "length_error",
    "normalised",
    "relative_error",
    "rest_length_error",
    "source_sweep",
    "summary",
    "tail_change",
]

#: a curve has plateaued when its fitted relative change over the window a floor or a final
#: value is read from (the last quarter of the steps) is at most this; else it is still
#: falling (the value read is an upper bound of where the run settles) or still rising (a
#: lower bound)
PLATEAU = 0.1


def first_below(values: ArrayLike, level: float) -> int | None:
    """Index of the first entry of ``values`` (a 1-D curve, e.g. C/C0 per step) that is
    ``<= level``; None when none is."""
    hit = np.flatnonzero(np.asarray(values) <= level)
    return int(hit[0]) if hit.size else None


def normalised(values: ArrayLike) -> NDArray:
    """``values / values[..., :1]`` per trial (curves scaled by their initial value).

    ``values`` is (trials, steps + 1); a trial whose initial value is 0 gives NaN.
    """
    v = np.asarray(values, dtype=np.float64)
    first = v[..., :1]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(first != 0, v / np.where(first != 0, first, 1.0), np.nan)


def length_error(history: History) -> NDArray:
    """Fig. 8: ``sum_T |r_T^F - l_T|``, distance of the free target lengths from the
    lengths that give the desired strains (the GPC clamp lengths), (trials, steps + 1)."""
    return np.sum(np.abs(history.target_length - history.desired_length), axis=-1)


def rest_length_error(history: History) -> NDArray:
    """Fig. 9: ``sum_T |L_T - l_T|``, distance of the target rest lengths from the
    lengths that give the desired strains, (trials, steps + 1)."""
    return np.sum(np.abs(history.target_rest_length - history.desired_length), axis=-1)


def tail_change(error: ArrayLike, *, fraction: float = 0.25) -> float:
    """Fitted relative change of the error over its last ``fraction`` of entries: a least
    squares line through log(error) against the step, ``exp(slope * (n - 1)) - 1`` over
    the ``n = max(1, size * fraction)`` last entries (the window the floor is the median
    of); NaN when fewer than 2 entries or any is not finite and positive.

    ``error`` : (steps + 1,) float array (any scale).
    """
    e = np.asarray(error, dtype=np.float64).ravel()
    tail = e[-max(1, int(e.size * fraction)) :]
    if tail.size < 2 or not np.all(np.isfinite(tail) & (tail > 0)):
        return float("nan")
    slope = np.polyfit(np.arange(tail.size, dtype=float), np.log(tail), 1)[0]
    return float(np.expm1(slope * (tail.size - 1)))


def bound(change: float) -> str:
    """What a value read at the end of a curve is, from :func:`tail_change`: "plateau"
    (``|change| <= PLATEAU``), "upper bound" (still falling), "lower bound" (still rising)
    or "unknown" (NaN)."""
    if not np.isfinite(change):
        return "unknown"
    if abs(change) <= PLATEAU:
        return "plateau"
    return "upper bound" if change < 0 else "lower bound"


def final_values(values: ArrayLike, completed: ArrayLike | None = None) -> NDArray:
    """The last measured value of every trial, (trials,).

    ``completed`` (from a history) picks entry ``completed[i]`` of trial ``i``, or the last
    finite entry before it when there is none there (a trial that stopped because its
    equilibrium was lost has no measurement at ``completed``: it would otherwise drop out
    of every median and mean silently); without it the last finite entry is used.
    """
    v = np.asarray(values, dtype=np.float64)
    last = v.shape[1] - 1
    idx = np.full(v.shape[0], last) if completed is None else np.asarray(completed, np.int64)
    idx = np.minimum(idx, last)
    out = v[np.arange(v.shape[0]), idx]
    for i in np.flatnonzero(~np.isfinite(out)):
        finite = np.flatnonzero(np.isfinite(v[i, : idx[i] + 1]))
        if finite.size:
            out[i] = v[i, finite[-1]]
    return out


def summary(values: ArrayLike, completed: ArrayLike | None = None) -> dict[str, float]:
    """Median, quartiles, mean, min and max over trials of the final *normalised* values.

    ``values`` (trials, steps + 1) is normalised by its initial entries first. Trials
    without a finite final value are left out and counted in ``"missing"``.
    """
    final = final_values(normalised(values), completed)
    ok = final[np.isfinite(final)]
    if not ok.size:
        return {"n": 0, "missing": int(final.size)}
    return {
        "n": int(ok.size),
        "missing": int(final.size - ok.size),
        "median": float(np.median(ok)),
        "q25": float(np.quantile(ok, 0.25)),
        "q75": float(np.quantile(ok, 0.75)),
        "mean": float(np.mean(ok)),
        "min": float(np.min(ok)),
        "max": float(np.max(ok)),
    }


def cosine(a: ArrayLike, b: ArrayLike) -> float:
    """Cosine of the angle between two vectors."""
    a, b = np.ravel(a), np.ravel(b)
    return float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))


def relative_error(a: ArrayLike, reference: ArrayLike) -> float:
    """``|a - reference| / |reference|`` (Euclidean norms)."""
    a, ref = np.ravel(a), np.ravel(reference)
    return float(np.linalg.norm(a - ref) / np.linalg.norm(ref))


def source_sweep(
    net: SpringNetwork,
    task: AllosteryTask,
    source_strains: ArrayLike,
    *,
    strain_reference: StrainReference = "initial",
    solver: Solver | None = None,
) -> NDArray:
    """Free-state target strains of ``net`` for other source strains (Fig. 5).

    Parameters
    ----------
    net, task : a (trained) network and its task.
    source_strains : (n_points,) or (n_points, n_sources) float array
        Source strains to apply (one value applies to every source).
    strain_reference : strain convention of clamps and read-out.
    solver : Solver, optional

    Returns
    -------
    (n_points, n_targets) float array
        Target strains. Points are solved by continuation from the task's own source
        strain outwards (warm starts), so a sweep follows one branch of equilibria.
    """
    s = np.asarray(source_strains, dtype=np.float64)
    if s.ndim == 1:
        s = np.repeat(s[:, None], task.n_sources, axis=1)
    if s.ndim != 2 or s.shape[1] != task.n_sources:
        raise ValueError(f"source_strains must be (n_points,) or (n_points, {task.n_sources})")
    tracker = Tracker(solver or Solver())
    start = tracker.solve(
        net, task.pinned, task.source_clamps(net, strain_reference), None, key="free"
    ).positions
    distance = np.linalg.norm(s - task.source_strain, axis=1)
    out = np.empty((s.shape[0], task.n_targets))
    above = np.mean(s - task.source_strain, axis=1) >= 0
    for branch in (above, ~above):
        x = start
        for i in np.flatnonzero(branch)[np.argsort(distance[branch])]:
            t = task.with_source_strain(s[i])
            eq = tracker.solve(
                net, task.pinned, t.source_clamps(net, strain_reference), x, key="free"
            )
            x = eq.positions
            out[i] = t.target_strains(net, net.lengths(x, task.targets), strain_reference)
    return out
