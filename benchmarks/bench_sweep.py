"""Wall time of a built-in sweep with 1 worker (serial, no Dask) and N local Dask workers.

Both runs start from an empty folder in the same process, one after the other, and their
tables are compared (every column but the wall-clock one must agree exactly)::

    python benchmarks/bench_sweep.py                  # eta_alpha, 1 and 2 workers
    python benchmarks/bench_sweep.py --workers 1 2 4 --scene eta_alpha

The times include starting the local Dask cluster (a few seconds) and writing the table.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="eta_alpha")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()

    from continuum_vs_network.scenes import load_scene
    from continuum_vs_network.scenes.sweep import run_sweep

    scene = load_scene(args.scene)
    print(f"scene {scene.name}; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}")
    times, frames = {}, {}
    with tempfile.TemporaryDirectory(prefix="bench_sweep_") as tmp:
        for n in args.workers:
            t0 = time.perf_counter()
            result = run_sweep(scene, f"{tmp}/w{n}", workers=n, progress=False)
            times[n] = time.perf_counter() - t0
            frames[n] = result.frame()
            trial_seconds = sum(r["wall_seconds"] for r in result.rows)
            print(
                f"workers {n}: {times[n]:6.1f} s wall, {len(result.points)} points, "
                f"{len(result.rows)} trials, sum of trial times {trial_seconds:.1f} s "
                f"({result.info['executor']})"
            )
    first = args.workers[0]
    cols = [c for c in frames[first].columns if c != "wall_seconds"]
    for n in args.workers[1:]:
        same = frames[n][cols].equals(frames[first][cols])
        print(
            f"speed-up {first} -> {n} workers: {times[first] / times[n]:.2f}x; "
            f"tables identical: {same}"
        )


if __name__ == "__main__":
    main()
