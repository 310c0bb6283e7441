"""Rules of the report's findings on learning that need a coupling measurement: the
physical_time learning-speed claims, the beyond_paper thermal floors, the continuum_learning
refinement; each judged from minimal stored-unit stand-ins or results (no computation)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from continuum_vs_network.report.document import Document
from continuum_vs_network.report.findings import (
    CONTRADICTED,
    NOT_COMPARABLE,
    REPRODUCED,
)
from continuum_vs_network.report.sections.beyond_paper.thermal import _thermal
from continuum_vs_network.report.sections.continuum_learning.findings import _verdicts
from continuum_vs_network.report.sections.physical_time.findings import _findings
from continuum_vs_network.scenes.results.beyond_paper import ThermalResult
from continuum_vs_network.scenes.results.physical_time import TimeRunResult


# -- physical_time: learning speed needs coupling; the quasi-static limit does not ----------
def _time_unit(n, coupling=None):
    """A unit whose learning time falls 100-fold from ratio 0.01 to 1 and is past at 10
    (oscillation), closed bracket (1, 10] (rho* of order one), error at ratio 0.01 equal to
    the quasi-static."""
    runs = [
        {"ratio": r, "T": T, "diverged": False, "error_at_qs_end": 0.01, "error_qs_end": 0.01}
        for r, T in ((0.01, 100.0), (0.1, 10.0), (1.0, 1.0), (10.0, 50.0))
    ]
    return TimeRunResult(
        runs=runs,
        n=n,
        n_nodes=n,
        rule="gcl",
        critical_low=1.0,
        critical_high=10.0,
        critical_ratio=3.16,
        critical_by="oscillation",
        tau=1.0,
        tau_force=0.1,
        coupling=coupling,
    )


def _time_verdicts(tmp_path, couplings):
    doc = Document(tmp_path, 50)
    units = [_time_unit(n, c) for n, c in zip((64, 256), couplings, strict=True)]
    _findings(doc, {"gcl": units}, np.array([1.0, 10.0, 100.0, 1000.0]))
    return {f.claim.split(":")[0]: f for f in doc.findings}


def test_learning_speed_claims_need_a_coupling_measurement(tmp_path):
    # speed-up 100 at every size (contradicts "cannot be addressed"), a closed bracket met by
    # oscillation (Stern reproduced) -- the verdicts the old rule gave without any coupling
    coupled = _time_verdicts(tmp_path, ["coupled", "coupled"])
    assert coupled["paper, discussion"].verdict == CONTRADICTED
    assert coupled["Stern et al. 2022"].verdict == REPRODUCED
    for couplings, why in (
        ([None, None], "coupling not measured"),
        (["coupled", None], "coupling not measured"),
        (["coupled", "decoupled"], "1 of 2 sizes x draws decoupled"),
    ):
        f = _time_verdicts(tmp_path, couplings)
        for claim in ("paper, discussion", "Stern et al. 2022"):
            assert f[claim].verdict == NOT_COMPARABLE
            assert why in f[claim].rule and "not decoupled" in f[claim].rule
        # the measured numbers are still reported
        assert f["paper, discussion"].measured["smallest speed-up N=64"] == 100.0
        # two computations of one dynamics: judged without coupling
        assert f["package"].verdict == REPRODUCED


# -- beyond_paper thermal: decoupled runs disclosed, unsettled floors called bounds --------
def test_decoupled_caveat_counts_and_words():
    from continuum_vs_network.report.sections.learning.noise import decoupled_caveat

    verdicts = ["decoupled", "coupled", "decoupled", "decoupled", "decoupled"]
    # final C/C0: met (<= 0.01), coupled, not met twice, not known
    ratios = [1e-3, 1e-4, 0.02, 0.5, np.nan]
    text, counts = decoupled_caveat(verdicts, ratios=ratios, runs="runs", what="X", noun="trials")
    assert counts == {"trials": 5, "decoupled trials": 4, "trials met trivially (decoupled)": 1}
    assert text.startswith("The 5 runs: 4 decoupled")
    assert "1 met the task (final C/C0 <= 0.01) trivially" in text
    assert (
        "2 did not meet the task (final C/C0 0.02 to 0.5, above 0.01): what they learned is "
        in text
    )
    assert "1 have no final C/C0" in text
    # decoupled runs that did not meet the task are not said to have met it
    text, counts = decoupled_caveat(
        ["decoupled"] * 2, ratios=[0.02, 0.03], runs="runs", what="X", noun="trials"
    )
    assert "met the task" not in text and "trivially" not in text
    assert "not carried by the sources" in text and counts["trials met trivially (decoupled)"] == 0
    text, counts = decoupled_caveat(
        ["coupled"], ratios=[1e-3], runs="runs", what="X", noun="trials"
    )
    assert counts["decoupled trials"] == 0 and text.endswith("none here is decoupled.")
    assert decoupled_caveat([], ratios=[], runs="runs", what="X", noun="trials") == ("", {})
    with pytest.raises(ValueError, match="ratios needs one final C/C0 per verdict"):
        decoupled_caveat(["coupled"], ratios=[], runs="runs", what="X", noun="trials")


def _thermal_doc(tmp_path, coupling, ratio=None):
    """``ratio``: every run's final C/C0 (None: that of its error curve); ``coupling``:
    every run's coupling verdict, its source share 0."""
    temps, etas = (0.0, 1e-6), (0.01, 1.0)
    steps = np.arange(61)
    falling = 0.04 * 0.93**steps  # -64 % over the last quarter: an upper bound
    level = np.full(61, 0.8)  # a plateau
    units = {}
    for i in range(len(temps)):
        for run in [f"gcl_eta{eta:g}" for eta in etas] + ["exact"]:
            err = level if (i, run) == (1, "gcl_eta0.01") else falling
            units[f"beyond/thermal/T{i}/{run}"] = ThermalResult(
                error=err,
                seconds_trace=np.zeros(err.size),
                completed=60,
                steps=60,
                stop_reason="",
                ratio=float(err[-1] / err[0]) if ratio is None else ratio,
                source_share=0.0,
                coupling=coupling,
                outcome="not met",
                seconds=0.0,
                rule={},
                shares=[0.0],
                floor=float(np.median(err[-15:])),
                temperature=temps[i],
                eta=None if run == "exact" else float(run.removeprefix("gcl_eta")),
            )
    scene = SimpleNamespace(
        learning=SimpleNamespace(temperatures=temps, etas=etas, eta=0.1, steps=60),
        network=SimpleNamespace(sizes=(5,)),
    )
    doc = Document(tmp_path, 50)
    _thermal(doc, scene, units)
    return doc


