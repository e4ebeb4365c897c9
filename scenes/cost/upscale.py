"""The glitter pattern with its three maps upscaled (nearest), for the map-layout figures of
docs/performance.md ("Glint maps", memory): the same functions at FACTOR times the resolution.

Writes OUT/glitter_pattern_{density,alpha,tint}.png and OUT/glitter_pattern_big.toml (the
scene with those textures). Usage, from the repository root, with the project's Python
environment (numpy and Mitsuba's Bitmap read and write the PNGs):

    target/python-venv/bin/python scenes/cost/upscale.py OUT [FACTOR]     # FACTOR: 16
"""

import sys
from pathlib import Path

import mitsuba as mi
import numpy as np


def main():
    out = Path(sys.argv[1]).resolve()
    factor = int(sys.argv[2]) if len(sys.argv) > 2 else 16
    out.mkdir(parents=True, exist_ok=True)
    mi.set_variant("scalar_rgb")
    scenes = Path(__file__).resolve().parents[1]
    for name in ["density", "alpha", "tint"]:
        source = mi.Bitmap(str(scenes / "assets" / f"glitter_pattern_{name}.png"))
        texels = np.array(source)
        upscaled = np.repeat(np.repeat(texels, factor, axis=0), factor, axis=1)
        image = mi.Bitmap(np.ascontiguousarray(upscaled), mi.Bitmap.PixelFormat.RGB)
        image.set_srgb_gamma(source.srgb_gamma())
        image.write(str(out / f"glitter_pattern_{name}.png"))
    scene = (scenes / "glitter_pattern.toml").read_text()
    for name in ["density", "alpha", "tint"]:
        scene = scene.replace(f'"assets/glitter_pattern_{name}.png"',
                              f'"{out / f"glitter_pattern_{name}.png"}"')
    for asset in ["vase.obj", "sky.png"]:
        scene = scene.replace(f'"assets/{asset}"', f'"{scenes / "assets" / asset}"')
    (out / "glitter_pattern_big.toml").write_text(scene)


if __name__ == "__main__":
    main()
