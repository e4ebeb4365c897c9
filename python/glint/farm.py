"""Render an animation on a Dask cluster: frames × tiles, merged, bit-identical to one machine.

    python -m glint.farm SCENE --frames A..B --out DIR [--tile SIZE] [--spp N]
        [--resolution WxH] [--scheduler ADDRESS | --workers K] [--overwrite]

Each task renders one tile (``glint.render`` with ``pixel_bounds``) of one frame on a Dask
worker. A tile's pixels are exactly the full frame's pixels there (each pixel's samples depend
on the scene, the settings and the pixel alone), so the frames merged here equal, bit for bit,
the ones ``cargo xtask render --frames A..B`` writes on one machine. The client writes
``DIR/<scene>_<frame>.exr``, ``.png`` and ``.json`` (the frame's summary) atomically: each to a
temporary file, then renamed, the JSON last. A frame whose three outputs exist and whose JSON
records the same scene (SHA-256 of the scene file and its assets), resolution, samples and glint version is
skipped, so an interrupted run continues where it stopped; ``--overwrite`` renders it again.

Tasks that raise are retried (``retries``); tasks on a worker that dies are run again on
another (Dask's own rescheduling). Workers need the ``glint`` package (install the same wheel
everywhere) and must see the scene file and its assets at the same path (a shared file
system). See ``docs/farm.md`` in the repository for clusters (Slurm through dask-jobqueue).

From Python: ``glint.farm.render_frames(scene, frames, out, ...)`` returns the paths written.
"""

import argparse
import hashlib
import json
import os
import sys
import time
import uuid

import numpy as np

from . import __version__
from ._render import render, write_exr, write_png

#: The most frames one run renders, as ``cargo xtask render --frames``.
MAX_FRAMES = 100_000

#: The summary fields summed over a frame's tiles.
_SUMMED = ("seconds", "rays", "glint_queries", "negligible_queries", "clamped_samples",
           "discarded_samples")


def tiles(width, height, size):
    """The (x0, x1, y0, y1) tiles of side ``size`` covering a width × height image, row by row."""
    if size < 1:
        raise ValueError(f"the tile size must be at least 1 pixel, not {size}")
    return [(x0, min(x0 + size, width), y0, min(y0 + size, height))
            for y0 in range(0, height, size) for x0 in range(0, width, size)]


def render_tile(scene, frame, bounds, resolution, spp, threads):
    """One task: the tile ``bounds`` of ``frame``, as (bounds, float32 image, stats)."""
    result = render(scene, frame=frame, pixel_bounds=bounds, resolution=resolution, spp=spp,
                    threads=threads)
    return bounds, result["image"], result["stats"]


