"""The sphere-lights example in Mitsuba 3 with a glint floor against Mitsuba's roughconductor
floor in the same integrator, alternating, in one run.

    python python/benchmarks/mitsuba_floor.py [--variant llvm_ad_rgb] [--integrator glint_direct]
        [--resolution 160x90] [--spp 8] [--pairs 3] [--density-map stripes|IMAGE]

Prints each render's time, the medians of the times and of the pairs' ratios (glint /
roughconductor), and the ratios' range. Each configuration is rendered once first (Dr.Jit
compiles its kernels; not timed). ``llvm_*`` variants need ``DRJIT_LIBLLVM_PATH`` (python/README.md).
``--density-map`` maps the glint floor's flake density as the example's option does
(``stripes``: bands of flakes and bare floor, ``glint_mitsuba.stripes_density_map``; or an
image file); the roughconductor floor stays as it is.
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import drjit as dr
import mitsuba as mi


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument("--integrator", choices=["glint_direct", "glint_path"],
                        default="glint_direct")
    parser.add_argument("--resolution", default="160x90")
    parser.add_argument("--spp", type=int, default=8)
    parser.add_argument("--pairs", type=int, default=3)
    parser.add_argument("--density-map", default=None, metavar="stripes|IMAGE")
    args = parser.parse_args()
    mi.set_variant(args.variant)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "mitsuba"))
    import glint_mitsuba as gm

    res = tuple(int(x) for x in args.resolution.split("x"))
    density_map = args.density_map
    if density_map == "stripes":
        density_map = gm.stripes_density_map()
    scenes = {floor: mi.load_dict(gm.sphere_lights_scene(
        res, args.spp, floor, integrator=args.integrator,
        density_map=density_map if floor == "glint" else None))
        for floor in ("glint", "roughconductor")}
    for scene in scenes.values():
        gm.render(scene)
    times = {"glint": [], "roughconductor": []}
    for pair in range(args.pairs):
        for floor, scene in scenes.items():
            start = time.perf_counter()
            image = gm.render(scene, seed=pair + 1)
            dr.eval(image)
            dr.sync_thread()
            times[floor].append(time.perf_counter() - start)
            print(f"pair {pair}: {floor} {times[floor][-1]:.2f} s", flush=True)
    ratios = [g / r for g, r in zip(times["glint"], times["roughconductor"])]
    mapped = "" if args.density_map is None else f" (density map {args.density_map})"
    print(f"{args.variant}, {args.integrator}, {args.resolution}, {args.spp} spp: glint{mapped} "
          f"{statistics.median(times['glint']):.2f} s, roughconductor "
          f"{statistics.median(times['roughconductor']):.2f} s, glint / roughconductor "
          f"{statistics.median(ratios):.2f}× (median of {args.pairs} pairs; "
          f"{min(ratios):.2f}–{max(ratios):.2f}×)")


if __name__ == "__main__":
    main()
