"""Rocks-style allostery on jammed networks: how fast each rule learns, against the optimum.

Run::

    python benchmarks/bench_allostery.py                        # N ~ 512, 4 draws, all rules
    python benchmarks/bench_allostery.py --n 10000 --draws 1 --rules gcl --steps 600
    python benchmarks/bench_allostery.py --profile              # + cProfile of train's steps

Each draw ``d`` builds ``jammed_network(n, default_rng(d), phi)`` (stiffness ``k = 1/L``; the
network keeps about 90 % of the ``n`` discs) and, from the same generator, Rocks et al.'s
one-source, one-target task (``allostery_task``: source strain 0.05, target about 0.25 box
sizes away, response ratio ``S_T / S_S = +0.3`` on even draws and ``-0.3`` on odd ones),
trained together with its rest example (``anchored``). Every rule learns the stiffnesses
(``dof="stiffness"``) of the springs that are neither source nor target, with its default
objects (the scale-free adaptive rate; nothing tuned): ``gcl`` (coupled learning),
``exact`` (exact gradient), ``gpc`` (prospective configuration), ``aging`` (directed
aging). One ``train`` call per rule and draw, ``--steps`` steps. Printed:

1. the draws: nodes, springs, builder seconds, the ratio asked for, ``C0``;
2. per rule and draw, and the median over draws per rule: the first step index ``t`` with
   ``C/C0 <= 1e-2`` and ``<= 1e-3`` (``C`` = the history's ``error_initial``, summed over
   both examples; "-" when never reached within ``--steps``) and the wall-clock seconds to
   it, read off the history's ``seconds[t]`` (cumulative wall clock of the trial until the
   network after ``t`` steps was measured, so it includes ``train``'s own measuring and
   recording); ``C/C0`` after the last step; the stiffness contrast ``max(k/k0) /
   min(k/k0)`` over the non-source/target springs; the mean seconds per step; a trial that
   stopped early is marked ``*`` and its reason printed below. Medians count a level never
   reached as infinitely late (so the median is "-" when half the draws or more miss it);
3. per draw, the optimum (``exact_optimum(net, tasks, dof="stiffness")``: L-BFGS-B on the
   exact gradient within the stiffness range): ``C/C0``, gradient evaluations, seconds
   (timed around the call), the contrast it needs, and whether it is feasible
   (``C_e/C_e0 <= 1e-3`` for every example); ``--no-optimum`` skips it;
4. the per-step cost of ``train`` (which records the free state of every step, measuring it
   where the rule does not solve it itself) against a bare loop ``step = rule.update(cur,
   tasks, warm=warm, tracker=tracker); cur = step.apply(cur); warm = step.warm`` for
   ``--overhead-steps`` steps on draw 0 at ``--overhead-n`` nodes, and ``train(...,
   measure=False)``; the columns are measured side by side in one run (bare, train,
   train without measuring, in turn, ``--repeat`` times, best kept) and the ratios are
   what to compare; ``--no-overhead`` skips it;
5. with ``--profile``: the top cProfile entries (by own time) of ``train`` and of the bare
   loop for every rule of table 4, to see where any difference goes.

Timings depend on the machine and its load (other processes on a shared machine slow every
column); compare the ratios within one run.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

import numpy as np

import continuum_vs_network as cvn
from continuum_vs_network.learning import (
    CoupledLearning,
    DirectedAging,
    ExactGradient,
    ProspectiveConfiguration,
    Tracker,
    anchored,
    train,
)
from continuum_vs_network.learning.allostery import allostery_task
from continuum_vs_network.learning.optimum import exact_optimum

RULES = {
    "gcl": CoupledLearning,
    "exact": ExactGradient,
    "gpc": ProspectiveConfiguration,
    "aging": DirectedAging,
}
LEVELS = (1e-2, 1e-3)


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=512, help="discs of the packing (default 512)")
    p.add_argument("--draws", type=int, default=4, help="networks and tasks (default 4)")
    p.add_argument("--steps", type=int, default=1000, help="learning steps (default 1000)")
    p.add_argument(
        "--rules", default=",".join(RULES), help=f"comma-separated, of {', '.join(RULES)}"
    )
    p.add_argument("--phi", type=float, default=0.86, help="packing fraction (default 0.86)")
    p.add_argument("--no-optimum", action="store_true", help="skip the optimum (table 3)")
    p.add_argument("--no-overhead", action="store_true", help="skip train vs bare (table 4)")
    p.add_argument("--overhead-n", type=int, default=512, help="discs for table 4 (512)")
    p.add_argument("--overhead-steps", type=int, default=200, help="steps for table 4 (200)")
    p.add_argument("--repeat", type=int, default=2, help="repeats of table 4, best kept (2)")
    p.add_argument("--profile", action="store_true", help="cProfile train and the bare loop")
    p.add_argument("--top", type=int, default=15, help="profile entries printed (15)")
    args = p.parse_args()
    args.rules = [r.strip() for r in args.rules.split(",") if r.strip()]
    unknown = [r for r in args.rules if r not in RULES]
    if unknown:
        p.error(f"unknown rules {unknown}; choose among {list(RULES)}")
    return args


def _rule(name: str):
    return RULES[name](dof="stiffness")


def _draw(n: int, phi: float, d: int):
    """Draw ``d``: network (timed), task, the task with its rest example, ratio asked."""
    rng = np.random.default_rng(d)
    t0 = time.perf_counter()
    net = cvn.jammed_network(n, rng, phi=phi)
    build = time.perf_counter() - t0
    ratio = 0.3 if d % 2 == 0 else -0.3
    task = allostery_task(net, rng, ratio=ratio, source_strain=0.05, distance=0.25)
    return net, anchored(task, net), build, ratio


def _contrast(k: np.ndarray, k0: np.ndarray, mask: np.ndarray) -> float:
    q = k[mask] / k0[mask]
    return float(q.max() / q.min()) if q.size else 1.0


def _run(net, tasks, name: str, steps: int) -> dict:
    rule = _rule(name)
    h = train(net, tasks, rule, steps, seeds=(0,), progress=False)
    c = h.data["error_initial"][0]
    sec = h.data["seconds"][0]
    done = int(h.completed[0])
    r = c / c[0]
    out = {"final": float(r[done]), "done": done, "reason": h.stop_reason[0]}
    for level in LEVELS:
        hit = np.flatnonzero(r <= level)
        out[level] = (int(hit[0]), float(sec[hit[0]])) if hit.size else (np.inf, np.inf)
    out["contrast"] = _contrast(h.final[0].stiffness, net.stiffness, rule.learning_mask(net, tasks))
    out["per_step"] = float(sec[done]) / max(done, 1)
    out["c0"] = float(c[0])
    return out


def _fmt_steps(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{int(x)}"


def _fmt_sec(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{x:.2f}"


def _row(label: str, draw: str, r: dict) -> str:
    cells = []
    for level in LEVELS:
        cells += [_fmt_steps(r[level][0]), _fmt_sec(r[level][1])]
    mark = "*" if r.get("stopped") else " "
    return (
        f"{label:6s} {draw:>6s}  {cells[0]:>8s} {cells[1]:>8s}  {cells[2]:>8s} {cells[3]:>8s}  "
        f"{r['final']:10.2e}{mark} {r['contrast']:10.3g}  {r['per_step']:8.4f}"
    )


def _median(rows: list[dict]) -> dict:
    out = {}
    for level in LEVELS:
        out[level] = tuple(float(np.median([r[level][i] for r in rows])) for i in (0, 1))
    for key in ("final", "contrast", "per_step"):
        out[key] = float(np.median([r[key] for r in rows]))
    return out


def _bare(net, tasks, rule, steps: int) -> float:
    tracker = Tracker(rule.solver)
    cur, warm = net, None
    t0 = time.perf_counter()
    for _ in range(steps):
        step = rule.update(cur, tasks, warm=warm, tracker=tracker)
        cur = step.apply(cur)
        warm = step.warm
    return time.perf_counter() - t0


def _trained(net, tasks, rule, steps: int, measure: bool = True) -> float:
    t0 = time.perf_counter()
    h = train(net, tasks, rule, steps, seeds=(0,), progress=False, measure=measure)
    elapsed = time.perf_counter() - t0
    if h.completed[0] < steps:
        print(f"    (train stopped: {h.stop_reason[0]})")
    return elapsed


def _overhead(args) -> None:
    net, tasks, _, _ = _draw(args.overhead_n, args.phi, 0)
    steps = args.overhead_steps
    print(
        f"4. per-step seconds of train against the bare update/apply loop, {steps} steps, "
        f"draw 0, {net.n_nodes} nodes (best of {args.repeat})"
    )
    print("rule       bare s/step  train s/step  no-measure s/step  train/bare  no-measure/bare")
    for name in args.rules:
        rule = _rule(name)
        best = {"bare": np.inf, "train": np.inf, "nomeasure": np.inf}
        for _ in range(args.repeat):
            best["bare"] = min(best["bare"], _bare(net, tasks, rule, steps))
            best["train"] = min(best["train"], _trained(net, tasks, rule, steps))
            best["nomeasure"] = min(best["nomeasure"], _trained(net, tasks, rule, steps, False))
        b, t, m = (best[k] / steps for k in ("bare", "train", "nomeasure"))
        print(f"{name:8s} {b:13.5f} {t:13.5f} {m:18.5f} {t / b:11.2f} {m / b:16.2f}")
    if args.profile:
        for name in args.rules:
            _profile(net, tasks, name, steps, args.top)


def _where(key: tuple) -> str:
    """``file:line(function)`` of a pstats key, the path cut to the package or site dir."""
    path, line, func = key
    for cut in ("continuum_vs_network/", "site-packages/"):
        if cut in path:
            path = path[path.index(cut) + len(cut) :]
            break
    return f"{path}:{line}({func})"[:72]


def _profile(net, tasks, name: str, steps: int, top: int) -> None:
    """cProfile ``train`` and the bare loop; top own times of train, then the largest
    differences in cumulative time (train - bare), per function."""
    stats = {}
    for label, fn in (("train", _trained), ("bare", _bare)):
        prof = cProfile.Profile()
        prof.enable()
        fn(net, tasks, _rule(name), steps)
        prof.disable()
        stats[label] = pstats.Stats(prof).stats  # key -> (cc, nc, tottime, cumtime, callers)
    total = {k: sum(v[2] for v in s.values()) for k, s in stats.items()}
    print(
        f"\n5. cProfile, {name}, {steps} steps: train {total['train']:.2f} s, "
        f"bare loop {total['bare']:.2f} s (profiled)"
    )
    print(f"   top {top} own times in train\n      calls   own s   cum s  function")
    rows = sorted(stats["train"].items(), key=lambda kv: -kv[1][2])[:top]
    for key, (_, nc, tt, ct, _) in rows:
        print(f"   {nc:8d} {tt:7.3f} {ct:7.3f}  {_where(key)}")
    print(f"   top {top} cumulative seconds train - bare\n      calls  (bare)  extra s  function")
    extra = []
    for key, v in stats["train"].items():
        if key[0].endswith("bench_allostery.py") or key[2] in ("train", "_run_trial"):
            continue  # the wrappers (all of train's time)
        b = stats["bare"].get(key, (0, 0, 0.0, 0.0, None))
        extra.append((v[3] - b[3], v[1], b[1], key))
    for dt, nc, nb, key in sorted(extra, key=lambda e: -e[0])[:top]:
        print(f"   {nc:8d} {nb:7d} {dt:8.3f}  {_where(key)}")


def main() -> None:
    args = _parse()
    draws = [_draw(args.n, args.phi, d) for d in range(args.draws)]
    print(f"1. draws: jammed_network({args.n}, phi={args.phi}), Rocks task + rest example")
    print("draw  nodes  springs  build s  ratio         C0")
    results: dict[str, list[dict]] = {name: [] for name in args.rules}
    for d, (net, tasks, build, ratio) in enumerate(draws):
        c0 = None
        print(
            f"{d:4d}  {net.n_nodes:5d}  {net.n_springs:7d}  {build:7.2f}  {ratio:+5.1f}  ",
            end="",
            flush=True,
        )
        for name in args.rules:
            r = _run(net, tasks, name, args.steps)
            r["stopped"] = r["done"] < args.steps
            results[name].append(r)
            c0 = r["c0"]
        print(f"{c0:.3e}" if c0 is not None else "")
    print()
    print(f"2. stiffness learning, {args.steps} steps (steps / seconds from train's history)")
    print("rule     draw  steps1e-2    s1e-2  steps1e-3    s1e-3  final C/C0   contrast    s/step")
    for name in args.rules:
        for d, r in enumerate(results[name]):
            print(_row(name, str(d), r))
        print(_row(name, "median", _median(results[name])))
    for name in args.rules:
        for d, r in enumerate(results[name]):
            if r["stopped"]:
                print(f"* {name} draw {d}: stopped after {r['done']} steps: {r['reason']}")
    if not args.no_optimum:
        print()
        print("3. optimum: exact_optimum(net, tasks, dof='stiffness') (seconds timed around it)")
        print("draw        C/C0  evaluations  seconds   contrast  feasible(1e-3)  message")
        for d, (net, tasks, _, _) in enumerate(draws):
            t0 = time.perf_counter()
            opt = exact_optimum(net, tasks, dof="stiffness")
            sec = time.perf_counter() - t0
            mask = _rule("exact").learning_mask(net, tasks)
            contrast = _contrast(opt.net.stiffness, net.stiffness, mask)
            print(
                f"{d:4d}  {opt.ratio:10.2e}  {opt.evaluations:11d}  {sec:7.2f}  {contrast:9.3g}"
                f"  {opt.feasible(1e-3)!s:>14s}  {opt.message}"
            )
    if not args.no_overhead:
        print()
        _overhead(args)


if __name__ == "__main__":
    main()
