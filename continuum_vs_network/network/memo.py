"""What a network, or its read-only springs array, alone decides: kept while it lives.

Networks are immutable (their arrays are read-only) and ``with_*`` copies share the springs
array, so results that depend only on the topology (Hessian patterns, incidence matrices,
scatter indices, validation) or only on one network (its scale, pins, rigidity checks,
solver setup) are computed once. Two stores, each a dict per ``(object, name)``:

- :func:`per_array` keys on the array's identity and drops the entry when the array is
  collected (an id is not reused before that);
- :func:`per_network` keys weakly on the network object.

Callers use a ``name`` of their own, so the stores of different modules never mix.
"""

from __future__ import annotations

import weakref
from typing import Any

import numpy as np

__all__ = ["per_array", "per_network"]

_ARRAYS: dict[tuple[int, str], dict] = {}
_NETWORKS: dict[str, weakref.WeakKeyDictionary] = {}


def per_array(array: np.ndarray, name: str) -> dict:
    """The ``name`` store of ``array`` (read-only callers only), emptied when it goes."""
    key = (id(array), name)
    store = _ARRAYS.get(key)
    if store is None:
        store = _ARRAYS[key] = {}
        weakref.finalize(array, _ARRAYS.pop, key, None)
    return store


def per_network(net: Any, name: str) -> dict:
    """The ``name`` store of the network object ``net``, kept while it lives."""
    stores = _NETWORKS.setdefault(name, weakref.WeakKeyDictionary())
    store = stores.get(net)
    if store is None:
        store = stores[net] = {}
    return store