def test_thermal_floors_disclose_decoupled_runs_and_unsettled_points(tmp_path):
    doc = _thermal_doc(tmp_path, "decoupled")
    (nudge,) = [f for f in doc.findings if "larger nudge" in f.claim]
    assert nudge.verdict == REPRODUCED  # judged on every run, as the noise floor is
    assert nudge.measured["decoupled GCL runs"] == 2 and nudge.measured["GCL runs"] == 2
    # final C/C0 0.0129 (0.93^60) and 1: the task is not met, so not "met trivially"
    assert (
        "trivially" not in nudge.rule and nudge.measured["GCL runs met trivially (decoupled)"] == 0
    )
    assert "2 did not meet the task (final C/C0 0.0129 to 1, above 0.01)" in nudge.rule
    assert "what they learned is not carried by the sources" in nudge.rule
    (grows,) = [f for f in doc.findings if "grows with the temperature" in f.claim]
    assert grows.measured["decoupled GCL runs"] == 4
    body = "\n".join(doc.lines)
    assert "plateaued by the plateau test" in body
    assert "GCL eta=0.01 at T = 1e-06" in body
    assert "upper bounds (C still falling: the run settles lower): every other point" in body
    assert "all decoupled (source share 0)" in body
    met = _thermal_doc(tmp_path, "decoupled", ratio=1e-3)
    (nudge,) = [f for f in met.findings if "larger nudge" in f.claim]
    assert "2 met the task (final C/C0 <= 0.01) trivially" in nudge.rule
    assert nudge.measured["GCL runs met trivially (decoupled)"] == 2
    coupled = _thermal_doc(tmp_path, "coupled")
    (nudge,) = [f for f in coupled.findings if "larger nudge" in f.claim]
    assert nudge.measured["decoupled GCL runs"] == 0 and "met trivially" not in nudge.rule


# -- continuum_learning: the refinement of a prestress field is not comparable -------------
def _refinement(share):
    units = {}
    for key in ("network", "refine0"):
        units[f"continuum_learning/{key}/gcl"] = SimpleNamespace(
            source_share=share,
            coupling="decoupled" if share < 0.1 else "coupled",
            outcome="met",
            error=np.array([1.0, 1e-3]),
        )
    summary = {
        "correlation": [0.95],
        "change": [np.nan, 0.2, 0.05],  # shrinks 4-fold, last <= 0.1: converges
        "localised": [np.nan],
    }
    doc = SimpleNamespace(findings=[])
    doc.finding = doc.findings.append
    _verdicts(doc, "gcl", units, summary, [np.nan], 2)
    (f,) = [f for f in doc.findings if "converges under refinement" in f.claim]
    return f


def test_refinement_of_a_decoupled_field_is_not_comparable():
    assert _refinement(0.8).verdict == REPRODUCED
    f = _refinement(0.0)
    assert f.verdict == NOT_COMPARABLE
    assert f.rule.endswith(
        "not comparable when either medium is decoupled (its field is prestress)"
    )
    # the old rule judged the prestress field's refinement: changes 0.2 -> 0.05 converge
    assert f.measured == {"change h/2": 0.2, "change h/4": 0.05}
