"""Storage of a scene's units in ``<directory>/units/``: write, check, read back, merge.

Each unit is an ``.npz`` payload (its arrays, or a saved
:class:`~..learning.history.History`) and a
``.json`` record written last, holding a fingerprint of every setting the unit depends on;
both are written atomically. A unit is done when its record matches its fingerprint (and,
when asked, its payload reads back).

Records are strict JSON (:mod:`continuum_vs_network.io.strict_json`): a non-finite value
(NaN: not available, e.g. the error of an explicit step refused above its stability limit;
inf: an open end such as no instability below the largest value tried) is written as
``null`` and named in the record's ``"non_finite"`` map (JSON pointer -> ``"nan"``,
``"inf"`` or ``"-inf"``), and read back as it was; records written with bare ``NaN`` tokens
by earlier versions still load.

Not ``joblib.Memory``: it keys a result by a hash of the function's code and its pickled
arguments and drops a function's results when its code changes, while a unit here is keyed
by its name and the settings it depends on (:attr:`.Unit.fingerprint`) and kept across code
changes; and its pickles, stored under hashes, are not the ``.npz`` + JSON record by unit
key that the runner, the reports and other units read.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from ..io.atomic import atomic_path, write_text_atomic
from ..io.strict_json import dumps_record, loads_record
from .provenance import environment
from .results import is_result, to_stored
from .units import Unit, UnitResult

__all__: list[str] = []  # helpers of the runner (:mod:`.runner`) and :mod:`.compute`


def _units_dir(directory: Path) -> Path:
    return directory / "units"


def _record_path(directory: Path, key: str) -> Path:
    return _units_dir(directory) / (key.replace("/", "__") + ".json")


def _payload_path(directory: Path, key: str) -> Path:
    return _units_dir(directory) / (key.replace("/", "__") + ".npz")


def _is_done(directory: Path, unit: Unit, *, verify: bool = False) -> bool:
    """The unit's record matches its fingerprint (and, with ``verify``, its payload loads)."""
    rec = _record_path(directory, unit.key)
    if not (rec.exists() and _payload_path(directory, unit.key).exists()):
        return False
    try:
        record = json.loads(rec.read_text())
        if record["fingerprint"] != unit.fingerprint:
            return False
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return not verify or _payload_loads(directory, unit.key, bool(record.get("history")))


def _payload_loads(directory: Path, key: str, history: bool) -> bool:
    """True when the unit's payload reads back completely (every array, every CRC)."""
    path = _payload_path(directory, key)
    try:
        if history:
            from ..learning.history import History

            History.load(path)
        else:
            with np.load(path, allow_pickle=False) as z:
                for name in z.files:
                    z[name]
    except Exception:  # any failure to read back means: compute the unit again
        return False
    return True


def _save_unit(directory: Path, unit: Unit, output: Any, seconds: float) -> None:
    from ..learning.history import History

    payload = _payload_path(directory, unit.key)
    if isinstance(output, History):
        with atomic_path(payload) as tmp:
            output.save(tmp)
        record = {"history": True, "meta": {}}
    else:
        arrays, meta = to_stored(output) if is_result(output) else output
        with atomic_path(payload) as tmp, open(tmp, "wb") as fh:
            np.savez_compressed(fh, **{k: np.asarray(v) for k, v in arrays.items()})
        record = {"history": False, "meta": meta}
    # the code that computed it: a later run reuses the unit whatever the code is then
    record.update(
        key=unit.key,
        fingerprint=unit.fingerprint,
        seconds=float(seconds),
        commit=environment()["commit"],
    )
    write_text_atomic(
        _record_path(directory, unit.key),
        dumps_record(record, sort_keys=True, default=_json_default),
    )


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _read_record(directory: Path, key: str) -> dict:
    return loads_record(_record_path(directory, key).read_text())


def _read_unit(directory: Path, key: str) -> UnitResult:
    rec = _read_record(directory, key)
    if rec["history"]:
        return UnitResult(key, {}, {}, rec["seconds"])
    with np.load(_payload_path(directory, key), allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    return UnitResult(key, arrays, rec["meta"], rec["seconds"])


def _trial_keys(directory: Path, group: str) -> list[str]:
    prefix = "train/" + group + "/trial"
    keys = []
    for rec in _units_dir(directory).glob("train__*.json"):
        key = json.loads(rec.read_text())["key"]
        if key.startswith(prefix):
            keys.append(key)
    return sorted(keys, key=lambda k: int(k.rsplit("trial", 1)[1]))


def _merged_history(directory: Path, group: str, keys: Iterable[str] | None = None):
    """Concatenate the one-trial histories of a learning group along the trial axis."""
    from ..learning.history import History

    keys = list(keys) if keys is not None else _trial_keys(directory, group)
    if not keys:
        raise KeyError(f"no trials of {group!r} in {directory}")
    parts = [History.load(_payload_path(directory, k)) for k in keys]
    first = parts[0]
    return dataclasses.replace(
        first,
        seeds=np.concatenate([h.seeds for h in parts]),
        completed=np.concatenate([h.completed for h in parts]),
        stop_reason=tuple(r for h in parts for r in h.stop_reason),
        data={name: np.concatenate([h.data[name] for h in parts]) for name in first.data},
        initial=tuple(n for h in parts for n in h.initial),
        final=tuple(n for h in parts for n in h.final),
        tasks=tuple(t for h in parts for t in h.tasks),
    )


def _clean(directory: Path, units: list[Unit]) -> None:
    """Remove unit files and checkpoints that belong to no unit of the plan."""
    stems = {u.stem for u in units}
    for path in _units_dir(directory).iterdir():
        if path.name.startswith("."):
            continue
        stem = path.name.rsplit(".", 1)[0]
        if stem not in stems:
            path.unlink(missing_ok=True)
    ckpts = directory / "checkpoints"
    if ckpts.exists():
        for path in ckpts.iterdir():
            path.unlink(missing_ok=True)
        ckpts.rmdir()
