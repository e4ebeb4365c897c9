"""Render the sphere-lights scene (scenes/sphere_lights.toml, small) with Mitsuba 3 and glint.

    python python/mitsuba/render_sphere_lights.py [--spp N] [--resolution WxH] [--out FILE]

FILE ends in .png (exposure −2.5 stops, as the scene file; sRGB) or .exr (linear). Scalar
Mitsuba calls the Python plugins once per sample (~0.2 ms each with a glint floor), so the
default is small: 160×90 at 8 spp takes about 20 s.
"""

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import glint_mitsuba as gm  # noqa: E402  (sets the variant and registers the plugins)
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
    parser.add_argument("--seed", type=int, default=0, help="sampler seed (0)")
    args = parser.parse_args(argv)
    if args.spp < 1:
        parser.error("--spp must be at least 1")
    suffix = args.out.suffix.lower()
    if suffix not in (".png", ".exr"):
        parser.error("--out must end in .png or .exr")

    scene = mi.load_dict(gm.sphere_lights_scene(args.resolution, args.spp, args.floor,
                                                sampler_seed=args.seed))
    start = time.perf_counter()
    image = mi.render(scene)
    seconds = time.perf_counter() - start
    if suffix == ".png":
        image = image * math.pow(2.0, gm.EXPOSURE)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    mi.util.write_bitmap(str(args.out), image)
    w, h = args.resolution
    print(f"{args.out}: {w}x{h}, {args.spp} spp, {args.floor} floor, {seconds:.1f} s")


if __name__ == "__main__":
    main()
