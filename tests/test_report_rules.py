"""Report rules that keep trivial or unsettled results from counting as successes: decoupled
runs, floors that have not plateaued, states that are not equilibria. Synthetic inputs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from continuum_vs_network.learning.metrics import PLATEAU, bound, tail_change
from continuum_vs_network.report.document import Document
from continuum_vs_network.report.findings import NOT_COMPARABLE, NOT_REPRODUCED, REPRODUCED
from continuum_vs_network.report.sections.beyond_paper.thermal import rises
from continuum_vs_network.report.sections.continuum_learning.findings import (
    agreed_coupling,
    fields_agree_verdict,
)
from continuum_vs_network.report.sections.learning.checks import (
    EQUILIBRIUM_RESIDUAL,
    not_equilibria,
    residual_range,
)
from continuum_vs_network.report.sections.sweep import _eta_finding


# -- two rules' fields: not comparable when a run is decoupled ---------------------------------
def test_field_agreement_of_decoupled_runs_is_not_comparable():
    assert fields_agree_verdict(1e-13, [0.0, 0.8]) == NOT_COMPARABLE
    assert fields_agree_verdict(1e-13, [0.8, 0.9]) == REPRODUCED
    assert fields_agree_verdict(0.5, [0.8, 0.9]) == NOT_REPRODUCED


def test_coupling_agreement_says_what_was_agreed():
    def run(coupling: str) -> SimpleNamespace:
        return SimpleNamespace(coupling=coupling)

    both = agreed_coupling({"network": run("decoupled"), "c": run("decoupled")})
    assert both.startswith("here both decoupled") and "not that any learned it" in both
    coupled = agreed_coupling({"a": run("coupled"), "b": run("coupled")})
    assert coupled == "here both coupled"
    split = agreed_coupling({"a": run("coupled"), "b": run("decoupled")})
    assert split == "here a coupled, b decoupled"


# -- plateau test of a floor ---------------------------------------------------------------------
def test_tail_change_of_a_geometric_decay_is_its_rate_over_the_window():
    steps = np.arange(61)
    e = 0.04 * 0.93**steps  # the last quarter: 15 entries, 14 steps
    assert tail_change(e) == pytest.approx(0.93**14 - 1, rel=1e-9)
    assert bound(tail_change(e)) == "upper bound"
    assert bound(tail_change(np.exp(0.05 * steps))) == "lower bound"
    flat = 0.02 * (1 + 0.01 * np.sin(steps))  # noise around a level
    assert abs(tail_change(flat)) <= PLATEAU and bound(tail_change(flat)) == "plateau"
    assert bound(tail_change(np.r_[1.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])) == "unknown"


def test_floor_rise_is_decided_only_when_transients_cannot_reverse_it():
    # settled runs: a rise and a missing rise
    assert rises([0.02, 0.05], ["plateau", "plateau"]) == REPRODUCED
    assert rises([0.02, 0.0201], ["plateau", "plateau"]) == NOT_REPRODUCED
    # the baseline still falling: a rise above it stands, equality does not decide
    assert rises([0.02, 0.05], ["upper bound", "plateau"]) == REPRODUCED
    assert rises([0.0196, 0.0196], ["upper bound", "upper bound"]) == NOT_COMPARABLE
    # the higher floor still falling: its rise may vanish
    assert rises([0.02, 0.05], ["plateau", "upper bound"]) == NOT_COMPARABLE
    # a missing rise is shown when the lower floor cannot fall and the higher cannot rise
    assert rises([0.02, 0.019], ["lower bound", "upper bound"]) == NOT_REPRODUCED
    assert rises([0.02, float("nan")], ["plateau", "unknown"]) == NOT_COMPARABLE


# -- equilibria by the stored residual -----------------------------------------------------------
def _hist(residual, completed, tension, dof="rest_length"):
    res = np.asarray(residual, dtype=float)
    return SimpleNamespace(
        data={"residual": res, "energy_gradient_free": np.asarray(tension, dtype=float)},
        completed=np.asarray(completed),
        steps=res.shape[1] - 1,
        settings={"dof": dof},
    )


def test_residual_range_covers_completed_steps_only():
    # trial 1 stopped at step 0: its later entries are not read
    h = _hist([[1e-9, 2e-8, 3e-9], [5e-9, 1e3, 7e2]], [2, 0], [[1.0, 2.0, 2.0], [1.0] * 3])
    assert residual_range(h) == (1e-9, 2e-8)
    assert residual_range(h, relative=True) == pytest.approx((5e-10, 1e-8))
    assert not not_equilibria(h)


def test_equilibrium_is_judged_against_the_force_scale():
    # a large absolute residual in a very stiff (highly tensed) state is still an equilibrium
    stiff = _hist([[7.8, 1.0]], [1], [[1e10, 1e10]])
    assert residual_range(stiff)[1] == 7.8 and not not_equilibria(stiff)
    # Adagrad-like states: residuals of order the tensions themselves
    loose = _hist([[172.0, 1.25e4]], [1], [[1e3, 3.5e4]])
    assert residual_range(loose, relative=True)[1] == pytest.approx(1.25e4 / 3.5e4)
    assert not_equilibria(loose) and 1.25e4 / 3.5e4 > EQUILIBRIUM_RESIDUAL
    # no force scale defined (stiffness learning): not judged
    assert not not_equilibria(_hist([[172.0, 1.25e4]], [1], [[1.0, 1.0]], dof="stiffness"))


# -- eta sweep: judged on trials not decoupled ---------------------------------------------------
def _rows(errors_by_eta, coupling):
    rows = []
    for eta, errors in errors_by_eta.items():
        for e in errors:
            rows.append(
                {
                    "solver": "newton",
                    "rule": "gcl",
                    "noise": 0.0,
                    "learning.eta": eta,
                    "learning.alpha_gcl": 0.1,
                    "relative_error": e,
                    "coupling": coupling,
                }
            )
    return rows


def _eta_verdict(tmp_path, rows):
    doc = Document(tmp_path, 50)
    _eta_finding(doc, SimpleNamespace(rows=rows), ["learning.eta", "learning.alpha_gcl"])
    (f,) = doc.findings
    return f


def test_eta_finding_is_not_comparable_when_every_trial_is_decoupled(tmp_path):
    f = _eta_verdict(tmp_path, _rows({0.01: [1e-5, 2e-5], 1.0: [1e-5, 2e-5]}, "decoupled"))
    assert f.verdict == NOT_COMPARABLE
    assert dict(f.measured)["decoupled trials"] == 4


def test_eta_finding_ignores_decoupled_trials(tmp_path):
    coupled = _rows({0.01: [1e-3, 1e-3], 1.0: [1e-3, 1e-3]}, "coupled")
    decoupled = _rows({0.01: [1e-8, 1e-8], 1.0: [1e-2, 1e-2]}, "decoupled")  # would differ
    f = _eta_verdict(tmp_path, coupled + decoupled)
    assert f.verdict == REPRODUCED and dict(f.measured)["ratio"] == pytest.approx(1.0)
    coupled_differ = _rows({0.01: [1e-2, 1e-2], 1.0: [1e-3, 1e-3]}, "partially coupled")
    f = _eta_verdict(tmp_path, coupled_differ + decoupled)
    assert f.verdict == NOT_REPRODUCED and dict(f.measured)["ratio"] == pytest.approx(10.0)
