"""The base of every learning rule: its options and what every rule shares.

:class:`Rule` checks the options, masks and floors a raw update, finds the states several
rules read (the free state, the fully clamped state), sums the updates of a task set's
examples, and asks any other learning medium (:mod:`.medium`) for its states. A rule
supplies ``_update`` (one step on a spring network) and ``_medium_step`` (on another
medium); the rules themselves are in :mod:`.rules`.

Options every rule honours: ``dof`` (``"rest_length"``, ``"stiffness"``, or ``"both"``:
rest lengths and stiffnesses learned together, each by its own line of the rule, from the
same states; the exact gradient's two rows are the gradient with respect to both),
``learn_sources`` and ``learn_targets`` (both False by
default: bulk learning; a target that learns its own rest length meets the task trivially,
without the bulk transmitting anything, see :mod:`.coupling`),
``strain_reference`` (``"initial"``, the default: fixed clamp lengths from the task's
recorded rest lengths, the convention in which the rules learn; ``"current"``: the paper's
literal ``S = r / L - 1`` with the learning ``L``),
floors ``min_rest_length`` / ``min_stiffness``, the physical range ``stiffness_range`` /
``rest_length_range`` (factors of the values when training started, :mod:`.ranges`), the
rate (``alpha``, the paper's raw rate, or ``rate``, a scale-free rate, the rule's
``default_rate`` when ``alpha`` is left out: :mod:`.rates`), and the equilibrium ``solver``.

A step is made in one place (:meth:`Rule.update`): the rule's raw line, masked, then the
rate, then the floors and the range.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..network.equilibrium import Equilibrium
from ..network.model import SpringNetwork
from .examples import TaskSet
from .node_tasks import NodeTask
from .ranges import STIFFNESS_RANGE, check_range, clip_to_range
from .rates import Adaptive, Rate, RateState, Scaled
from .readout import Readout
from .states import Solver, Tracker
from .step import JOINT, Dof, Step, Warm, check_finite_update
from .tasks import AllosteryTask, StrainReference, check_strain_reference

__all__ = ["Rule"]

_NETWORK_DOFS = ("rest_length", "stiffness", "both")


def _plain(value: object) -> object:
    """Tuples as lists, so that settings survive a JSON round trip unchanged."""
    return list(value) if isinstance(value, tuple) else value


@dataclass(frozen=True, kw_only=True)
class Rule:
    """Options shared by every rule (see the module docstring)."""

    dof: Dof = "rest_length"
    learn_sources: bool = False
    learn_targets: bool = False
    strain_reference: StrainReference = "initial"
    min_rest_length: float | None = None
    min_stiffness: float | None = None
    stiffness_range: tuple[float, float] | None = STIFFNESS_RANGE
    rest_length_range: tuple[float, float] | None = None
    rate: Rate | None = None
    solver: Solver = field(default_factory=Solver)

    def __post_init__(self) -> None:
        for name in ("stiffness_range", "rest_length_range"):
            object.__setattr__(self, name, check_range(name, getattr(self, name)))
        if self.rate is not None and not isinstance(self.rate, Adaptive | Scaled):
            raise check.ArgumentError("rate", self.rate, "None, an Adaptive or a Scaled rate")
        alpha = getattr(self, "alpha", None)
        if alpha is not None:
            check.real("alpha", alpha, low=0, low_open=True)
            if self.rate is not None:
                raise ValueError(
                    "give alpha (the paper's raw rate) or rate (an adaptive rate), not both"
                )
        check.choice(
            "dof", self.dof, ("rest_length", "stiffness", "both", "eigenstrain", "modulus")
        )
        check_strain_reference(self.strain_reference)
        check.boolean("learn_sources", self.learn_sources)
        check.boolean("learn_targets", self.learn_targets)
        for name in ("min_rest_length", "min_stiffness"):
            value = getattr(self, name)
            if value is not None:
                check.real(name, value, low=0, what="None or a finite number >= 0")
        if not isinstance(self.solver, Solver):
            raise ValueError(f"solver must be a Solver, got {type(self.solver).__name__}")

    # -- what every rule shares -------------------------------------------------------
    @property
    def name(self) -> str:
        return type(self).__name__

    @property
    def uses_free_state(self) -> bool:
        return True

    #: the rate used when neither ``alpha`` nor ``rate`` is given
    default_rate: ClassVar[Rate] = Adaptive()

    @property
    def adaptive(self) -> Rate | None:
        """The scale-free rate in use (``rate``, or ``default_rate`` when ``alpha`` is None);
        None when the rule runs at the raw rate ``alpha``."""
        if getattr(self, "alpha", None) is not None:
            return None
        return self.rate or self.default_rate

    @property
    def _alpha(self) -> float:
        """The factor of the rule's raw line: ``alpha``, or 1 under an adaptive rate (which
        does not depend on it)."""
        alpha = getattr(self, "alpha", None)
        return 1.0 if alpha is None else float(alpha)

    def settings(self) -> dict[str, object]:
        """The rule's parameters as a flat dict of plain values (for histories)."""
        out: dict[str, object] = {"rule": self.name}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "rate":
                value = self.adaptive
                out["rate"] = "raw" if value is None else type(value).__name__
                for g in dataclasses.fields(Adaptive):
                    out[f"rate.{g.name}"] = getattr(value, g.name, None)
            elif isinstance(value, Solver):
                for g in dataclasses.fields(value):
                    out[f"solver.{g.name}"] = _plain(getattr(value, g.name))
            else:
                out[f.name] = _plain(value)
        return out

    def learning_mask(self, net: SpringNetwork, task: AllosteryTask) -> NDArray[np.bool_]:
        """Springs (elements of a continuum) whose degree of freedom may change, bool."""
        if not isinstance(net, SpringNetwork):
            return net.learning_mask(
                task, learn_sources=self.learn_sources, learn_targets=self.learn_targets
            )
        mask = np.ones(net.n_springs, dtype=bool)
        if not self.learn_sources:
            mask[task.sources] = False
        if not self.learn_targets:
            mask[task.targets] = False
        return mask

    def _delta(self, net: SpringNetwork, task: AllosteryTask, raw: NDArray) -> NDArray:
        """``raw`` with the springs that do not learn set to 0 (rows for "both")."""
        mask = self.learning_mask(net, task)
        return np.where(mask, raw, 0.0)

    def _values(self, net: SpringNetwork) -> NDArray:
        """The learning dofs of ``net``: ``(n,)``, or ``(2, n)`` rows JOINT for "both"."""
        pick = {"rest_length": net.rest_length, "stiffness": net.stiffness}
        if self.dof == "both":
            return np.stack([pick[d] for d in JOINT])
        return pick[self.dof].copy()

    def _rate_step(self, net, task, raw: NDArray, warm: Warm) -> tuple[NDArray, RateState]:
        """The step from the summed, masked raw line: the rate, then floors and range."""
        state = warm.rate
        if state is None or np.shape(state.initial) != np.shape(raw):
            state = RateState.start(self._values(net))
        raw = self._delta(net, task, raw)
        dofs = JOINT if self.dof == "both" else (self.dof,)
        adaptive = self.adaptive
        if adaptive is not None:
            initial = np.atleast_2d(state.initial)
            scale = np.array([
                np.mean(initial[i]) * (_strain_scale(task) if d == "rest_length" else 1.0)
                for i, d in enumerate(dofs)
            ])  # fmt: skip
            step, state = adaptive.delta(raw, scale[:, None] if raw.ndim == 2 else scale, state)
        else:
            step = raw
        rows = [
            self._bounded(net, d, row, init)
            for d, row, init in zip(dofs, np.atleast_2d(step), np.atleast_2d(state.initial))
        ]
        return (np.stack(rows) if self.dof == "both" else rows[0]), state

    def _bounded(self, net, dof: str, delta: NDArray, initial: NDArray | None) -> NDArray:
        """Floor (stops a decrease; never lifts a value), then the physical range relative
        to ``initial`` (none when None)."""
        rest = dof == "rest_length"
        old = net.rest_length if rest else net.stiffness
        floor = self.min_rest_length if rest else self.min_stiffness
        if floor is not None:
            delta = np.maximum(old + delta, np.minimum(old, floor)) - old
        if initial is None:
            return delta
        factors = self.rest_length_range if rest else self.stiffness_range
        return clip_to_range(old, delta, initial, factors)

    def _per_dof(self, local) -> NDArray:
        """``local(dof)`` for the rule's ``dof``; rows :data:`JOINT` stacked for "both"."""
        if self.dof == "both":
            return np.stack([local(d) for d in JOINT])
        return local(self.dof)

    def _free(
        self,
        net: SpringNetwork,
        task: AllosteryTask,
        tracker: Tracker,
        warm: Warm,
    ) -> Equilibrium:
        clamps = task.source_clamps(net, self.strain_reference)
        return tracker.solve(
            net, task.pinned, clamps, warm.free, key="free", guess=warm.free_guess()
        )

    def _fully_clamped(self, net, task, warm, tracker, read: Readout, rng):
        """The state with sources *and* targets clamped at the task's strains (GPC's
        clamped state, the trainer's imposed strain of directed aging): ``(state, target
        clamp lengths, measured spring lengths)``."""
        ref = self.strain_reference
        x0 = warm.clamped if warm.clamped is not None else warm.free
        if isinstance(task, NodeTask):  # outputs held at the desired values
            lengths = task.desired
            start = net.positions if x0 is None else x0
            clamped = task.hold(net, tracker, start, lengths, key="clamped")
            return clamped, lengths, net.lengths(clamped.positions)
        lengths = task.desired_lengths(net, ref)
        clamps = task.source_clamps(net, ref)
        clamps.update(zip(task.targets.tolist(), lengths.tolist()))
        clamped = tracker.solve(net, task.pinned, clamps, x0, key="clamped")
        return clamped, lengths, read.lengths(net, clamped, task.pinned, clamps, rng)

    def _clamped_only_step(self, net, task, warm, tracker, read: Readout, rng, local) -> Step:
        """A rule that reads the fully clamped state only (GPC, directed aging): ``local(dof,
        k, L, r_c)`` gives the per-spring update from the clamped spring lengths ``r_c``."""
        clamped, lengths, r_c = self._fully_clamped(net, task, warm, tracker, read, rng)
        k, L = net.stiffness, net.rest_length
        raw = self._per_dof(lambda dof: local(dof, k, L, r_c))
        return Step(
            delta=self._delta(net, task, raw),
            dof=self.dof,
            free=None,
            clamped=clamped,
            clamp_lengths=lengths,
            measured_clamped=r_c,
            raw=raw,
        )

    def update(
        self,
        net: SpringNetwork,
        task: AllosteryTask,
        *,
        warm: Warm | None = None,
        tracker: Tracker | None = None,
        noise: float = 0.0,
        temperature: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> Step:
        """One learning step on ``net`` for ``task``.

        Parameters
        ----------
        net : SpringNetwork
        task : AllosteryTask or TaskSet
            A task set (several examples) gives the sum of the per-example updates.
        warm : Warm, optional
            Warm starts (the previous step's ``step.warm``).
        tracker : Tracker, optional
            Equilibrium tracker carrying reusable factorisations (one per trial). A new one
            with this rule's ``solver`` is made when None.
        noise : float
            Relative read-out noise: every length the rule reads is ``r (1 + noise xi)``
            with ``xi ~ N(0, 1)`` drawn from ``rng``.
        rng : numpy.random.Generator, optional
            Required when ``noise > 0`` or ``temperature > 0``.
        temperature : float
            ``k_B T`` (energy units): every state the rule reads is one draw of its thermal
            fluctuations (exact harmonic Boltzmann distribution, :mod:`.thermal`) instead
            of the equilibrium; the rule's own states are still found as equilibria.

        Returns
        -------
        Step
        """
        if not isinstance(net, SpringNetwork):
            if temperature != 0.0:
                raise ValueError("temperature is implemented for spring networks only")
            return self._medium_update(net, task, tracker=tracker, noise=noise, warm=warm)
        if self.dof not in _NETWORK_DOFS:
            raise ValueError(
                f"a SpringNetwork learns 'rest_length' or 'stiffness', not {self.dof!r}"
            )
        task.check(net)
        noise = check.real("noise", noise, low=0)
        temperature = check.real("temperature", temperature, low=0)
        if (noise > 0 or temperature > 0) and not isinstance(rng, np.random.Generator):
            raise ValueError("noise > 0 or temperature > 0 needs rng, a numpy.random.Generator")
        node = isinstance(task, NodeTask) or (isinstance(task, TaskSet) and task.node_outputs)
        if node and (noise > 0 or temperature > 0):
            raise ValueError(
                "read-out noise and temperature are implemented for spring tasks: node tasks "
                "take noise 0 and temperature 0"
            )
        read = Readout(float(noise), float(temperature))
        tracker = tracker or Tracker(self.solver)
        warm = warm or Warm()
        if isinstance(task, TaskSet):
            step = self._update_examples(net, task, warm, tracker, read, rng)
        else:
            step = self._update(net, task, warm, tracker, read, rng)
        check_finite_update(step.raw, self.dof)
        delta, rate = self._rate_step(net, task, step.raw, warm)
        check_finite_update(delta, self.dof)
        return dataclasses.replace(step, delta=delta, previous=warm, rate=rate)

    def _update_examples(self, net, tasks, warm, tracker, read, rng) -> Step:
        """Several examples at once: the sum of the per-example updates (.examples)."""
        steps = []
        for e, task in enumerate(tasks.tasks):
            w = warm.example(e)
            step = self._update(net, task, w, tracker, read, rng)
            steps.append(dataclasses.replace(step, previous=w))
        raw = np.sum([s.raw for s in steps], axis=0)
        return Step(
            delta=raw, dof=self.dof, free=None, clamped=None, raw=raw, examples=tuple(steps)
        )

    def _update(
        self,
        net: SpringNetwork,
        task: AllosteryTask,
        warm: Warm,
        tracker: Tracker,
        read: Readout,
        rng: np.random.Generator | None,
    ) -> Step:  # pragma: no cover - abstract
        raise NotImplementedError

    # -- any other learning medium (.medium): the rule asks it for states and gradients --
    def _medium_update(self, medium, task, *, tracker, noise: float, warm=None) -> Step:
        """One step on a medium: its raw line, or under a scale-free rate (the modulus
        field only, scale the mean initial modulus, then ``min_stiffness`` and
        ``stiffness_range`` as for a network's stiffnesses)."""
        from .medium import check_rule_on_medium, is_medium

        if not is_medium(medium):
            raise ValueError(
                "net must be a SpringNetwork or a learning medium (LearnableBody), "
                f"got {type(medium).__name__}"
            )
        if noise != 0.0:
            raise ValueError("read-out noise is implemented for spring networks only")
        rate = self.adaptive
        if rate is not None and medium.learning_dof(self.dof) != "modulus":
            raise ValueError(
                "alpha: a continuum's eigenstrain learns at the raw rate for now (the "
                "scale-free rates serve its modulus field); give alpha > 0"
            )
        check_rule_on_medium(medium, task, self)
        step = self._medium_step(medium, task, tracker)
        if rate is None:
            return step
        values = medium.parameters("modulus")
        state = None if warm is None else warm.rate
        if state is None or np.shape(state.initial) != np.shape(values):
            state = RateState.start(values)
        delta, state = rate.delta(step.raw, float(np.mean(state.initial)), state)
        delta = medium.floor(self.dof, delta, self.min_stiffness)
        delta = clip_to_range(values, delta, state.initial, self.stiffness_range)
        check_finite_update(delta, self.dof)
        return dataclasses.replace(step, delta=delta, previous=warm or Warm(), rate=state)

    def _medium_step(self, medium, task, tracker) -> Step:  # pragma: no cover - abstract
        raise NotImplementedError

    def _medium_result(self, medium, task, raw, free, clamped, clamp_strain) -> Step:
        mask = self.learning_mask(medium, task)
        raw = np.where(mask if raw.ndim == 1 else mask[:, None], raw, 0.0)
        floor = self.min_stiffness
        lengths = None if clamp_strain is None else task.target_length * (1.0 + clamp_strain)
        return Step(
            delta=medium.floor(self.dof, raw, floor),
            dof=self.dof,
            free=free,
            clamped=clamped,
            clamp_lengths=lengths,
            raw=raw,
        )


def _strain_scale(task) -> float:
    """The largest strain a task asks for (sources and targets, every example): the scale of
    a rest-length step (a rate's ``step`` moves ``L`` by about that fraction of this strain
    times ``L``)."""
    tasks = task.tasks if isinstance(task, TaskSet) else (task,)
    values = [0.0]
    for t in tasks:
        values.append(float(np.max(np.abs(t.source_strain), initial=0.0)))
        values.append(float(np.max(np.abs(getattr(t, "target_strain", ())), initial=0.0)))
    largest = max(values)
    return largest if largest > 0 else 1.0
