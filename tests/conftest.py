"""Test-wide settings.

Hypothesis draws the same examples on every run (``derandomize``) and keeps no example
database: the default run is reproducible on a fresh clone, a failure seen once is seen
again, and CI never fails on a draw a developer's machine did not make.
"""

import gc
import weakref
from types import SimpleNamespace

import pytest
from hypothesis import settings

settings.register_profile("reproducible", derandomize=True, database=None)
settings.load_profile("reproducible")


class _TrackedLU:
    """A SuperLU factorisation a weak reference can follow (SuperLU objects take none)."""

    def __init__(self, lu) -> None:
        self._lu, self.perm_r, self.perm_c = lu, lu.perm_r, lu.perm_c

    def solve(self, b):
        return self._lu.solve(b)

    def __getattr__(self, name):  # L, U
        return getattr(self._lu, name)


@pytest.fixture
def superlu_lifetimes(monkeypatch):
    """SuperLU everywhere (no banded Cholesky), its factorisations followed: ``made``, the
    number made, and ``most``, the most alive at once (reachable, counted as each is made)."""
    from continuum_vs_network.linalg import spd
    from continuum_vs_network.network import lagrangian

    monkeypatch.setattr(spd, "banded_pays", lambda n, width: False)
    monkeypatch.setattr(lagrangian, "banded_pays", lambda n, width: False)
    made: list[weakref.ref] = []
    record = SimpleNamespace(made=0, most=0)
    superlu = spd.sparse_lu

    def tracked(W, **kw):
        gc.collect()
        alive = sum(r() is not None for r in made)
        lu = _TrackedLU(superlu(W, **kw))
        made.append(weakref.ref(lu))
        record.made, record.most = len(made), max(record.most, alive + 1)
        return lu

    monkeypatch.setattr(spd, "sparse_lu", tracked)
    return record
