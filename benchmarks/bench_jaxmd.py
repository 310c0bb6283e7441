"""Newton and the package's FIRE against jax-md's jitted FIRE, on the same networks, one run.

Optional comparison: needs ``jax`` and ``jax-md`` (CPU); ``--jax-path DIR`` appends a
folder holding them to ``sys.path`` (e.g. one made with ``pip install --target DIR jax
jax-md``). Without them the script says so and times the package's methods only.

Problem (identical for every method): a triangular lattice of ~N nodes with 10 % position
noise, stress-free, ``k = 1``; the spring nearest the centre is strained to ``S`` by moving
its two nodes apart symmetrically and pinning them there, plus the default pins. All
methods stop at the package's local rule, relative residual ``<= 1e-10`` (each net force
against its node's ``sum k L``); jax-md's FIRE runs in jitted chunks of 50 steps in
float64 on the free coordinates (compile time excluded, standard jax-md parameters with
``dt_start = 0.1 dt_max`` and the same ``dt_max`` as the package's FIRE). Prints seconds
and iterations, time per FIRE iteration, and the ratios.

    python benchmarks/bench_jaxmd.py --jax-path /tmp/jax --sizes 256,1024,4096
"""

from __future__ import annotations

import argparse
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
    return p.parse_args()


def main() -> None:
    args = _parse()
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
    from continuum_vs_network.network.energy import hessian_norm_bound

    try:
        import jax
        import jax.numpy as jnp
        from jax_md import minimize

        jax.config.update("jax_enable_x64", True)
        have_jax = True
    except ImportError:
        have_jax = False
        print("# jax / jax-md not importable: timing the package's methods only")

    def setup(n_nodes: int, strain: float):
        side = round(float(np.sqrt(n_nodes)))
        net = cvn.triangular_lattice(side, side, noise=0.1, rng=np.random.default_rng(0))
        mid = net.positions[net.springs].mean(axis=1)
        c = int(np.argmin(np.linalg.norm(mid - net.positions.mean(axis=0), axis=1)))
        a, b = net.springs[c]
        x0 = net.positions.copy()
        d = x0[b] - x0[a]
        grow = strain * d
        x0[a] -= 0.5 * grow
        x0[b] += 0.5 * grow
        pins = cvn.default_pins(net, avoid=[c])
        pins[[a, b]] = True
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

        def run(budget_s):
            state = init(jnp.asarray(x0.ravel()[free]))
            it = 0
            t0 = time.perf_counter()
            while True:
                g = np.asarray(grad(state.position))
                if np.max(np.abs(g) / scale) <= tol:
                    return time.perf_counter() - t0, it, True
                if time.perf_counter() - t0 > budget_s:
                    return time.perf_counter() - t0, it, False
                state = chunk(state)
                state.position.block_until_ready()
                it += 50

        init = jax.jit(init)
        warm = chunk(init(jnp.asarray(x0.ravel()[free])))  # compile (both state signatures)
        chunk(warm).position.block_until_ready()
        grad(warm.position).block_until_ready()
        return run

    from continuum_vs_network.network.kkt import sparse_solver

    print(
        f"# bench_jaxmd: {' '.join(sys.argv[1:])}; jax-md={have_jax}; one BLAS thread; "
        f"sparse solver {sparse_solver()}"
    )
    print(f"{'N':>6} {'S':>5} {'method':>8} {'seconds':>9} {'iters':>7} {'us/iter':>8}")
    rows = []
    for n in [int(s) for s in args.sizes.split(",")]:
        for strain in [float(s) for s in args.strains.split(",")]:
            net, x0, pins = setup(n, strain)
            times = {}
            for method in ("newton", "fire"):
                kw = {} if method == "newton" else {"max_iter": 10**9}
                cvn.relax(net, pinned=pins, x0=x0, method=method, **kw)  # warm caches
                t0 = time.perf_counter()
                try:
                    eq = cvn.relax(
                        net, pinned=pins, x0=x0, method=method, max_seconds=args.max_seconds, **kw
                    )
                    ok, its = True, eq.iterations
                except cvn.EquilibriumError as err:
                    ok, its = False, err.state.iterations
                dt = time.perf_counter() - t0
                times[method] = (dt, its, ok)
            if have_jax:
                times["jax-md"] = jax_fire(net, x0, pins, 1e-10)(args.max_seconds)
            for method, (dt, its, ok) in times.items():
                per = f"{dt / its * 1e6:8.0f}" if its and method != "newton" else f"{'':>8}"
                flag = "" if ok else "  NOT CONVERGED"
                print(f"{net.n_nodes:>6} {strain:>5g} {method:>8} {dt:9.3f} {its:7d} {per}{flag}")
            rows.append((net.n_nodes, strain, times))
    print(
        "\n# ratios (same run): jax-md FIRE / newton (time to 1e-10), "
        "package FIRE / jax-md FIRE (time per iteration)"
    )
    for n, strain, t in rows:
        if "jax-md" not in t:
            continue
        speed = t["jax-md"][0] / t["newton"][0]
        per = (t["fire"][0] / t["fire"][1]) / (t["jax-md"][0] / max(t["jax-md"][1], 1))
        print(
            f"{n:>6} {strain:>5g}  newton {speed:6.1f}x faster than jax-md FIRE; "
            f"package FIRE per iteration {per:5.2f}x jax-md's"
        )


if __name__ == "__main__":
    main()
