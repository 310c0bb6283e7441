"""Training units of a learning scene: one trial per unit, and its trajectory frames.

``train/<solver>/<rule>/noise<i>/trial<k>``: one trial (seed ``scene.seed + k``) of one
rule with one equilibrium solver at one read-out noise level; a one-trial
:class:`~continuum_vs_network.learning.History`, checkpointed inside the trial. With
``[export] series`` the rest lengths and stiffnesses are kept every few steps
(:func:`frames_file`).
"""

from __future__ import annotations

import numpy as np

from ..io.atomic import atomic_path
from .schema import Scene
from .units import UnitContext
from .units_learning_build import build_rules, builders, rule_steps

__all__ = ["frames_file", "train_unit"]


def train_unit(scene: Scene, params: dict, ctx: UnitContext):
    """One training trial; returns its (one-trial) History."""
    from ..learning.train import train

    L = scene.learning
    rule = build_rules(scene, params["solver"])[params["rule"]]
    net, task = builders(scene)
    every = int(params["series_every"])
    steps = rule_steps(scene, params["rule"])
    frames_path = ctx.checkpoint.with_name(ctx.checkpoint.stem + ".frames.npz")
    frames = _load_frames(frames_path) if every else {}

    def callback(trial: int, step: int, cur) -> None:
        if every and (step % every == 0 or step == steps):
            frames[step] = (np.array(cur.rest_length), np.array(cur.stiffness))
            _save_frames(frames_path, frames)
        if ctx.on_step is not None:
            ctx.on_step()

    history = train(
        net,
        task,
        rule,
        steps,
        seeds=(int(params["seed"]),),
        noise=float(params["noise"]),
        measure=L.measure,
        progress=False,
        checkpoint=ctx.checkpoint,
        checkpoint_every=L.checkpoint_every,
        callback=callback,
    )
    if every:
        _save_frames(frames_file(ctx.directory, ctx.key), frames)
    frames_path.unlink(missing_ok=True)
    return history


def frames_file(directory, key: str):
    """Where the trajectory frames (rest lengths, stiffnesses) of a training unit are kept."""
    return directory / "frames" / (key.replace("/", "__") + ".npz")


def _load_frames(path) -> dict[int, tuple]:
    if not path.exists():
        return {}
    with np.load(path) as z:
        steps = z["steps"]
        return {int(s): (z["rest_length"][i], z["stiffness"][i]) for i, s in enumerate(steps)}


def _save_frames(path, frames: dict[int, tuple]) -> None:
    steps = sorted(frames)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(
            fh,
            steps=np.array(steps, dtype=np.int64),
            rest_length=np.array([frames[s][0] for s in steps]),
            stiffness=np.array([frames[s][1] for s in steps]),
        )
