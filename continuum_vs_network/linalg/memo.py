"""What a read-only array, or an immutable object, alone decides: kept while it lives.

Nothing here depends on what the array or object is. The network engine is the main user:
networks are immutable (their arrays are read-only) and ``with_*`` copies share the springs
array, so results that depend only on the topology (Hessian patterns, incidence matrices,
scatter indices, validation) or only on one network (its scale, pins, rigidity checks,
solver setup) are computed once. Two stores, each a dict per ``(object, name)``:

- :func:`per_array` keys a small array (up to :data:`CONTENT_MAX_BYTES`) on its content, so
  networks built anew with the same topology (a sweep over seeds of one patch) share the
  entry, at most :data:`CONTENT_KEPT` topologies per name, least recently used dropped
  first; a larger array on its identity, dropping the entry when the array is collected
  (an id is not reused before that);
- :func:`per_network` keys weakly on the object (a network).

Callers use a ``name`` of their own, so the stores of different modules never mix, and keep
only what the array's content and the rest of their key decide. The banded Cholesky
(:mod:`.spd`) keeps its band layout per matrix structure (``W.indptr``) this way.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from typing import Any

import numpy as np

__all__ = ["per_array", "per_network"]

CONTENT_MAX_BYTES = 4096  # 256 springs: a key of this size hashes in ~1 us
CONTENT_KEPT = 64  # topologies kept per name (least recently used dropped)

_ARRAYS: dict[tuple[int, str], dict] = {}
_CONTENT: dict[str, OrderedDict] = {}
_NETWORKS: dict[str, weakref.WeakKeyDictionary] = {}


def per_array(array: np.ndarray, name: str) -> dict:
    """The ``name`` store of ``array`` (read-only callers only): shared by arrays of equal
    content when small, else kept while this array lives."""
    if array.nbytes <= CONTENT_MAX_BYTES:
        kept = _CONTENT.setdefault(name, OrderedDict())
        content = (array.shape, array.dtype.str, array.tobytes())
        store = kept.get(content)
        if store is None:
            store = kept[content] = {}
            if len(kept) > CONTENT_KEPT:
                kept.popitem(last=False)
        else:
            try:
                kept.move_to_end(content)
            except KeyError:  # dropped meanwhile by another thread: the store still serves
                pass
        return store
    key = (id(array), name)
    store = _ARRAYS.get(key)
    if store is None:
        store = _ARRAYS[key] = {}
        weakref.finalize(array, _ARRAYS.pop, key, None)
    return store


def per_network(net: Any, name: str) -> dict:
    """The ``name`` store of the object ``net`` (a network; any object a weak reference
    can follow), kept while it lives."""
    stores = _NETWORKS.setdefault(name, weakref.WeakKeyDictionary())
    store = stores.get(net)
    if store is None:
        store = stores[net] = {}
    return store
