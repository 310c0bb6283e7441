"""The training loop: ``cvn.train(net, task, rule, steps, ...) -> History``.

Each trial builds its network and task (from callables of a seeded generator, or uses the
ones given), then repeats ``rule.update`` / ``step.apply`` with warm-started equilibria and
one :class:`~.states.Tracker` (reused factorisations) per trial, measuring after every
step (see :mod:`.record` and :mod:`.history` for what is recorded).

Randomness: trial ``i`` uses ``SeedSequence(seeds[i]).spawn(2)``: the first child builds
the network and the task, the second draws the read-out noise. The same seeds give the
same history, up to the wall-clock columns.

Checkpoints (:mod:`.checkpoint`): with ``checkpoint=path`` the state is written to ``path`` every
``checkpoint_every`` steps (and when a trial ends); calling ``train`` again with the same
arguments resumes from it and returns exactly the history an uninterrupted run returns
(wall-clock columns aside: they carry on from the saved totals). The cached factorisations
are dropped at every checkpoint in every run, so a resumed run takes the same iterates.
A finished run's checkpoint is kept and a repeated call just loads it.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..network.equilibrium import Equilibrium, EquilibriumError
from ..network.model import SpringNetwork
from .checkpoint import Checkpoint, check_checkpoint
from .examples import TaskSet
from .history import History
from .medium import is_medium
from .node_tasks import NodeTask
from .record import record_bytes, record_measure, record_time, record_update
from .rule_base import Rule
from .states import Tracker
from .step import LearningError, Step, Warm
from .tasks import AllosteryTask

__all__ = ["train"]

NetworkSpec = SpringNetwork | Callable[[np.random.Generator], SpringNetwork]
TaskSpec = AllosteryTask | Callable[[SpringNetwork, np.random.Generator], AllosteryTask]
Callback = Callable[[int, int, SpringNetwork], None]


def train(
    net: NetworkSpec,
    task: TaskSpec,
    rule: Rule,
    steps: int,
    *,
    seeds: Sequence[int] = (0,),
    noise: float = 0.0,
    temperature: float = 0.0,
    measure: bool = True,
    progress: bool = True,
    checkpoint: str | Path | None = None,
    checkpoint_every: int = 50,
    callback: Callback | None = None,
) -> History:
    """Train ``net`` on ``task`` with ``rule`` for ``steps`` steps, one trial per seed.

    Parameters
    ----------
    net : SpringNetwork or callable ``f(rng) -> SpringNetwork``
        A callable builds each trial's network from the trial's generator (e.g.
        ``paper_network``); a network is used as is in every trial.
    task : AllosteryTask, TaskSet or callable ``f(net, rng) -> task``
        Likewise (e.g. ``paper_task``).
    rule : Rule
        :class:`CoupledLearning`, :class:`ProspectiveConfiguration` or
        :class:`ExactGradient`.
    steps : int
        Learning steps per trial (>= 0).
    seeds : sequence of int
        One trial per seed.
    noise : float
        Relative read-out noise of the lengths the rule reads (see ``Rule.update``);
        measurements in the history are noise-free.
    temperature : float
        ``k_B T``: every state the rule reads is one thermal draw around its equilibrium
        (see ``Rule.update`` and :mod:`.thermal`); measurements are equilibria.
    measure : bool
        Solve the free state after every step to measure the error even when the rule
        does not need it (prospective configuration). With False those measurements are
        NaN and the run does only the rule's own work.
    progress : bool
        Show a progress bar (tqdm, imported only when True; none if it is missing).
    checkpoint : path, optional
        ``.npz`` file to write the state to and to resume from (see the module).
    checkpoint_every : int
        Steps between checkpoints.
    callback : callable ``f(trial, step, net)``, optional
        Called after every step with the trial index, the number of steps done and the
        new network.

    Returns
    -------
    History

    A trial whose equilibrium cannot be found or whose step cannot be applied (a rest
    length reaching 0 without a floor) stops there; its ``completed`` count and
    ``stop_reason`` say so and its remaining entries are NaN.
    """
    if not isinstance(rule, Rule):
        raise check.ArgumentError("rule", rule, "a learning Rule (CoupledLearning, ...)")
    steps = check.integer("steps", steps, low=0)
    seeds = _check_seeds(seeds)
    check.memory(
        "steps", steps, 2 * seeds.size * record_bytes(steps, 1), f"the history of {seeds.size} "
        f"trial(s) of {steps} steps"
    )  # fmt: skip
    noise = check.real("noise", noise, low=0)
    temperature = check.real("temperature", temperature, low=0)
    measure = check.boolean("measure", measure)
    checkpoint_every = check.integer("checkpoint_every", checkpoint_every, low=1)
    if callback is not None and not callable(callback):
        raise check.ArgumentError("callback", callback, "None or a callable f(trial, step, net)")
    if checkpoint is not None:
        checkpoint = check_checkpoint(checkpoint)

    settings = dict(rule.settings())
    settings.update(steps=steps, noise=float(noise), measure=bool(measure))
    if temperature > 0:  # (absent at T = 0: settings and checkpoints of plain runs unchanged)
        settings["temperature"] = float(temperature)
    fingerprint = json.dumps(
        {"settings": settings, "seeds": seeds.tolist(), "every": int(checkpoint_every)},
        sort_keys=True,
        default=str,
    )
    state = Checkpoint.open(checkpoint, fingerprint)
    if state.finished(len(seeds)):
        return state.history(settings, steps, seeds)

    bar = _progress_bar(progress, len(seeds) * steps, state.steps_done(steps))
    try:
        for i, seed in enumerate(seeds):
            if i < state.trial:
                continue
            _run_trial(
                i,
                int(seed),
                net,
                task,
                rule,
                steps,
                (float(noise), float(temperature)),
                measure,
                state,
                int(checkpoint_every),
                callback,
                bar,
            )
    finally:
        if bar is not None:
            bar.close()
    return state.history(settings, steps, seeds)


def _check_seeds(seeds: Sequence[int]) -> NDArray[np.int64]:
    if isinstance(seeds, str | bytes) or not isinstance(seeds, Sequence | np.ndarray):
        raise check.ArgumentError("seeds", seeds, "a sequence of integers in 0..2**63-1")
    out = np.array([check.seed(f"seeds[{i}]", s) for i, s in enumerate(seeds)], dtype=np.int64)
    if out.size == 0:
        raise check.ArgumentError("seeds", seeds, "a sequence naming at least one trial")
    return out


# -- one trial --------------------------------------------------------------------------
def _build(seed: int, net: NetworkSpec, task: TaskSpec):
    build_ss, noise_ss = np.random.SeedSequence(seed).spawn(2)
    build_rng = np.random.default_rng(build_ss)
    net0 = net(build_rng) if callable(net) else net
    task0 = task(net0, build_rng) if callable(task) else task
    if is_medium(net0):  # a continuum (or another medium): it checks its own task
        net0.check_task(task0)
        return net0, task0, np.random.default_rng(noise_ss)
    if not isinstance(net0, SpringNetwork):
        raise ValueError(
            "net must be a SpringNetwork or a learning medium (LearnableBody), or build one; "
            f"got {type(net0).__name__}"
        )
    if not isinstance(task0, AllosteryTask | TaskSet | NodeTask):
        raise ValueError(
            "task must be an AllosteryTask, a NodeTask or a TaskSet or build one, got "
            f"{type(task0).__name__}"
        )
    task0.check(net0)
    return net0, task0, np.random.default_rng(noise_ss)


def _run_trial(
    i: int,
    seed: int,
    net: NetworkSpec,
    task: TaskSpec,
    rule: Rule,
    steps: int,
    readout: tuple[float, float],
    measure: bool,
    state: Checkpoint,
    every: int,
    callback: Callback | None,
    bar,
) -> None:
    net0, task0, noise_rng = _build(seed, net, task)
    check.memory(
        "steps", steps, 2 * (i + 1) * record_bytes(steps, task0.n_targets),
        f"the history of {i + 1} trial(s) of {steps} steps and {task0.n_targets} targets",
    )  # fmt: skip
    rec = state.start_trial(i, net0, task0, noise_rng, steps)
    cur = state.current_network(net0)
    warm = state.warm
    tracker = Tracker(rule.solver)
    mask = rule.learning_mask(net0, task0)
    t_start = time.perf_counter() - state.seconds
    measure_seconds = state.measure_seconds
    base = dict(state.counters)

    def counters() -> dict[str, float]:
        s = tracker.stats
        return {
            "solves": base["solves"] + s.solves,
            "factorisations": base["factorisations"] + s.factorisations,
            "iterations": base["iterations"] + s.iterations,
        }

    def measure_free(cur: SpringNetwork, warm: Warm, task=task0) -> Equilibrium | None:
        nonlocal measure_seconds
        if not measure:
            return None
        t0 = time.perf_counter()
        if is_medium(cur):
            eq = cur.free_state(task, tracker=tracker)
            measure_seconds += time.perf_counter() - t0
            return eq
        clamps = task.source_clamps(cur, rule.strain_reference)
        eq = tracker.solve(cur, task.pinned, clamps, warm.free, key="free")
        measure_seconds += time.perf_counter() - t0
        return eq

    def measure_examples(cur, warm: Warm, step: Step | None) -> list | None:
        """Free states of every example of a task set (the rule's own, or measured)."""
        out = []
        for e, task in enumerate(task0.tasks):
            own = step.examples[e].free if step is not None else None
            out.append(own if own is not None else measure_free(cur, warm.example(e), task))
        return None if any(f is None for f in out) else out

    def next_warm(warm: Warm, step: Step, free) -> Warm:
        if step.examples is not None:
            return Warm(
                examples=tuple(
                    next_warm(warm.example(e), s, None if free is None else free[e])
                    for e, s in enumerate(step.examples)
                ),
                rate=step.rate,
            )
        return Warm(
            free=free.positions if free is not None else warm.free,
            clamped=step.warm.clamped,
            previous_free=warm.free if free is not None else warm.previous_free,
            rate=step.rate,
        )

    t = state.step
    reason = ""
    try:
        while t < steps:
            step = rule.update(
                cur, task0, warm=warm, tracker=tracker, noise=readout[0],
                temperature=readout[1], rng=noise_rng,
            )  # fmt: skip
            if step.examples is not None:
                free = measure_examples(cur, warm, step)
            else:
                free = step.free if step.free is not None else measure_free(cur, warm)
            record_update(rec, t, step, cur, rule, mask)
            record_measure(rec, t, cur, task0, rule, free, mask)
            record_time(rec, t, time.perf_counter() - t_start, measure_seconds, counters())
            nxt = step.apply(cur)
            warm = next_warm(warm, step, free)
            cur = nxt
            t += 1
            if bar is not None:
                bar.update(1)
            if callback is not None:
                callback(i, t, cur)
            if t % every == 0 and t < steps:
                tracker.forget()
                state.save_progress(
                    i,
                    t,
                    cur,
                    warm,
                    noise_rng,
                    rec,
                    time.perf_counter() - t_start,
                    measure_seconds,
                    counters(),
                )
        if isinstance(task0, TaskSet):
            free = measure_examples(cur, warm, None)
        else:
            free = measure_free(cur, warm)
        record_measure(rec, steps, cur, task0, rule, free, mask)
        record_time(rec, steps, time.perf_counter() - t_start, measure_seconds, counters())
    except (EquilibriumError, LearningError) as err:
        reason = f"step {t}: {type(err).__name__}: {err}"
    if bar is not None and t < steps:
        bar.update(steps - t)
    state.finish_trial(i, t, reason, cur, rec)


def _progress_bar(progress: bool, total: int, done: int):
    if not progress or total == 0:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:  # progress bars are optional
        return None
    return tqdm(total=total, initial=done, desc="train", unit="step")
