"""Test-wide settings.

Hypothesis draws the same examples on every run (``derandomize``) and keeps no example
database: the default run is reproducible on a fresh clone, a failure seen once is seen
again, and CI never fails on a draw a developer's machine did not make.
"""

from hypothesis import settings

settings.register_profile("reproducible", derandomize=True, database=None)
settings.load_profile("reproducible")
