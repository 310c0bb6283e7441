"""The report writer: ``reports/<scene>/report.md`` with its figures, and the index.

:func:`write_report` reads a :class:`~continuum_vs_network.scenes.runner.SceneResult` (it
runs nothing), hands a :class:`~.document.Document` to the section of the scene's kind
(its ``section`` in the kind registry, :data:`~continuum_vs_network.scenes.schema.KINDS`),
then adds the meshes, settings and provenance (:mod:`.provenance`). When the scene
asks for images and off-screen rendering works, sections draw pyvista renders. Every file is
written atomically; figures of an earlier report that the new one does not use are removed.
``report.json`` beside the report holds its metadata and findings;
:func:`write_index` writes ``reports/README.md``: a one-page summary and the findings of
every scene in three tables by whose claim they judge (:mod:`.index_summary`), then the list
of reports.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from pathlib import Path

from ..io.atomic import write_text_atomic
from ..io.strict_json import dumps_record, loads_record
from . import escape
from .document import Document
from .findings import Finding
from .provenance import provenance_table, settings, short_source

__all__ = ["write_index", "write_report", "write_sweep_report"]

_META = "report.json"


def write_report(
    result,
    folder: str | os.PathLike[str],
    *,
    meshes: Sequence[str | os.PathLike[str]] = (),
    render: bool | None = None,
) -> Path:
    """Write ``<folder>/report.md`` (and its figures) for a scene result; return its path.

    Parameters
    ----------
    result : SceneResult
        From :func:`~continuum_vs_network.scenes.run_scene` or ``load_result``.
    folder : path
        Destination, e.g. ``reports/<scene>``; created.
    meshes : sequence of paths
        Mesh files written for the scene (listed in the report).
    render : bool, optional
        Draw pyvista renders. Default: when the scene asks for images (``[report] images``)
        and :func:`~continuum_vs_network.io.render.rendering_available` says rendering
        works; otherwise the report says renders were skipped and why.
    """
    t0 = time.perf_counter()
    scene = result.scene
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    reason = "the scene does not ask for images ([report] images = false)"
    if render is None:
        render = scene.report.images
        if render:
            from ..io.render import rendering_available

            render, why = rendering_available()
            reason = f"no off-screen rendering backend ({why})"
    elif not render:
        reason = "rendering switched off for this run"
    doc = Document(folder, scene.report.dpi, render=render, render_reason=reason)
    from ..scenes.schema import KINDS, builtin_names

    builtin = scene.name in builtin_names() and Path(scene.source).parent.name == "builtin"
    target = scene.name if builtin else short_source(scene.source)
    doc.add(
        f"# {scene.name}",
        "",
        escape.text(scene.description),
        "",
        f"Kind: `{scene.kind}`. Regenerate with `cvn run {target}`"
        + (" (a built-in scene; `cvn scenes` lists them)." if builtin else "."),
    )
    KINDS[scene.kind].section(doc, result)
    unshown = doc.unshown()
    if unshown:
        doc.heading("Findings")
        doc.add("Every verdict of this report not tabulated above, with its rule:", "")
        doc.findings_table(unshown)
    if meshes:
        doc.heading("Meshes for ParaView")
        root = folder.resolve().parent.parent
        for m in meshes:
            p = Path(m).resolve()
            try:
                shown = p.relative_to(root)
            except ValueError:
                shown = p
            doc.add(f"- `{shown}`")
    settings(doc, scene)
    provenance_table(doc, result)
    report, figures = _write_markdown(doc, folder)
    meta = {
        "name": scene.name,
        "kind": scene.kind,
        "description": scene.description,
        "default": scene.report.default,
        "wall_seconds": result.provenance.wall_seconds,
        "compute_seconds": result.provenance.compute_seconds,
        "report_seconds": time.perf_counter() - t0,
        "started": result.provenance.started,
        "commit": result.provenance.commit,
        "figures": figures,
        "findings": [f.to_dict() for f in doc.findings],
        "summaries": doc.summaries,
    }
    # not sorted: a finding's measured values keep the order its section gave
    write_text_atomic(folder / _META, dumps_record(meta, indent=1))
    return report


def write_sweep_report(result, folder: str | os.PathLike[str], *, command: str = "") -> Path:
    """Write ``<folder>/report.md`` (and its figures) for a sweep; return its path.

    Parameters
    ----------
    result : SweepResult
        From :func:`~continuum_vs_network.scenes.sweep.run_sweep` or ``load_sweep``.
    folder : path
        Destination, e.g. ``reports/<scene>``; created.
    command : str
        The command that regenerates the sweep (shown in the report).
    """
    from .sections.sweep import section as sweep_section

    t0 = time.perf_counter()
    scene, info = result.scene, result.info
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    doc = Document(folder, scene.report.dpi)
    doc.add(
        f"# {scene.name}",
        "",
        scene.description,
        "",
        f"A sweep of a `{scene.kind}` scene."
        + (f" Regenerate with `{command}`." if command else ""),
    )
    sweep_section(doc, result)
    settings(doc, scene)
    report, figures = _write_markdown(doc, folder)
    meta = {
        "name": scene.name,
        "kind": f"{scene.kind} sweep",
        "description": scene.description,
        "default": scene.report.default,
        "wall_seconds": info["wall_seconds"],
        "compute_seconds": float(sum(r["wall_seconds"] for r in result.rows)),
        "report_seconds": time.perf_counter() - t0,
        "started": info["started"],
        "commit": info.get("commit", "unknown"),
        "figures": figures,
        "findings": [f.to_dict() for f in doc.findings],
    }
    write_text_atomic(folder / _META, dumps_record(meta, indent=1, sort_keys=True))
    return report


def _write_markdown(doc: Document, folder: Path) -> tuple[Path, list[str]]:
    """Write ``folder/report.md`` from ``doc`` and delete the PNGs in ``folder`` it no longer
    shows; return its path and the names of its figures, sorted."""
    report = write_text_atomic(folder / "report.md", "\n".join(doc.lines).rstrip() + "\n")
    keep = {p.name for p in doc.files}
    for old in folder.glob("*.png"):
        if old.name not in keep:
            old.unlink(missing_ok=True)
    return report, sorted(keep)


def write_index(root: str | os.PathLike[str], *, note: str | None = None) -> Path:
    """Write ``<root>/README.md`` listing every ``<root>/<scene>/report.md``; return its path.

    ``note`` (e.g. how long the last default run took) is kept in ``<root>/index.json`` and
    shown again by later calls without one.
    """
    root = Path(root)
    keep = root / "index.json"
    if note is not None:
        write_text_atomic(keep, json.dumps({"note": note}))
    elif keep.exists():
        note = json.loads(keep.read_text()).get("note", "")
    entries = []
    for meta_path in sorted(root.glob(f"*/{_META}")):
        if not (meta_path.parent / "report.md").exists():
            continue
        entries.append(loads_record(meta_path.read_text()))
    lines = [
        "# Reports",
        "",
        "Written by `cvn report` (the default set: `cvn report` with no argument) and "
        "`cvn run SCENE`; one folder per scene with `report.md` and its figures.",
        "",
    ]
    if note:
        lines += [note, ""]
    findings = [(e["name"], Finding.from_dict(f)) for e in entries for f in e.get("findings", ())]
    if findings:
        from .index_summary import findings_tables, summary_lines

        lines += summary_lines(entries, findings)
        lines += findings_tables(findings)
        lines += ["## Reports", ""]
    lines += [
        "| scene | kind | default | description | compute s | report s |",
        "|---|---|---|---|---|---|",
    ]
    for e in entries:
        lines.append(
            f"| [{e['name']}]({e['name']}/report.md) | {e['kind']} | "
            f"{'yes' if e['default'] else 'no'} | {escape.cell(e['description'])} | "
            f"{e['compute_seconds']:.1f} | {e['report_seconds']:.1f} |"
        )
    return write_text_atomic(root / "README.md", "\n".join(lines) + "\n")
