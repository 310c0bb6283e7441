"""Newton and the package's FIRE against jax-md's jitted FIRE, on the same networks, one run.

Optional comparison: needs ``jax`` and ``jax-md`` (CPU); ``--jax-path DIR`` appends a
folder holding them to ``sys.path`` (e.g. one made with ``pip install --target DIR jax
jax-md``). Without them the script says so and times the package's methods only.

Problem (identical for every method): a triangular lattice of ~N nodes with 10 % position
noise, stress-free, ``k = 1``; the spring nearest the centre is strained to ``S`` by moving
its two nodes apart symmetrically and pinning them there, plus the default pins. All
methods run on one core (the process is pinned to one CPU where the OS allows) and stop at
the package's local rule, relative residual ``<= 1e-10`` (each net force against its node's
``sum k L``); jax-md's FIRE runs in jitted chunks of 50 steps in float64 on the free
coordinates (compile time excluded, standard jax-md parameters with
``dt_start = 0.1 dt_max`` and the same ``dt_max`` as the package's FIRE). Every method is
timed ``--repeat`` times, in rounds of one run per method (the machine is shared: load falls
alike on the methods compared); medians are printed, and ratios are medians of the rounds'
ratios. The package's FIRE is timed as the whole ``relax`` call (problem set-up and the
second-order check included) over its iterations; jax-md's FIRE over the iterations it ran
(whole chunks); its ``exact`` count is the first iteration at which it meets the rule
(found by single steps after the timed run).

The two FIRE variants share every parameter but not the iteration counts: jax-md mixes the
velocity with ``F / sqrt(|F|^2 + 1e-6)`` (``minimize.fire_descent``; "wrong if F_norm
~< 1e-8" in its source), so once the force is below ~1e-3 (force units ``k L``, here ~1)
the mixing only damps the velocity; it also steps with velocity Verlet where the package
uses semi-implicit Euler, and holds its parameters, ``dt`` and ``alpha`` in float16
(``util.static_cast`` takes ``numpy.min_scalar_type`` of each). The last table counts the
iterations of a numpy emulation of jax-md's step (float16 included) and of the same step
without the ``1e-6``.

    python benchmarks/bench_jaxmd.py --jax-path /work/side/jaxmd --sizes 256,1024,4096
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import time


def _parse() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--sizes", default="256,1024,4096")
    p.add_argument("--strains", default="0.05,1")
    p.add_argument("--jax-path", default="")
    p.add_argument("--max-seconds", type=float, default=120.0)
    p.add_argument(
        "--side", action="append", default=[], help="folder with optional packages (pypardiso)"
    )
    p.add_argument("--repeat", type=int, default=5, help="timings per method (median)")
    return p.parse_args()


def main() -> None:
    args = _parse()
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if cpus:  # one core for every method (jax starts thread pools of its own)
        os.sched_setaffinity(0, {cpus[0]})
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")
    os.environ.setdefault("JAX_PLATFORMS", "cpu")
    os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false")
    if args.jax_path:
        sys.path.append(args.jax_path)
    sys.path.extend(args.side)
    import numpy as np

    import continuum_vs_network as cvn
    from continuum_vs_network.network.constraints import Problem
    from continuum_vs_network.network.energy import hessian_norm_bound, spring_gradient

    try:
        import jax
        import jax.numpy as jnp
        from jax_md import minimize

        jax.config.update("jax_enable_x64", True)
        have_jax = True
    except ImportError:
        have_jax = False
        print("# jax / jax-md not importable: timing the package's methods only")

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(__file__)), "tests"))
    from pulled_lattices import pulled_apart

    def setup(n_nodes: int, strain: float):
        net, pins, x0 = pulled_apart(round(float(np.sqrt(n_nodes))), strain)
        return net, x0, pins

    def jax_fire(net, x0, pins, tol):
        free = np.flatnonzero(~pins.ravel())
        springs = jnp.asarray(net.springs)
        k = jnp.asarray(net.stiffness)
        L = jnp.asarray(net.rest_length)
        base = jnp.asarray(x0.ravel())
        free_j = jnp.asarray(free)

        def energy(y):
            x = base.at[free_j].set(y).reshape(-1, 2)
            d = x[springs[:, 1]] - x[springs[:, 0]]
            r = jnp.sqrt(jnp.sum(d * d, axis=1))
            return 0.5 * jnp.sum(k * (r - L) ** 2)

        dt_max = 1.4 / np.sqrt(hessian_norm_bound(x0, net.springs, net.stiffness, net.rest_length))
        init, apply = minimize.fire_descent(
            energy, lambda a, b: a + b, dt_start=0.1 * dt_max, dt_max=dt_max
        )
        grad = jax.jit(jax.grad(energy))

        @jax.jit
        def chunk(state):
            return jax.lax.fori_loop(0, 50, lambda i, s: apply(s), state)

        scale = Problem.build(net, pinned=pins).scale[free]

        def met(state) -> bool:
            return bool(np.max(np.abs(np.asarray(grad(state.position))) / scale) <= tol)

        def run(budget_s):
            state = init(jnp.asarray(x0.ravel()[free]))
            it, last = 0, None
            t0 = time.perf_counter()
            while True:
                if met(state):
                    return time.perf_counter() - t0, it, True, last
                if time.perf_counter() - t0 > budget_s:
                    return time.perf_counter() - t0, it, False, last
                last = state
                state = chunk(state)
                state.position.block_until_ready()
                it += 50

        def exact(it, last):
            """First iteration meeting the rule: single steps from the last chunk's start."""
            if last is None:
                return it
            state, it = last, it - 50
            while not met(state):
                state, it = step(state), it + 1
            return it

        init = jax.jit(init)
        step = jax.jit(apply)
        warm = chunk(init(jnp.asarray(x0.ravel()[free])))  # compile (both state signatures)
        chunk(warm).position.block_until_ready()
        step(warm).position.block_until_ready()
        grad(warm.position).block_until_ready()
        return run, exact

    from continuum_vs_network.linalg.kkt import sparse_backend

    print(
        f"# bench_jaxmd: {' '.join(sys.argv[1:])}; jax-md={have_jax}; one BLAS thread; "
        f"CPUs {sorted(os.sched_getaffinity(0)) if cpus else 'not pinned'}; "
        f"median of {args.repeat}; sparse solver {sparse_backend()}"
    )
    print(
        f"{'N':>6} {'S':>5} {'method':>8} {'seconds':>9} {'iters':>7} {'us/iter':>8} {'exact':>7}"
    )

    def emulated_jaxmd(net, x0, pins, tol, eps, max_iter=200_000):
        """Iterations of jax-md's ``fire_descent`` step re-written in numpy, stopped at the
        package's rule checked every iteration: unit masses, velocity Verlet with ``dt`` in
        float32, mixing with ``F / sqrt(|F|^2 + eps)``, and the parameters, ``dt`` and
        ``alpha`` in the dtype jax-md's ``util.static_cast`` gives them
        (``numpy.min_scalar_type``: float16)."""

        def cast(value):
            return np.asarray(value, dtype=np.min_scalar_type(value))[()]

        problem = Problem.build(net, pinned=pins)
        free = problem.free_flat
        scale = problem.scale[free]
        x = x0.copy()

        def force(y):
            x.ravel()[free] = y
            return -spring_gradient(x, net.springs, net.stiffness, net.rest_length).ravel()[free]

        bound = hessian_norm_bound(x0, net.springs, net.stiffness, net.rest_length)
        dt_max = 1.4 / np.sqrt(bound)
        dt_max, dt = cast(dt_max), cast(0.1 * dt_max)
        f_inc, f_dec, alpha_start, f_alpha = cast(1.1), cast(0.5), cast(0.1), cast(0.99)
        alpha, n_pos = alpha_start, 0
        y, p, f = x0.ravel()[free].copy(), np.zeros(free.size), force(x0.ravel()[free])
        for it in range(max_iter):
            if np.max(np.abs(f) / scale) <= tol:
                return it
            step = np.float32(dt)
            half = step / np.float32(2.0)
            p += half * f
            y += step * p
            f = force(y)
            p += half * f
            power = float(f @ p)
            p += alpha * (f * np.sqrt(p @ p) / np.sqrt(f @ f + eps) - p)
            n_pos = n_pos + 1 if power >= 0 else 0
            if power > 0 and n_pos > 5:
                dt, alpha = min(dt * f_inc, dt_max), alpha * f_alpha
            if power < 0:
                dt, alpha, p = dt * f_dec, alpha_start, np.zeros_like(p)
        return max_iter

    def package(net, x0, pins, method):
        kw = {} if method == "newton" else {"max_iter": 10**9}

        def run():
            t0 = time.perf_counter()
            try:
                eq = cvn.relax(
                    net, pinned=pins, x0=x0, method=method, max_seconds=args.max_seconds, **kw
                )
                ok, its = True, eq.iterations
            except cvn.EquilibriumError as err:
                ok, its = False, err.state.iterations
            return time.perf_counter() - t0, its, ok, its

        run()  # warm caches
        return run

    rows = []
    for n in [int(s) for s in args.sizes.split(",")]:
        for strain in [float(s) for s in args.strains.split(",")]:
            net, x0, pins = setup(n, strain)
            runs = {m: package(net, x0, pins, m) for m in ("newton", "fire")}
            if have_jax:
                jax_run, exact = jax_fire(net, x0, pins, 1e-10)
                runs["jax-md"] = functools.partial(jax_run, args.max_seconds)
            # rounds: every method once per round, so that the machine's load (shared)
            # falls alike on the methods compared; ratios are medians over the rounds
            samples = {m: [] for m in runs}
            for _ in range(args.repeat):
                for m, run in runs.items():
                    samples[m].append(run())
            if have_jax:
                dt, its, ok, last = samples["jax-md"][-1]
                first = exact(its, last) if ok else its
                samples["jax-md"] = [(t, i, o, first) for t, i, o, _ in samples["jax-md"]]
            times = {}
            for method, out in samples.items():
                dt = float(np.median([o[0] for o in out]))
                _, its, ok, first = out[-1]
                times[method] = (dt, its, ok, first)
                per = f"{dt / its * 1e6:8.0f}" if its and method != "newton" else f"{'':>8}"
                flag = "" if ok else "  NOT CONVERGED"
                print(
                    f"{net.n_nodes:>6} {strain:>5g} {method:>8} {dt:9.3f} {its:7d} {per} "
                    f"{first:7d}{flag}"
                )
            emulated = [emulated_jaxmd(net, x0, pins, 1e-10, eps) for eps in (1e-6, 0.0)]
            rows.append((net.n_nodes, strain, times, samples, emulated))
    print(
        "\n# ratios (same run, medians over rounds): jax-md FIRE / newton (time to 1e-10), "
        "package FIRE / jax-md FIRE (time per iteration; iterations to the rule)"
    )
    for n, strain, t, samples, _ in rows:
        if "jax-md" not in t:
            continue
        pairs = list(zip(samples["newton"], samples["fire"], samples["jax-md"], strict=True))
        speed = np.median([j[0] / nw[0] for nw, _, j in pairs])
        per = np.median([(f[0] / f[1]) / (j[0] / max(j[1], 1)) for _, f, j in pairs])
        print(
            f"{n:>6} {strain:>5g}  newton {speed:6.1f}x faster than jax-md FIRE; "
            f"package FIRE per iteration {per:5.2f}x jax-md's "
            f"(iterations {t['fire'][3]} against {t['jax-md'][3]})"
        )

    print(
        "\n# FIRE iterations to the rule: package | jax-md (exact) | numpy emulation of "
        "jax-md's step | the same without the 1e-6 in |F|"
    )
    for n, strain, t, _, emulated in rows:
        jax_its = t["jax-md"][3] if "jax-md" in t else "-"
        print(
            f"{n:>6} {strain:>5g}  {t['fire'][3]:>7} | {jax_its:>7} | {emulated[0]:>7} | "
            f"{emulated[1]:>7}"
        )


if __name__ == "__main__":
    main()
