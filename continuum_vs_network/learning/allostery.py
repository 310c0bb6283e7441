"""The field's allosteric tasks, with desired strains set by a response ratio.

Rocks et al. (2017, PNAS) ask one source spring, strained by ``S_S``, to strain one distant
target spring by ``S_T = ratio * S_S`` (the allosteric response ratio); Stern et al. (2021,
PRX) ask 10 sources for 3 targets at once. :func:`allostery_task` builds both: sources drawn
at random, targets drawn among the springs about ``distance`` box sizes from the nearest
source, and every desired target strain a ratio of the source strains, so the task asks for
a *response* (a target that must follow its sources), not for strains drawn independently
of them. Trained with its rest example (:func:`~.examples.anchored`), a network meets such a
task only by transmitting the source strain: prestress alone leaves the error at half.

A draw whose target cannot be made to respond within the physical range is found by the
optimum (:meth:`~.optimum.Optimum.feasible`); a study flags or redraws it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..network.model import SpringNetwork
from .tasks import AllosteryTask, _candidates

__all__ = ["allostery_task", "spring_distances"]

#: half-width of the band of target distances, as a fraction of the distance asked for
_BAND = 0.1


def spring_distances(net: SpringNetwork, springs: ArrayLike) -> NDArray[np.float64]:
    """Distance of every spring's midpoint to the nearest midpoint of ``springs``,
    ``(n_springs,)``, in units of the box size (the larger side of the network's bounding box).
    """
    mid = 0.5 * (net.positions[net.springs[:, 0]] + net.positions[net.springs[:, 1]])
    box = float(np.max(np.ptp(net.positions, axis=0)))
    ref = mid[np.atleast_1d(np.asarray(springs, dtype=np.int64))]
    d = np.min(np.linalg.norm(mid[:, None, :] - ref[None, :, :], axis=2), axis=1)
    return d / box


def allostery_task(
    net: SpringNetwork,
    rng: np.random.Generator,
    *,
    n_sources: int = 1,
    n_targets: int = 1,
    ratio: float = 0.3,
    source_strain: float = 0.05,
    distance: float = 0.25,
    candidates: ArrayLike | None = None,
) -> AllosteryTask:
    """An allosteric task whose desired target strains are ``ratio`` times the source strain.

    Parameters
    ----------
    net : SpringNetwork
    rng : numpy.random.Generator
        Draws the sources, then the targets, then the signs.
    n_sources, n_targets : int
        1 and 1: Rocks et al.'s task; 10 and 3: Stern et al.'s.
    ratio : float
        Allosteric response ratio ``S_T / S_S`` asked for (non-zero; negative: the target
        shortens when the sources stretch).
    source_strain : float
        Magnitude of the source strains (> 0; 0.05 keeps a jammed network in linear
        response). One source is stretched by it; several get random signs.
    distance : float
        Distance of the targets from the nearest source, as a fraction of the box size
        (in (0, 1)); targets are drawn among the candidates within +-10 % of it (the nearest
        to it when fewer are there).
    candidates : int array or bool mask, optional
        Springs the sources and targets are drawn from. Default: every spring whose two
        nodes each have at least 3 springs (a dyad's springs stay at rest whatever is
        learned). A cheap local test, so that a 1e5-node network draws its task at once;
        :func:`~continuum_vs_network.network.strain_tunable` is the exact one (a global
        self-stress computation). A target that still cannot be made to respond is found
        by the optimum.

    Returns
    -------
    AllosteryTask
        One target's desired strain is ``ratio * S_S`` (one source), or ``+-ratio *
        source_strain`` with random signs (several sources: the target follows the sources'
        overall scale, its sign drawn).
    """
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    ratio = check.real("ratio", ratio)
    if ratio == 0.0:
        raise check.ArgumentError("ratio", ratio, "a non-zero response ratio S_T / S_S")
    source_strain = check.real("source_strain", source_strain, low=0, low_open=True, high=1)
    distance = check.real("distance", distance, low=0, high=1, low_open=True, high_open=True)
    if candidates is None:
        degree = np.bincount(net.springs.ravel(), minlength=net.n_nodes)
        candidates = np.all(degree[net.springs] >= 3, axis=1)
    pool = _candidates(net, candidates)
    if pool.size < n_sources + n_targets:
        raise ValueError(
            f"need {n_sources + n_targets} candidate springs, the network offers {pool.size}"
        )
    sources = rng.choice(pool, size=n_sources, replace=False)
    rest = np.setdiff1d(pool, sources)
    d = spring_distances(net, sources)[rest]
    near = np.abs(d - distance) <= _BAND * distance
    if near.sum() >= n_targets:
        targets = rng.choice(rest[near], size=n_targets, replace=False)
    else:
        targets = rest[np.argsort(np.abs(d - distance), kind="stable")[:n_targets]]
    if n_sources == 1:
        s_source = np.array([source_strain])
        s_target = np.full(n_targets, ratio * source_strain)
    else:
        s_source = source_strain * rng.choice([-1.0, 1.0], size=n_sources)
        s_target = ratio * source_strain * rng.choice([-1.0, 1.0], size=n_targets)
    return AllosteryTask.create(net, sources, s_source, targets, s_target)
