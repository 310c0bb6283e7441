"""Verdicts on the paper's learning claims, beside :mod:`..findings`.

* :mod:`.claims`: every claim of :func:`...scenes.replication.paper_experiments` split into
  statements and judged against the trained histories (:func:`~.claims.check_claims`);
* :mod:`.claim_statements`: the statements, each with the metric that tests it and the
  rule that judges it.
"""
