"""First-order equilibrium methods: FIRE, L-BFGS and the seed paper's Adagrad.

Each method has the signature of :data:`~.equilibrium.METHODS`:
``f(problem, x, stop, trace) -> Outcome`` and is judged by the same local stop rule as
Newton (:mod:`.stopping`). FIRE (:mod:`.fire`) and L-BFGS (:mod:`.lbfgs`) minimise the
objective of :mod:`.objective` (exact clamps by an augmented Lagrangian there);
``paper_adagrad`` (:mod:`.adagrad`) is the seed paper's untuned baseline with rod clamps.
"""

from .adagrad import paper_adagrad
from .fire import fire
from .lbfgs import lbfgs

__all__ = ["fire", "lbfgs", "paper_adagrad"]
