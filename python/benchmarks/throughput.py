"""Queries per second for 10⁶ queries: the Python package against `cargo xtask eval` (JSON
Lines) and the Rust API (`cargo run --release -p glint-eval --example throughput`), on the
same queries and material.

    python python/benchmarks/throughput.py [--queries N]

Run from the repository's root with the package installed (`pip install ./python`). The
queries are near a Beckmann α = 0.1 highlight (N = 10⁹, γ = 1°, seed 7) with pixel-sized
footprints of 10⁻⁴ to 10⁻³, as a renderer makes them.
"""

import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np

import glint

MATERIAL = dict(distribution="beckmann", alpha=0.1, particles=1e9, gamma_degrees=1.0, seed=7)


def queries(n, seed=1):
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0.0, 1.2, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    wi = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    wo = wi * np.array([-1.0, -1.0, 1.0]) + rng.normal(0.0, 0.1, (n, 3))
    uv = rng.uniform(0.0, 1.0, (n, 2))
    side = 10 ** rng.uniform(-4, -3, n)
    dx = np.stack([side, np.zeros(n)], 1)
    dy = np.stack([np.zeros(n), side], 1)
    return wi, wo, uv, dx, dy


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--queries", type=int, default=1_000_000)
    n = parser.parse_args().queries
    wi, wo, uv, dx, dy = queries(n)
    m = glint.Material(**MATERIAL)

    start = time.perf_counter()
    r = m.eval(wi, wo, uv, dx, dy)
    seconds = time.perf_counter() - start
    print(f"Python glint.Material.eval, {os.cpu_count()} threads: {n / seconds:.0f} queries/s "
          f"({seconds:.2f} s); particles found: {np.nansum(r['count'])}")

    with tempfile.TemporaryDirectory() as folder:
        lines = os.path.join(folder, "queries.jsonl")
        with open(lines, "w") as out:
            for i in range(n):
                out.write(json.dumps({
                    "material": MATERIAL, "wi": wi[i].tolist(), "wo": wo[i].tolist(),
                    "uv": uv[i].tolist(), "duv_dx": dx[i].tolist(),
                    "duv_dy": dy[i].tolist()}) + "\n")
        subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "xtask"], check=True)
        start = time.perf_counter()
        with open(lines) as source:
            subprocess.run(["target/release/xtask", "eval"], stdin=source,
                           stdout=subprocess.DEVNULL, check=True)
        seconds = time.perf_counter() - start
        print(f"cargo xtask eval (JSON Lines, one thread): {n / seconds:.0f} queries/s "
              f"({seconds:.2f} s)")

        raw = os.path.join(folder, "queries.f64")
        np.concatenate([wi, wo, uv, dx, dy], axis=1).astype("<f8").tofile(raw)
        subprocess.run(["cargo", "run", "--release", "--quiet", "-p", "glint-eval",
                        "--example", "throughput", "--", raw], check=True)


if __name__ == "__main__":
    main()