def sources_sha256(sources):
    """The SHA-256 of the files a scene is built from (the scene file and the assets it read,
    a render's ``stats["sources"]``), names and bytes in order: what a resumed run compares."""
    digest = hashlib.sha256()
    for path in sources:
        digest.update(os.path.basename(path).encode() + b"\0")
        with open(path, "rb") as file:
            for block in iter(lambda: file.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()


def _atomic(path, write):
    """Runs ``write(temporary)`` and renames the temporary file to ``path``."""
    root, extension = os.path.splitext(path)
    temporary = f"{root}.partial-{os.getpid()}{extension}"
    try:
        write(temporary)
        os.replace(temporary, path)
    finally:
        if os.path.exists(temporary):
            os.remove(temporary)


def _outputs(out, stem, frame):
    base = os.path.join(out, f"{stem}_{frame:04d}")
    return base + ".exr", base + ".png", base + ".json"


def _is_done(paths, identity):
    """Whether a frame's outputs exist and its summary records ``identity``."""
    if not all(os.path.isfile(p) for p in paths):
        return False
    try:
        with open(paths[2]) as file:
            return json.load(file).get("farm", {}).get("identity") == identity
    except (OSError, ValueError):
        return False


class _Progress:
    """Tiles and frames done, on one line of stderr (a line per frame when not a terminal)."""

    def __init__(self, tiles_total, frames_total, enabled):
        self.tiles, self.frames = 0, 0
        self.tiles_total, self.frames_total = tiles_total, frames_total
        self.enabled = enabled
        self.start = time.monotonic()
        self.terminal = sys.stderr.isatty()

    def tile(self):
        self.tiles += 1
        if self.enabled and self.terminal:
            self._show(end="")

    def frame(self, name):
        self.frames += 1
        if self.enabled:
            self._show(end="\n" if not self.terminal else "", name=name)

    def _show(self, end, name=None):
        width = 30
        filled = width * self.tiles // max(1, self.tiles_total)
        bar = "=" * filled + " " * (width - filled)
        line = (f"[{bar}] {self.tiles}/{self.tiles_total} tiles, {self.frames}/"
                f"{self.frames_total} frames, {time.monotonic() - self.start:.1f} s")
        if name is not None:
            line += f"  wrote {name}"
        print(("\r" if self.terminal else "") + line, end=end, file=sys.stderr, flush=True)


def _frame_summary(frame, parts, identity, resolution, workers):
    """One frame's summary from its tiles' stats: the first tile's settings, sums of counts."""
    first = parts[0]
    summary = {key: first[key] for key in (
        "scene", "sources", "frame", "resolution", "spp", "smooth", "glint_footprints", "exposure",
        "bloom", "expected_footprint_areas") if key in first}
    summary["pixel_bounds"] = [0, resolution[0], 0, resolution[1]]
    for key in _SUMMED:
        summary[key] = sum(p[key] for p in parts)
    summary["tiles"] = len(parts)
    summary["farm"] = {"identity": identity, "workers": workers}
    return summary


def render_frames(scene, frames, out, *, tile=64, spp=None, resolution=None, client=None,
                  scheduler=None, workers=None, threads=None, overwrite=False, retries=3,
                  frames_in_flight=None, progress=True, on_tile=None):
    """Renders frames ``frames`` (an iterable of ints, or ``(a, b)`` for a..b inclusive) of the
    scene file ``scene`` into folder ``out`` on a Dask cluster and returns the paths written
    (EXR, PNG and JSON per frame rendered; frames already done are skipped and not listed).

    The cluster is ``client`` (a ``distributed.Client``), else a new client of the scheduler at
    ``scheduler``, else a ``LocalCluster`` of ``workers`` processes (default 2) that is closed
    at the end. ``threads`` is each task's render threads (default: the machine's cores shared
    among a local cluster's workers; all of a remote worker's cores). At most
    ``frames_in_flight`` frames (default: twice the workers, at least 2) are rendered at once,
    so the client holds that many frame buffers whatever the length of the animation.
    ``on_tile(frame, bounds)`` is called on the client as each tile arrives.
    """
    from dask.distributed import Client, LocalCluster, as_completed

    scene = os.path.abspath(os.fspath(scene))
    if not os.path.isfile(scene):
        raise FileNotFoundError(f"scene file {scene!r} does not exist")
    if isinstance(frames, tuple) and len(frames) == 2:
        frames = range(frames[0], frames[1] + 1)
    if len(frames) > MAX_FRAMES:
        raise ValueError(f"{len(frames)} frames, more than the limit of {MAX_FRAMES} per run "
                         "(as cargo xtask render --frames; split the range)")
    frames = list(frames)
    os.makedirs(out, exist_ok=True)
    stem = os.path.splitext(os.path.basename(scene))[0]
    # The frame size (and a check of the scene and the options) from a one-pixel render here.
    probe = render(scene, frame=frames[0] if frames else 0, pixel_bounds=(0, 1, 0, 1),
                   resolution=resolution, spp=spp, threads=1)["stats"]
    width, height = probe["resolution"]
    samples = probe["spp"]
    identity = {"sources_sha256": sources_sha256(probe["sources"]),
                "resolution": [width, height], "spp": samples, "glint": __version__}
    todo = [f for f in frames if overwrite or not _is_done(_outputs(out, stem, f), identity)]
    for f in frames:
        if f not in todo and progress:
            print(f"frame {f}: done already ({_outputs(out, stem, f)[0]}), skipped",
                  file=sys.stderr)
    if not todo:
        return []
    cluster = None
    own_client = client is None
    if own_client:
        if scheduler is not None:
            client = Client(scheduler)
        else:
            count = 2 if workers is None else workers
            if threads is None:
                threads = max(1, (os.cpu_count() or 1) // count)
            cluster = LocalCluster(n_workers=count, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            client = Client(cluster)
    try:
        boxes = tiles(width, height, tile)
        worker_count = len(client.scheduler_info().get("workers", {}))
        # Frames in flight at once: enough to keep every worker busy across a frame's last
        # tiles, few enough that the merge buffers (one image per frame) stay bounded.
        window = max(2, 2 * worker_count) if frames_in_flight is None else frames_in_flight
        if window < 1:
            raise ValueError(f"frames_in_flight must be at least 1, not {window}")
        waiting = list(todo)
        futures = {}
        pending = as_completed()

        def submit_next_frame():
            f = waiting.pop(0)
            for bounds in boxes:
                key = f"glint-tile-{stem}-{f}-{bounds[0]}-{bounds[2]}-{uuid.uuid4().hex}"
                future = client.submit(render_tile, scene, f, bounds, (width, height), samples,
                                       threads, retries=retries, pure=False, key=key)
                futures[future] = f
                pending.add(future)
            images[f] = np.zeros((height, width, 3), dtype=np.float32)
            parts[f] = []

        images, parts = {}, {}
        while waiting and len(images) < window:
            submit_next_frame()
        meter = _Progress(len(boxes) * len(todo), len(todo), progress)
        written = []
        for future in pending:
            f = futures.pop(future)
            (x0, x1, y0, y1), image, stats = future.result()
            images[f][y0:y1, x0:x1] = image
            parts[f].append(stats)
            meter.tile()
            if on_tile is not None:
                on_tile(f, (x0, x1, y0, y1))
            if len(parts[f]) < len(boxes):
                continue
            paths = _outputs(out, stem, f)
            summary = _frame_summary(f, parts.pop(f), identity, (width, height), worker_count)
            frame_image = images.pop(f)
            _atomic(paths[0], lambda p, im=frame_image: write_exr(p, im))
            _atomic(paths[1], lambda p, im=frame_image, s=summary: write_png(
                p, im, s.get("exposure", 0.0), s.get("bloom")))

            def write_json(p, s=summary):
                with open(p, "w") as file:
                    json.dump(s, file, indent=2)
                    file.write("\n")

            _atomic(paths[2], write_json)
            written.extend(paths)
            meter.frame(os.path.basename(paths[0]))
            if waiting:
                submit_next_frame()
        return written
    finally:
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()


def _frames(text):
    first, _, last = text.partition("..")
    try:
        a, b = int(first), int(last.lstrip("="))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not A..B") from None
    if b < a:
        raise argparse.ArgumentTypeError(f"{text!r}: the last frame comes before the first")
    return a, b


def _resolution(text):
    width, _, height = text.lower().partition("x")
    try:
        return int(width), int(height)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT") from None


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m glint.farm",
        description="Render frames of a glint scene file on a Dask cluster, tile by tile.")
    parser.add_argument("scene", help="the scene file (TOML, scenes/README.md)")
    parser.add_argument("--frames", type=_frames, default=(0, 0), metavar="A..B",
                        help="camera frames A to B inclusive (default 0..0)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--tile", type=int, default=64, help="tile side in pixels (64)")
    parser.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    parser.add_argument("--resolution", type=_resolution, metavar="WxH",
                        help="image size (default: the scene's)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="a running Dask scheduler, e.g. tcp://10.0.0.1:8786")
    where.add_argument("--workers", type=int, metavar="K",
                       help="a local cluster of K worker processes (default 2)")
    parser.add_argument("--threads", type=int,
                        help="render threads per task (default: cores / local workers)")
    parser.add_argument("--retries", type=int, default=3, help="retries of a failed task (3)")
    parser.add_argument("--overwrite", action="store_true",
                        help="render frames whose outputs exist too")
    parser.add_argument("--quiet", action="store_true", help="no progress")
    args = parser.parse_args(argv)
    try:
        written = render_frames(args.scene, args.frames, args.out, tile=args.tile, spp=args.spp,
                                resolution=args.resolution, scheduler=args.scheduler,
                                workers=args.workers, threads=args.threads,
                                overwrite=args.overwrite, retries=args.retries,
                                progress=not args.quiet)
    except KeyboardInterrupt:
        print("\ninterrupted: frames written so far are kept; run again to render the rest",
              file=sys.stderr)
        return 130
    except (ValueError, OSError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"{len(written) // 3} frame(s) written to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
