"""The report writer: every section, every figure on disk and referenced, renders or a reason."""

from __future__ import annotations

import re

import numpy as np
import pytest
from PIL import Image

from continuum_vs_network.io.render import rendering_available
from continuum_vs_network.report import write_index, write_report
from continuum_vs_network.report.sections.solvers import time_to as _time_to
from continuum_vs_network.scenes import load_scene, run_scene

PAPER = """
name = "paper_tiny"
description = "every paper run, tiny"
seed = 7
kind = "learning"
[network]
builder = "paper"
[task]
kind = "paper"
[learning]
rules = ["gcl_floor", "gpc", "gpc_frozen", "exact"]
trials = 2
steps = 5
noise = [0.0, 0.05]
sweeps = true
sweep_points = 3
compare_gradient = true
[export]
[report]
dpi = 45
"""

STABILITY = """
name = "stab"
description = "one stiff and one extreme case"
kind = "stability"
[network]
builder = "triangular"
size = 4
stiffness_ratios = [1e6]
[task]
kind = "source"
strains = [5.0]
[solver]
methods = ["newton", "fire"]
rod_stiffnesses = [1e10]
max_seconds = 2.0  # Newton needs ms; under heavy load small dense solves slow 25x
"""

SOLVERS = """
name = "solv"
description = "two sizes, two methods"
kind = "solvers"
[network]
builder = "triangular"
sizes = [4, 6]
[task]
kind = "source"
strain = 0.3
[solver]
methods = ["newton", "fire"]
max_seconds = 2.0
"""


def _result(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text)
    scene = load_scene(path)
    return run_scene(scene, tmp_path / "results", progress=False)


def _check_files(folder, text):
    """Every image the report links exists as a PNG, and every PNG there is linked."""
    linked = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert linked and len(linked) == len(set(linked))
    for name in linked:
        with Image.open(folder / name) as img:
            assert img.format == "PNG" and min(img.size) >= 100
            assert np.asarray(img.convert("L")).std() > 1  # not a blank image
    assert sorted(p.name for p in folder.glob("*.png")) == sorted(linked)
    assert not list(folder.glob(".*.tmp"))  # atomic writes left nothing behind
    return linked


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("paper")
    result = _result(tmp, PAPER)
    folder = tmp / "reports" / "paper_tiny"
    folder.mkdir(parents=True)
    (folder / "fig_stale.png").write_bytes(b"old")  # from an earlier report: removed
    path = write_report(result, folder, render=False)
    return result, folder, path.read_text()


def test_learning_report_has_every_section(paper):
    result, folder, text = paper
    for heading in (
        "## The paper's claims and what this package measures",
        "## Error against iterations and against wall-clock time",
        "## The paper's figures from this package's runs",
        "## Source sweeps (Fig. 5 and appendix B)",
        "## Comparison with the exact gradient",
        "## Robustness to read-out noise",
        "## Appendix: the unscaled error of every trial",
        "## Renders",
        "## Settings",
        "## Provenance",
    ):
        assert heading in text, heading
    linked = _check_files(folder, text)
    for fig in (
        "fig_error.png",
        "fig_gcl_floor_mean.png",
        "fig_gpc_mean.png",
        "fig_gpc_energy.png",
        "fig_gpc_lengths.png",
        "fig_gpc_frozen_mean.png",
        "fig_sweeps_gpc.png",
        "fig_noise.png",
        "fig_trials.png",
    ):
        assert fig in linked
    assert "Renders skipped: rendering switched off" in text
    # the paper's claims are judged in the paper's own setting only (scene paper): this
    # package-setting scene says where, and judges none
    assert "The paper's claims are judged in scene `paper`" in text
    assert not re.search(r"^\| gpc \| Fig\. 6-9", text, re.M)
    assert "seeds | 7, 8" in text and result.provenance.commit in text


def test_report_numbers_come_from_the_histories(paper):
    result, _, text = paper
    from continuum_vs_network.learning.metrics import summary

    h = result.histories["newton/exact/noise0"]
    s = summary(h.error_initial, h.completed)
    assert f"| exact | {s['median']:.3g} [{s['q25']:.3g}, {s['q75']:.3g}]" in text
    cos = result.units["gradient/gcl_floor"].arrays["cosine"]
    assert np.all(np.abs(cos[np.isfinite(cos)]) <= 1 + 1e-12)
    assert f"| gcl_floor | {np.median(cos[:, 0]):.3f}" in text


def test_index_lists_reports(paper, tmp_path):
    _, folder, _ = paper
    index = write_index(folder.parent, note="a note").read_text()
    assert "[paper_tiny](paper_tiny/report.md)" in index and "a note" in index
    assert "every paper run, tiny" in index


def test_stability_report_has_a_row_per_case_and_method(tmp_path):
    result = _result(tmp_path, STABILITY)
    text = write_report(result, tmp_path / "rep").read_text()
    _check_files(tmp_path / "rep", text)
    rows = [li for li in text.splitlines() if re.match(r"^\| (stiff|rod|strain)_", li)]
    assert len(rows) == 3 * 2
    # Newton solves every case here; its rows say so with a local imbalance below tol
    for li in rows:
        cells = [c.strip() for c in li.strip("|").split("|")]
        if cells[1] == "newton":
            assert cells[2] == "converged" and float(cells[3]) <= 1e-10
    assert "Renders" not in text  # nothing to render in a stability scene


def test_solver_report_draws_error_against_iterations_and_seconds(tmp_path):
    result = _result(tmp_path, SOLVERS)
    text = write_report(result, tmp_path / "rep").read_text()
    linked = _check_files(tmp_path / "rep", text)
    assert {
        "fig_solvers_iterations.png",
        "fig_solvers_seconds.png",
        "fig_work_precision.png",
    } <= set(linked)
    for n in (4, 6):
        u = result.units[f"solvers/n{n}/newton"]
        assert u.meta["converged"] and u.arrays["residual"][-1] <= 1e-10
        assert np.all(np.diff(u.arrays["seconds"]) >= 0)  # a clock


def test_time_to_reach_a_residual():
    residual = np.array([1.0, 0.1, 0.2, 0.01, 0.5])
    seconds = np.array([0.0, 1.0, 2.0, 3.0, 4.0])
    assert _time_to(residual, seconds, 0.15) == 1.0
    assert _time_to(residual, seconds, 0.05) == 3.0
    assert np.isnan(_time_to(residual, seconds, 1e-3))


@pytest.mark.render
def test_renders_when_a_backend_exists(tmp_path):
    ok, why = rendering_available()
    if not ok:
        pytest.skip(f"no off-screen rendering: {why}")
    text = """
name = "trans"
description = "transmission with a render"
kind = "transmission"
[network]
builder = "triangular"
sizes = [6]
[task]
kind = "source"
[continuum]
refine = 0
order = 1
[report]
images = true
"""
    result = _result(tmp_path, text)
    report = write_report(result, tmp_path / "rep").read_text()
    linked = _check_files(tmp_path / "rep", report)
    assert "render_transmission_n6.png" in linked
    with Image.open(tmp_path / "rep" / "render_transmission_n6.png") as img:
        assert img.size == (1100, 560)
