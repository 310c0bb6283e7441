"""The paper's learning claims as statements: what each measures on a run's histories
and the rule that judges it (:func:`statements`); :mod:`.claims` applies them."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...learning.history import History
from ...learning.metrics import final_values, length_error, normalised, rest_length_error

__all__ = ["Statement", "statements"]

_C_METRIC = "C/C0 with strains against the learning L (Eq. 26 as printed; error_current)"


def _ratio_final(values: NDArray, h: History, *, updates: bool = False) -> NDArray:
    completed = np.minimum(h.completed, h.steps - 1) if updates else h.completed
    return final_values(normalised(values), completed)


def _median(x: NDArray) -> float:
    ok = x[np.isfinite(x)]
    return float(np.median(ok)) if ok.size else float("nan")


def _mean(x: NDArray) -> float:
    ok = x[np.isfinite(x)]
    return float(np.mean(ok)) if ok.size else float("nan")


def _majority_of(n: int) -> int:
    return n // 2 + 1


@dataclass(frozen=True)
class Statement:
    claim: str
    metric: str
    measure: Callable[[History], float]
    rule: str
    judge: Callable[[float, int], str]  # (measured, trials judged) -> verdict
    size: bool = True  # a size reached (False: a direction)
    # a claim that the task is learned (or C lowered): each trial's own success (trials,)
    # and how many trials must succeed while not decoupled; None: no coupling needed
    per_trial: Callable[[History], NDArray] | None = None
    needed: Callable[[int], int] = _majority_of
    # a rise that must be specific to the claimed rule: reproduced only when the measured
    # value exceeds that of the reference rule (:data:`REFERENCE_RULE`) in the same run
    specific: bool = False
    # a claim of convergence to 0: the quantity's normalised curves (trials, steps + 1);
    # a verdict other than reproduced stands only once their median has stopped falling
    # (:func:`.claims._settled`)
    curve: Callable[[History], NDArray] | None = None


def _c_ratio(h: History) -> NDArray:
    return _ratio_final(h.error_current, h)


def _c_curves(h: History) -> NDArray:
    return normalised(h.error_current)


def _converged(h: History) -> NDArray:
    return _c_ratio(h) <= 1e-6


def _converged_count(h: History) -> float:
    r = _c_ratio(h)
    return float(np.sum(r <= 1e-6)) if np.isfinite(r).any() else float("nan")


def _moved(h: History) -> NDArray:
    d = np.stack(
        [np.abs(h.target_strain[i, :, 0] - h.tasks[i].target_strain[0]) for i in range(h.trials)]
    )
    return 1.0 - _ratio_final(d, h)


def _gcl_statements() -> list[Statement]:
    return [
        Statement(
            "GCL lowers C by orders of magnitude",
            f"median over trials of the final {_C_METRIC}",
            lambda h: _median(_c_ratio(h)),
            "reproduced if <= 1e-2 and a majority of the trials judged each reach "
            "C/C0 <= 1e-2 and are not decoupled; contradicted if >= 1",
            lambda m, n: (
                "reproduced" if m <= 1e-2 else "contradicted" if m >= 1 else "not reproduced"
            ),
            per_trial=lambda h: _c_ratio(h) <= 1e-2,
            curve=_c_curves,
        ),
        Statement(
            "all trials but one converge to C = 0",
            "trials whose final C/C0 (learning L) is <= 1e-6",
            _converged_count,
            "reproduced if all trials judged but at most one reach C/C0 <= 1e-6 and are not "
            "decoupled; contradicted if none does",
            lambda m, n: (
                "reproduced" if m >= n - 1 else "contradicted" if m == 0 else "not reproduced"
            ),
            per_trial=_converged,
            needed=lambda n: n - 1,
            curve=_c_curves,
        ),
    ]


def _fall(claim: str, metric: str, measure) -> Statement:
    return Statement(
        claim,
        metric,
        measure,
        "reproduced if < 1 (it fell); contradicted if > 1",
        lambda m, n: "reproduced" if m < 1 else "contradicted" if m > 1 else "not reproduced",
        size=False,
    )


def _gpc_statements() -> list[Statement]:
    return [
        Statement(
            "C rises on average (large spread)",
            f"mean over trials of the final {_C_METRIC}",
            lambda h: _mean(_c_ratio(h)),
            "reproduced if > 1; contradicted if < 1",
            lambda m, n: "reproduced" if m > 1 else "contradicted" if m < 1 else "not reproduced",
            size=False,
            specific=True,
        ),
        _fall(
            "the clamped energy E^C descends",
            "median over trials of the final E^C / E^C_0",
            lambda h: _median(_ratio_final(h.energy_clamped, h, updates=True)),
        ),
        _fall(
            "|dE^C/dL| descends",
            "median over trials of the final |dE^C/dL| / |dE^C/dL|_0",
            lambda h: _median(_ratio_final(h.energy_gradient_clamped, h, updates=True)),
        ),
        Statement(
            "the target length error falls by ~50 %",
            "median over trials of the final sum |r_T - l_T| / initial (Fig. 8)",
            lambda h: _median(_ratio_final(length_error(h), h)),
            "reproduced if <= 0.75 (it fell by about half or more); not reproduced if in "
            "(0.75, 1); contradicted if >= 1",
            lambda m, n: (
                "reproduced" if m <= 0.75 else "contradicted" if m >= 1 else "not reproduced"
            ),
        ),
        Statement(
            "the target rest-length error converges to 0",
            "median over trials of the final sum |L_T - l_T| / initial (Fig. 9)",
            lambda h: _median(_ratio_final(rest_length_error(h), h)),
            "reproduced if <= 1e-2; contradicted if >= 1",
            lambda m, n: (
                "reproduced" if m <= 1e-2 else "contradicted" if m >= 1 else "not reproduced"
            ),
            curve=lambda h: normalised(rest_length_error(h)),
        ),
    ]


def _gpc_frozen_statements() -> list[Statement]:
    return [
        Statement(
            "GPC with the target frozen lowers C",
            f"median over trials of the final {_C_METRIC}",
            lambda h: _median(_c_ratio(h)),
            "reproduced if < 1 (it fell) and in a majority of the trials C fell while the "
            "network is not decoupled (a decoupled trial lowered it trivially); "
            "contradicted if > 1",
            lambda m, n: "reproduced" if m < 1 else "contradicted" if m > 1 else "not reproduced",
            size=False,
            per_trial=lambda h: _c_ratio(h) < 1,
        ),
        Statement(
            "the target strain moves 33 % of the way to the desired strain",
            "median over trials of 1 - |S - S_T| / |S_0 - S_T| (target strain in the run's "
            "convention)",
            lambda h: _median(_moved(h)),
            "reproduced if in [0.2, 0.5] (33 % within a factor 1.5); contradicted if <= 0",
            lambda m, n: (
                "reproduced" if 0.2 <= m <= 0.5 else "contradicted" if m <= 0 else "not reproduced"
            ),
        ),
    ]


def statements(name: str) -> list[Statement]:
    if name in ("gcl", "gcl_floor", "gcl_notebook"):
        return _gcl_statements()
    if name == "gpc":
        return _gpc_statements()
    if name == "gpc_frozen":
        return _gpc_frozen_statements()
    return []
