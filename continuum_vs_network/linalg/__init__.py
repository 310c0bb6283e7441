"""Linear algebra shared by the network and continuum engines: nothing here knows about
springs or finite elements.

- :mod:`.spd`: factorisations of a symmetric positive-definite matrix (dense, banded
  LAPACK Cholesky, SuperLU, PARDISO) and the back-end choice (``sparse_solver``);
- :mod:`.kkt`: symmetric saddle-point (KKT) systems on those factors, with their inertia;
- :mod:`.pardiso`: MKL PARDISO with the symbolic analysis kept per structure (optional);
- :mod:`.fpenv`: subnormal floats flushed to zero around float32 SuperLU (x86-64 Linux);
- :mod:`.memo`: caches kept per array (on its content or identity) or per object.

This subpackage imports nothing from the rest of the package.
"""
