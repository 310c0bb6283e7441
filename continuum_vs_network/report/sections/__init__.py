"""One report section per scene kind, ``section(doc, result)`` in the module of its name.

A section is a function ``section(doc, result) -> None`` that appends to a
:class:`~continuum_vs_network.report.document.Document` (headings, tables, figures, renders
and :class:`~continuum_vs_network.report.findings.Finding` objects) from a
:class:`~continuum_vs_network.scenes.runner.SceneResult`. The kind registry
(:data:`continuum_vs_network.scenes.schema.KINDS`) names each kind's section; a new scene
kind adds a module here and names its ``section`` there.

A kind whose section is short is one module (``accuracy``, ``continuum_mechanism``,
``relaxation``, ``solvers``, ``stability``, ``transmission``); a longer one is a package
whose ``__init__`` holds ``section`` and whose modules are its parts (``allostery``,
``beyond_paper``, ``continuum_learning``, ``learning``, ``physical_time``). Beside them:
``sweep`` (the section of a sweep's report) and ``renders`` (the pyvista renders of networks
that the learning, transmission and relaxation sections share).
"""
