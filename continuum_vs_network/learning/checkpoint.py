"""The state of a training run and its checkpoint file (resume after a kill).

:class:`Checkpoint` holds the completed trials and the progress of the current one (step,
learning arrays, warm starts, read-out generator state, wall-clock and solver totals) and,
with a path, writes them atomically to one ``.npz`` file; :meth:`Checkpoint.open` reads it
back. A run's ``fingerprint`` (its settings, seeds and checkpoint interval) must match the
file's, and each resumed trial's network must have the saved digest.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .. import _validate as check
from ..network.model import SpringNetwork
from .history import LEGACY, History
from .medium import is_medium, learning_arrays, with_learning_arrays
from .rates import RateState
from .record import COUNTERS, new_record
from .step import Warm
from .tasks import AllosteryTask

__all__ = ["Checkpoint", "check_checkpoint"]

_LEARNING = ("rest_length", "stiffness", "eigenstrain", "modulus")
_CURRENT_STATE = frozenset({*_LEARNING, "warm_free", "warm_clamped", "warm_previous_free"})
_RATE = "cur/rate_"  # the learning rate's state (.rates.RateState)


def check_checkpoint(checkpoint: str | Path) -> Path:
    """The checkpoint file: its folder must exist and take a new file, now (not at step 50)."""
    if not isinstance(checkpoint, str | os.PathLike):
        raise check.ArgumentError("checkpoint", checkpoint, "None or a path")
    path = Path(checkpoint)
    allowed = "None or a file path in an existing, writable folder"
    if path.is_dir():
        raise check.ArgumentError("checkpoint", str(checkpoint), allowed, detail="it is a folder")
    if not path.parent.is_dir():
        raise check.ArgumentError(
            "checkpoint", str(checkpoint), allowed, detail=f"no folder {str(path.parent)!r}"
        )
    try:
        fd, probe = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as err:
        raise check.ArgumentError(
            "checkpoint", str(checkpoint), allowed, detail=f"cannot write there: {err.strerror}"
        ) from None
    os.close(fd)
    os.unlink(probe)
    return path


def _digest(net: SpringNetwork) -> str:
    h = hashlib.sha1()
    arrays = net.to_arrays().values() if is_medium(net) else ()
    for a in arrays or (net.positions, net.springs, net.stiffness, net.rest_length):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _saved_warm(files: dict, examples: int | None) -> Warm:
    rate = RateState.from_arrays(files, _RATE)
    if examples is not None:
        ones = tuple(_saved_warm_one(files, f"example{e}_") for e in range(examples))
        return Warm(examples=ones, rate=rate)
    return dataclasses.replace(_saved_warm_one(files, ""), rate=rate)


def _saved_warm_one(files: dict, infix: str) -> Warm:
    return Warm(
        free=files.get(f"cur/warm_{infix}free"),
        clamped=files.get(f"cur/warm_{infix}clamped"),
        previous_free=files.get(f"cur/warm_{infix}previous_free"),
    )


# -- state of a run (and its checkpoint file) -----------------------------------------------
class Checkpoint:
    """Completed trials plus the progress of the current one; optionally on disk."""

    def __init__(self, path: Path | None, fingerprint: str) -> None:
        self.path = path
        self.fingerprint = fingerprint
        self.trial = 0  # index of the trial in progress
        self.step = 0
        self.records: list[dict[str, NDArray]] = []
        self.completed: list[int] = []
        self.reasons: list[str] = []
        self.initial: list[SpringNetwork] = []
        self.final: list[SpringNetwork] = []
        self.tasks: list[AllosteryTask] = []
        self.digests: list[str] = []
        self._resume: dict | None = None  # saved state of the trial in progress
        self.warm = Warm()
        self.seconds = 0.0
        self.measure_seconds = 0.0
        self.counters = dict.fromkeys(COUNTERS, 0)

    # -- opening ----------------------------------------------------------------------
    @classmethod
    def open(cls, path: str | Path | None, fingerprint: str) -> Checkpoint:
        state = cls(None if path is None else Path(path), fingerprint)
        if state.path is not None and state.path.exists():
            state._load()
        return state

    def finished(self, n_trials: int) -> bool:
        return len(self.completed) == n_trials

    def steps_done(self, steps: int) -> int:
        return len(self.completed) * steps + (self._resume or {}).get("step", 0)

    # -- trials -----------------------------------------------------------------------
    def start_trial(self, i, net0, task0, noise_rng, steps) -> dict[str, NDArray]:
        digest = _digest(net0)
        if self._resume is not None:
            if self._resume["digest"] != digest:
                raise ValueError(
                    f"checkpoint {self.path} was written for a different network in trial {i}"
                )
            noise_rng.bit_generator.state = self._resume["rng"]
            rec = self._resume["record"]
            self.step = self._resume["step"]
            self.warm = self._resume["warm"]
            self.seconds = self._resume["seconds"]
            self.measure_seconds = self._resume["measure_seconds"]
            self.counters = self._resume["counters"]
        else:
            rec = new_record(steps, task0.n_targets)
            self.step = 0
            self.warm = Warm()
            self.seconds = self.measure_seconds = 0.0
            self.counters = dict.fromkeys(COUNTERS, 0)
        self._current = (net0, task0, digest)
        return rec

    def current_network(self, net0: SpringNetwork) -> SpringNetwork:
        if self._resume is None:
            return net0
        cur = with_learning_arrays(net0, self._resume["learning"])
        self._resume = None
        return cur

    def save_progress(self, i, t, cur, warm, rng, rec, seconds, measure_seconds, counters):
        if self.path is None:
            return
        arrays = {f"cur/{k}": v for k, v in rec.items()}
        for name, value in learning_arrays(cur).items():
            arrays[f"cur/{name}"] = value
        if warm.free is not None:
            arrays["cur/warm_free"] = np.asarray(warm.free)
        if warm.clamped is not None:
            arrays["cur/warm_clamped"] = np.asarray(warm.clamped)
        if warm.previous_free is not None:
            arrays["cur/warm_previous_free"] = np.asarray(warm.previous_free)
        if warm.rate is not None:
            arrays.update(warm.rate.to_arrays(_RATE))
        for e, w in enumerate(warm.examples or ()):
            for name in ("free", "clamped", "previous_free"):
                if getattr(w, name) is not None:
                    arrays[f"cur/warm_example{e}_{name}"] = np.asarray(getattr(w, name))
        progress = {
            "examples": None if warm.examples is None else len(warm.examples),
            "trial": i,
            "step": t,
            "digest": self._current[2],
            "rng": rng.bit_generator.state,
            "seconds": seconds,
            "measure_seconds": measure_seconds,
            "counters": {k: int(v) for k, v in counters.items()},
        }
        self._write(arrays, progress)

    def finish_trial(self, i, t, reason, cur, rec) -> None:
        net0, task0, digest = self._current
        self.records.append(rec)
        self.completed.append(t)
        self.reasons.append(reason)
        self.initial.append(net0)
        self.final.append(cur)
        self.tasks.append(task0)
        self.digests.append(digest)
        self.trial = i + 1
        self._write({}, None)

    def history(self, settings, steps, seeds) -> History:
        data = {name: np.stack([r[name] for r in self.records]) for name in self.records[0]}
        return History(
            steps=steps,
            seeds=seeds.copy(),
            completed=np.array(self.completed, dtype=np.int64),
            stop_reason=tuple(self.reasons),
            settings=settings,
            data=data,
            initial=tuple(self.initial),
            final=tuple(self.final),
            tasks=tuple(self.tasks),
        )

    # -- disk -------------------------------------------------------------------------
    def _write(self, current: dict[str, NDArray], progress: dict | None) -> None:
        if self.path is None:
            return
        from .history import _net_arrays, _task_arrays

        arrays = dict(current)
        for j, rec in enumerate(self.records):
            arrays.update({f"rec/{j}/{k}": v for k, v in rec.items()})
            arrays.update(_net_arrays(f"initial/{j}", self.initial[j]))
            arrays.update(_net_arrays(f"final/{j}", self.final[j]))
            arrays.update(_task_arrays(f"task/{j}", self.tasks[j]))
        meta = {
            "fingerprint": self.fingerprint,
            "completed": self.completed,
            "reasons": self.reasons,
            "digests": self.digests,
            "progress": progress,
        }
        arrays["meta"] = np.array(json.dumps(meta))
        from ..io.atomic import atomic_path

        with atomic_path(self.path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    def _load(self) -> None:
        from .history import _net_from, _task_from

        with np.load(self.path, allow_pickle=False) as z:
            files = {k: z[k] for k in z.files}
        meta = json.loads(str(files["meta"]))
        if meta["fingerprint"] != self.fingerprint:
            raise ValueError(
                f"checkpoint {self.path} belongs to a different run (rule, steps, seeds, noise "
                f"or checkpoint_every differ); remove it or pass another path"
            )
        n = len(meta["completed"])
        self.completed = list(meta["completed"])
        self.reasons = list(meta["reasons"])
        self.digests = list(meta["digests"])
        for j in range(n):
            prefix = f"rec/{j}/"
            self.records.append(
                {
                    k[len(prefix) :]: v.copy()
                    for k, v in files.items()
                    if k.startswith(prefix) and k[len(prefix) :] not in LEGACY
                }
            )
            self.initial.append(_net_from(files, f"initial/{j}"))
            self.final.append(_net_from(files, f"final/{j}"))
            self.tasks.append(_task_from(files, f"task/{j}"))
        self.trial = n
        progress = meta["progress"]
        if progress is not None:
            self._resume = {
                "step": int(progress["step"]),
                "digest": progress["digest"],
                "rng": progress["rng"],
                "seconds": float(progress["seconds"]),
                "measure_seconds": float(progress["measure_seconds"]),
                "counters": progress["counters"],
                "record": {
                    k[4:]: v.copy()
                    for k, v in files.items()
                    if k.startswith("cur/")
                    and k[4:] not in _CURRENT_STATE | LEGACY
                    and not k.startswith("cur/warm_example")
                    and not k.startswith(_RATE)
                },
                "learning": {k: files[f"cur/{k}"] for k in _LEARNING if f"cur/{k}" in files},
                "warm": _saved_warm(files, progress.get("examples")),
            }
