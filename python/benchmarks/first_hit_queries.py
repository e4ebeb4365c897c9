"""The first-hit glint queries of a rendered frame, in pixel order, and what the package takes
to answer them against a renderer's loop over the same queries.

    RAYON_NUM_THREADS=1 python python/benchmarks/first_hit_queries.py [--resolution 160x90]
        [--spp 8] [--out target/first_hit_queries.f64] [--rounds 3]

Renders the sphere-lights example (python/mitsuba) in Mitsuba 3's ``llvm_ad_rgb`` with the
vectorized ``glint_direct`` integrator, recording every query the glint BSDF makes with a
footprint (light samples, and BSDF samples whose ray meets a light), in the order the
integrator asks them (pixel order: Mitsuba's wavefront index is pixel × spp + sample). The
plugin's own negligible-query test is switched off while recording, so that the rows are all of
the frame's first-hit queries, negligible ones included. Writes them as raw little-endian
float64, 12 per query (wi, wo, uv, duv_dx, duv_dy, as ``cargo run --release -p glint-eval
--example batch_speed`` reads them), then times, alternating, the package's ``f_hat`` on them
(what the plugin calls), its ``eval`` with every column, and that example's renderer loop (one
scratch, the given order, ``DiscreteBrdf::at(..).evaluate``, as glint-tracer calls it), each
per query on one thread. Needs the example built (``cargo build --release -p glint-eval
--example batch_speed``) and ``DRJIT_LIBLLVM_PATH`` (python/README.md).
"""

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import mitsuba as mi
import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--resolution", default="160x90")
    parser.add_argument("--spp", type=int, default=8)
    parser.add_argument("--out", type=Path, default=ROOT / "target" / "first_hit_queries.f64")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    mi.set_variant("llvm_ad_rgb")
    sys.path.insert(0, str(ROOT / "python" / "mitsuba"))
    import glint_mitsuba as gm

    import glint

    res = tuple(int(x) for x in args.resolution.split("x"))
    scene = mi.load_dict(gm.sphere_lights_scene(res, args.spp, "glint"))
    bsdf = next(s.bsdf() for s in scene.shapes() if isinstance(s.bsdf(), gm.GlintBSDF))
    rows = []
    answer = bsdf.material.f_hat

    def record(wi, wo, uv, dx, dy):
        rows.append(np.concatenate([wi, wo, uv, dx, dy], axis=1))
        return answer(wi, wo, uv, dx, dy)

    bsdf.material.f_hat = record
    bsdf.lobe.negligible = None  # every first-hit query goes to the package
    gm.render(scene)
    queries = np.ascontiguousarray(np.concatenate(rows), dtype="<f8")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    queries.tofile(args.out)
    n = len(queries)
    print(f"{args.out}: {n} first-hit queries of {args.resolution} at {args.spp} spp")

    material = glint.Material(**bsdf.params)
    columns = [np.ascontiguousarray(queries[:, a:b]) for a, b in
               ((0, 3), (3, 6), (6, 8), (8, 10), (10, 12))]
    spec = json.dumps({k: v for k, v in material._spec.items()})
    example = ROOT / "target" / "release" / "examples" / "batch_speed"
    for k in range(args.rounds):
        start = time.perf_counter()
        material.f_hat(*columns)
        fast = (time.perf_counter() - start) / n * 1e6
        start = time.perf_counter()
        material.eval(*columns)
        full = (time.perf_counter() - start) / n * 1e6
        run = subprocess.run([str(example), str(args.out), spec], capture_output=True,
                             text=True, check=True)
        loop = float(re.search(r"renderer loop ([0-9.]+)", run.stdout).group(1))
        print(f"round {k}: package f_hat {fast:.2f} µs/query ({fast / loop:.2f}× the renderer "
              f"loop), eval with every column {full:.2f} µs/query; renderer loop {loop:.2f} "
              f"µs/query", flush=True)


if __name__ == "__main__":
    main()
