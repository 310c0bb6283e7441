"""Allosteric tasks: strain some source springs, ask for chosen strains at target springs.

A task names source springs with the strains they are clamped at and target springs with
the strains they should show in the free state (Sec. 6.4). The task error is Eq. 26,
``C = sum_T (S_T^F - S_T)^2 / 2``.

A strain ``S = r / L - 1`` (Eq. 24) needs a reference rest length. Two conventions are
supported everywhere, under one parameter name, ``strain_reference``:

``"initial"`` (the default everywhere)
    ``L`` is the rest length the spring had when the task was made (stored on the task), so
    clamp lengths are fixed and the strain error is a length error in disguise: the targets
    are fixed geometries. Coupled learning descends the task error in this convention.
``"current"``
    The paper's literal convention: ``L`` is the spring's current, learning rest length, so
    clamp lengths ``L (S + 1)`` (Eq. 25) and measured strains move as ``L`` learns (where
    coupled learning does not descend Eq. 26 and prospective configuration runs away; see
    :mod:`.rules`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _validate as check
from ..network.constraints import default_pins
from ..network.model import SpringNetwork

__all__ = [
    "STRAIN_REFERENCES",
    "AllosteryTask",
    "StrainReference",
    "check_strain_reference",
    "paper_task",
    "stern_task",
]

StrainReference = Literal["initial", "current"]
#: the strain conventions, the default first
STRAIN_REFERENCES = ("initial", "current")


def check_strain_reference(strain_reference: object) -> None:
    """Raise ``ValueError`` unless ``strain_reference`` is ``"initial"`` or ``"current"``."""
    check.choice("strain_reference", strain_reference, STRAIN_REFERENCES)


def _frozen(value: ArrayLike, dtype: type, name: str) -> NDArray:
    if dtype is np.float64:
        arr = check.float_array(name, np.atleast_1d(value)).reshape(-1)
    else:
        arr = check.index_array(name, np.atleast_1d(value), check.INT64_MAX, what="spring indices")
        arr = arr.reshape(-1)
    arr.setflags(write=False)
    return arr


def _frozen_mask(value: ArrayLike, name: str = "pinned") -> NDArray[np.bool_]:
    """A read-only copy of a (n_nodes, 2) bool pin mask; anything else is refused."""
    mask = np.asarray(value)
    if mask.dtype != bool or mask.ndim != 2 or mask.shape[1] != 2:
        raise check.ArgumentError(name, value, "a bool mask of shape (n_nodes, 2)")
    mask = mask.copy()
    mask.setflags(write=False)
    return mask


@dataclass(frozen=True, eq=False)
class AllosteryTask:
    """Source springs clamped at strains; target springs that should reach strains.

    Build one with :meth:`create` (which records the reference rest lengths and the pins)
    or with :func:`paper_task` / :func:`stern_task`.

    Attributes
    ----------
    sources : (n_sources,) int array
        Spring indices clamped in every state.
    source_strain : (n_sources,) float array
        Strains ``S_s > -1`` the sources are clamped at (Eq. 25).
    targets : (n_targets,) int array
        Spring indices whose free-state strain is the output.
    target_strain : (n_targets,) float array
        Desired strains ``S_T > -1``.
    source_rest_length, target_rest_length : (n_sources,), (n_targets,) float arrays
        Rest lengths of the sources and targets when the task was made: the reference of
        the ``"initial"`` strain convention.
    pinned : (n_nodes, 2) bool array
        Coordinates held fixed in every state (rigid-body motion removed away from the
        sources and targets). The same mask is used for the free and clamped states.
    """

    sources: NDArray[np.int64]
    source_strain: NDArray[np.float64]
    targets: NDArray[np.int64]
    target_strain: NDArray[np.float64]
    source_rest_length: NDArray[np.float64]
    target_rest_length: NDArray[np.float64]
    pinned: NDArray[np.bool_]

    def __post_init__(self) -> None:
        fields = {
            "sources": _frozen(self.sources, np.int64, "sources"),
            "source_strain": _frozen(self.source_strain, np.float64, "source_strain"),
            "targets": _frozen(self.targets, np.int64, "targets"),
            "target_strain": _frozen(self.target_strain, np.float64, "target_strain"),
            "source_rest_length": _frozen(
                self.source_rest_length, np.float64, "source_rest_length"
            ),
            "target_rest_length": _frozen(
                self.target_rest_length, np.float64, "target_rest_length"
            ),
        }
        fields["pinned"] = _frozen_mask(self.pinned)
        for name, value in fields.items():
            object.__setattr__(self, name, value)
        for kind in ("source", "target"):
            idx = fields[f"{kind}s"]
            for what in (f"{kind}_strain", f"{kind}_rest_length"):
                if fields[what].shape != idx.shape:
                    raise ValueError(
                        f"{what} must have one entry per {kind} ({idx.size}), "
                        f"got {fields[what].size}"
                    )
            if np.unique(idx).size != idx.size:
                raise ValueError(f"{kind}s must be distinct, got {idx.tolist()}")
            bad = np.flatnonzero(fields[f"{kind}_strain"] <= -1.0)
            if bad.size:
                raise ValueError(
                    f"{kind}_strain must be > -1 (a positive clamp length), "
                    f"{kind}_strain[{bad[0]}] = {fields[f'{kind}_strain'][bad[0]]}"
                )
            bad = np.flatnonzero(fields[f"{kind}_rest_length"] <= 0.0)
            if bad.size:
                raise ValueError(f"{kind}_rest_length must be > 0")
        if fields["targets"].size == 0:
            raise ValueError("a task needs at least one target spring")
        both = np.intersect1d(fields["sources"], fields["targets"])
        if both.size:
            raise ValueError(f"spring {both[0]} is both a source and a target")

    # -- construction -------------------------------------------------------------------
    @classmethod
    def create(
        cls,
        net: SpringNetwork,
        sources: ArrayLike,
        source_strain: ArrayLike,
        targets: ArrayLike,
        target_strain: ArrayLike,
        *,
        pinned: ArrayLike | None = None,
    ) -> AllosteryTask:
        """A task on ``net``: records its rest lengths as the reference and its pins.

        ``pinned`` defaults to :func:`~continuum_vs_network.network.default_pins` computed
        away from the sources and targets.
        """
        if not isinstance(net, SpringNetwork):
            raise check.ArgumentError("net", net, "a SpringNetwork")
        top = net.n_springs
        sources = check.index_array("sources", np.atleast_1d(sources), top, what="spring indices")
        targets = check.index_array("targets", np.atleast_1d(targets), top, what="spring indices")
        source_strain = check.float_array("source_strain", source_strain)
        target_strain = check.float_array("target_strain", target_strain)
        if pinned is None:
            pinned = default_pins(net, avoid=np.concatenate([sources, targets]))
        task = cls(
            sources=sources,
            source_strain=np.broadcast_to(np.asarray(source_strain, float), sources.shape),
            targets=targets,
            target_strain=np.broadcast_to(np.asarray(target_strain, float), targets.shape),
            source_rest_length=net.rest_length[sources],
            target_rest_length=net.rest_length[targets],
            pinned=pinned,
        )
        task.check(net)
        return task

    def with_source_strain(self, source_strain: ArrayLike) -> AllosteryTask:
        """A copy with new source strains (same springs, references and pins)."""
        strain = np.broadcast_to(np.asarray(source_strain, float), self.sources.shape)
        return _replace(self, source_strain=strain)

    def with_target_strain(self, target_strain: ArrayLike) -> AllosteryTask:
        """A copy with new desired target strains."""
        strain = np.broadcast_to(np.asarray(target_strain, float), self.targets.shape)
        return _replace(self, target_strain=strain)

    def check(self, net: SpringNetwork) -> None:
        """Raise ``ValueError`` if the task does not fit ``net``."""
        top = max(int(self.sources.max(initial=-1)), int(self.targets.max()))
        if top >= net.n_springs:
            raise ValueError(f"task names spring {top} but the network has {net.n_springs}")
        if self.pinned.shape != (net.n_nodes, 2):
            raise ValueError(
                f"task.pinned has shape {self.pinned.shape}, network has {net.n_nodes} nodes"
            )

    # -- lengths and strains ------------------------------------------------------------
    @property
    def n_sources(self) -> int:
        return int(self.sources.size)

    @property
    def n_targets(self) -> int:
        return int(self.targets.size)

    def _reference(self, net: SpringNetwork, strain_reference: str, which: str) -> NDArray:
        check_strain_reference(strain_reference)
        if strain_reference == "initial":
            return self.source_rest_length if which == "source" else self.target_rest_length
        return net.rest_length[self.sources if which == "source" else self.targets]

    def source_rest(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> NDArray:
        """Reference rest lengths of the sources, (n_sources,)."""
        return self._reference(net, strain_reference, "source")

    def target_rest(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> NDArray:
        """Reference rest lengths of the targets, (n_targets,)."""
        return self._reference(net, strain_reference, "target")

    def source_lengths(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> NDArray:
        """Clamp lengths ``L_s (S_s + 1)`` of the sources (Eq. 25), (n_sources,)."""
        return self.source_rest(net, strain_reference) * (self.source_strain + 1.0)

    def desired_lengths(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> NDArray:
        """Target lengths ``L_T (S_T + 1)`` that realise the desired strains, (n_targets,)."""
        return self.target_rest(net, strain_reference) * (self.target_strain + 1.0)

    def source_clamps(
        self, net: SpringNetwork, strain_reference: StrainReference = "initial"
    ) -> dict[int, float]:
        """``{source: clamp length}`` for :func:`~continuum_vs_network.relax`."""
        return dict(zip(self.sources.tolist(), self.source_lengths(net, strain_reference).tolist()))

    def target_strains(
        self,
        net: SpringNetwork,
        target_lengths: ArrayLike,
        strain_reference: StrainReference = "initial",
    ) -> NDArray:
        """Strains ``r_T / L_T - 1`` of targets of lengths ``target_lengths`` (n_targets,)."""
        return np.asarray(target_lengths, float) / self.target_rest(net, strain_reference) - 1.0

    def error(
        self,
        net: SpringNetwork,
        positions: ArrayLike,
        strain_reference: StrainReference = "initial",
    ) -> float:
        """Task error ``C = sum_T (S_T^F - S_T)^2 / 2`` (Eq. 26) at free-state ``positions``."""
        r = net.lengths(positions, self.targets)
        err = self.target_strains(net, r, strain_reference) - self.target_strain
        return float(0.5 * np.sum(err**2))


def _replace(task: AllosteryTask, **changes) -> AllosteryTask:
    import dataclasses

    return dataclasses.replace(task, **changes)


def _positive_normal(rng: np.random.Generator, mean: float, std: float, size: int) -> NDArray:
    """Normal draws, redrawn until every value is a valid strain (> -1 + 1e-3)."""
    out = rng.normal(mean, std, size)
    for _ in range(1000):
        bad = out <= -1.0 + 1e-3
        if not bad.any():
            return out
        out[bad] = rng.normal(mean, std, int(bad.sum()))
    raise ValueError(f"could not draw strains > -1 from N({mean}, {std})")


def paper_task(
    net: SpringNetwork,
    rng: np.random.Generator,
    *,
    candidates: ArrayLike | None = None,
    source_mean: float = 5.0,
    source_std: float = 1.0,
    target_mean: float = 5.0,
    target_scale: float = 0.2,
) -> AllosteryTask:
    """The paper's task (Sec. 7.1): one source, one target, large strains.

    ``S_source ~ N(5, 1)`` and ``S_target ~ N(5, 0.2 * sum_s |S_s|)``. The paper writes the
    target law as ``N(5, 0.2 sum S)`` "scaled by the source strain"; it is read here as a
    normal distribution of mean 5 and *standard deviation* ``0.2`` times the summed absolute
    source strains (about 1 for one source near 5). Draws that would give a strain
    ``<= -1`` are redrawn (they have probability ~1e-9 here).

    Parameters
    ----------
    net : SpringNetwork
    rng : numpy.random.Generator
    candidates : (n_springs,) bool mask or int indices, optional
        Springs the source and target are drawn from, without replacement. Default:
        ``strain_tunable(net)`` from :mod:`continuum_vs_network.network.builders`, the
        springs whose free strain learning can change (on the paper's patch, springs at a
        corner node form a dyad whose free strain stays 0 whatever the rest lengths).

    Returns
    -------
    AllosteryTask
    """
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    source_mean = check.real("source_mean", source_mean)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    target_mean = check.real("target_mean", target_mean)
    target_scale = check.real("target_scale", target_scale, low=0, low_open=True)
    pool = _candidates(net, candidates)
    if pool.size < 2:
        raise ValueError(f"need at least 2 candidate springs, got {pool.size}")
    source, target = rng.choice(pool, size=2, replace=False)
    s_source = _positive_normal(rng, source_mean, source_std, 1)
    std = target_scale * float(np.sum(np.abs(s_source)))
    s_target = _positive_normal(rng, target_mean, std, 1)
    return AllosteryTask.create(net, [source], s_source, [target], s_target)


def stern_task(
    net: SpringNetwork,
    n_sources: int = 10,
    n_targets: int = 3,
    rng: np.random.Generator | None = None,
    *,
    candidates: ArrayLike | None = None,
    source_std: float = 0.1,
    target_std: float = 0.1,
) -> AllosteryTask:
    """Stern-scale allostery (Sec. 6.4): ``n_sources`` sources and ``n_targets`` targets.

    Springs are drawn without replacement among ``candidates`` (default:
    ``strain_tunable(net)``, as in :func:`paper_task`).
    Source strains and desired target strains are drawn from ``N(0, source_std)`` and
    ``N(0, target_std)`` (strains of order 10 %, in the linear-response regime of networks
    of N >= 512 nodes; the distributions are this package's choice, the reference paper
    gives none). ``rng`` is required; it comes after the counts to follow the paper's
    ``stern_task(net, n_sources, n_targets, rng)`` order.
    """
    if not isinstance(rng, np.random.Generator):
        raise check.ArgumentError("rng", rng, "a numpy.random.Generator")
    n_sources = check.integer("n_sources", n_sources, low=1)
    n_targets = check.integer("n_targets", n_targets, low=1)
    source_std = check.real("source_std", source_std, low=0, low_open=True)
    target_std = check.real("target_std", target_std, low=0, low_open=True)
    pool = _candidates(net, candidates)
    if pool.size < n_sources + n_targets:
        raise ValueError(
            f"need {n_sources + n_targets} candidate springs, the network offers {pool.size}"
        )
    chosen = rng.choice(pool, size=n_sources + n_targets, replace=False)
    s_source = _positive_normal(rng, 0.0, source_std, n_sources)
    s_target = _positive_normal(rng, 0.0, target_std, n_targets)
    return AllosteryTask.create(net, chosen[:n_sources], s_source, chosen[n_sources:], s_target)


def _candidates(net: SpringNetwork, candidates: ArrayLike | None) -> NDArray[np.int64]:
    if not isinstance(net, SpringNetwork):
        raise check.ArgumentError("net", net, "a SpringNetwork")
    if candidates is None:
        from ..network.builders import strain_tunable

        candidates = strain_tunable(net)
    arr = np.asarray(candidates)
    if arr.dtype == bool:
        if arr.shape != (net.n_springs,):
            raise ValueError(
                f"candidates as a mask must have shape ({net.n_springs},), got {arr.shape}"
            )
        return np.flatnonzero(arr)
    arr = check.index_array(
        "candidates", np.atleast_1d(arr).ravel(), net.n_springs, what="spring indices"
    )
    return np.unique(arr)
