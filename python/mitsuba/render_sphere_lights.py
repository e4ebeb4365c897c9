"""Render the sphere-lights scene (scenes/sphere_lights.toml, small) with Mitsuba 3 and glint.

    python python/mitsuba/render_sphere_lights.py [--variant scalar_rgb|llvm_ad_rgb]
        [--integrator glint_direct|glint_path] [--spp N] [--resolution WxH] [--out FILE]
        [--floor glint|roughconductor] [--density-map stripes|IMAGE]

FILE ends in .png (exposure −2.5 stops, as the scene file; sRGB) or .exr (linear). In
``scalar_rgb`` Mitsuba calls the Python plugins once per sample, so the default is small
(160×90 at 8 spp: about 20 s); in ``llvm_ad_rgb`` they answer whole wavefronts (about 1 s; it
needs LLVM 19, see python/README.md). ``--integrator glint_path`` (vectorized variants only)
traces paths: pixel footprints at the first hit, the smooth limit after. Images are rendered
in passes of ``--samples-per-pass`` samples per pixel (by default as many as keep a pass
within 2²¹ samples), so memory stays bounded. ``--density-map`` maps the glint floor's flake
density: ``stripes`` (bands of flakes and bare floor across the view,
``glint_mitsuba.stripes_density_map``) or an image file, read as the glint BSDF reads a
filename (python/mitsuba/glint_maps.py), its texture square 80 m of the floor.
"""

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mitsuba as mi  # noqa: E402


def resolution(text):
    try:
        w, h = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"resolution must be WxH, not {text!r}") from None
    if not (1 <= w <= 16384 and 1 <= h <= 16384):
        raise argparse.ArgumentTypeError(f"resolution {w}x{h} is out of range")
    return w, h


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spp", type=int, default=8, help="samples per pixel (8)")
    parser.add_argument("--resolution", type=resolution, default=(160, 90),
                        help="WxH (160x90)")
    parser.add_argument("--out", type=Path, default=Path("sphere_lights_mitsuba.png"),
                        help="output .png or .exr (sphere_lights_mitsuba.png)")
    parser.add_argument("--floor", choices=["glint", "roughconductor"], default="glint",
                        help="the floor's BSDF (glint)")
    parser.add_argument("--density-map", default=None, metavar="stripes|IMAGE",
                        help="the glint floor's density map: bands across the view "
                             "(stripes) or an image file (none)")
    parser.add_argument("--seed", type=int, default=0, help="sampler seed (0)")
    parser.add_argument("--variant", choices=["scalar_rgb", "llvm_ad_rgb", "cuda_ad_rgb"],
                        default="scalar_rgb", help="Mitsuba variant (scalar_rgb)")
    parser.add_argument("--integrator", choices=["glint_direct", "glint_path"],
                        default="glint_direct",
                        help="glint_direct, or glint_path in vectorized variants (glint_direct)")
    parser.add_argument("--samples-per-pass", type=int, default=None,
                        help="samples per pixel per pass, a divisor of --spp (automatic)")
    args = parser.parse_args(argv)
    if args.spp < 1:
        parser.error("--spp must be at least 1")
    if args.samples_per_pass is not None and not (
            1 <= args.samples_per_pass <= args.spp and args.spp % args.samples_per_pass == 0):
        parser.error("--samples-per-pass must be a divisor of --spp")
    if args.integrator == "glint_path" and args.variant == "scalar_rgb":
        parser.error("--integrator glint_path needs a vectorized variant (--variant llvm_ad_rgb): "
                     "the scalar plugins have no path integrator")
    if args.density_map is not None and args.floor != "glint":
        parser.error("--density-map maps the glint floor (--floor glint)")
    if args.variant not in mi.variants():
        parser.error(f"this Mitsuba has no variant {args.variant}")
    mi.set_variant(args.variant)
    import glint_mitsuba as gm  # registers the plugins of the variant
    suffix = args.out.suffix.lower()
    if suffix not in (".png", ".exr"):
        parser.error("--out must end in .png or .exr")

    density_map = args.density_map
    if density_map == "stripes":
        density_map = gm.stripes_density_map()
    scene = mi.load_dict(gm.sphere_lights_scene(args.resolution, args.spp, args.floor,
                                                sampler_seed=args.seed,
                                                integrator=args.integrator,
                                                density_map=density_map))
    start = time.perf_counter()
    image = gm.render(scene, samples_per_pass=args.samples_per_pass, seed=args.seed)
    seconds = time.perf_counter() - start
    if suffix == ".png":
        image = image * math.pow(2.0, gm.EXPOSURE)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    mi.util.write_bitmap(str(args.out), image)
    w, h = args.resolution
    mapped = "" if args.density_map is None else f" (density map {args.density_map})"
    print(f"{args.out}: {w}x{h}, {args.spp} spp, {args.floor} floor{mapped}, {args.variant}, "
          f"{args.integrator}, {seconds:.1f} s")


if __name__ == "__main__":
    main()
