"""Frames per minute of `python -m glint.farm` on a local Dask cluster of 1 and of 2 worker
processes, against `cargo xtask render --frames` of the same frames on one process, measured
alternately (rounds of: xtask, 1 worker, 2 workers) so that a shared machine's load falls on
all three alike.

    python python/benchmarks/farm_scaling.py [--scene S] [--frames 4] [--resolution 320x180]
        [--spp 16] [--tile 64] [--rounds 2]

Run from the repository's root with the package installed with its `farm` extra and
`cargo build --release -p xtask` done (or GLINT_XTASK naming the binary). Every farm task
renders with cores / workers threads, so each configuration uses every core; what the farm
adds is the tiles' scheduling, the scene loaded once per worker process, and the merge.
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

from glint.farm import render_frames


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--scene", default="scenes/sphere_lights.toml")
    parser.add_argument("--frames", type=int, default=4)
    parser.add_argument("--resolution", default="320x180")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--tile", type=int, default=64)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    width, height = (int(v) for v in args.resolution.split("x"))
    xtask = os.environ.get("GLINT_XTASK", "target/release/xtask")
    frames = (0, args.frames - 1)
    times = {"xtask render (1 process)": [], "farm, 1 worker": [], "farm, 2 workers": []}
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory() as out:
            start = time.monotonic()
            subprocess.run([xtask, "render", args.scene, "--frames", f"0..{args.frames - 1}",
                            "--resolution", args.resolution, "--spp", str(args.spp), "--out",
                            out, "--quiet"], check=True, capture_output=True)
            times["xtask render (1 process)"].append(time.monotonic() - start)
        for workers in (1, 2):
            out = tempfile.mkdtemp()
            try:
                start = time.monotonic()
                render_frames(args.scene, frames, out, tile=args.tile, spp=args.spp,
                              resolution=(width, height), workers=workers, progress=False)
                times[f"farm, {workers} worker{'s' if workers > 1 else ''}"].append(
                    time.monotonic() - start)
            finally:
                shutil.rmtree(out)
    print(f"{args.scene}, {args.frames} frames of {args.resolution} at {args.spp} spp, "
          f"tiles of {args.tile}, {os.cpu_count()} cores, {args.rounds} rounds (best of):",
          file=sys.stderr)
    print("| configuration | seconds | frames per minute |")
    print("|---|---|---|")
    for name, seconds in times.items():
        best = min(seconds)
        print(f"| {name} | {best:.1f} (all: {', '.join(f'{s:.1f}' for s in seconds)}) | "
              f"{60 * args.frames / best:.1f} |")


if __name__ == "__main__":
    main()
