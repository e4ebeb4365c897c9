"""Render an animation on a Dask cluster: frames × tiles, merged, bit-identical to one machine.

    python -m glint.farm SCENE --frames A..B --out DIR [--tile SIZE] [--spp N]
        [--resolution WxH] [--scheduler ADDRESS | --workers K] [--threads N] [--retries N]
        [--worker-timeout SECONDS] [--connect-timeout SECONDS] [--overwrite] [--quiet]

Each task renders one tile (``glint.render`` with ``pixel_bounds``) of one frame on a Dask
worker. A tile's pixels are exactly the full frame's pixels there (each pixel's samples depend
on the scene, the settings and the pixel alone), so the frames merged here equal, bit for bit,
the ones ``cargo xtask render --frames A..B`` writes on one machine. The farm renders whole
frames: a scene file that sets ``[render] pixel_bounds`` is refused.

Every argument is checked before anything starts (no folder, no lock, no cluster), with a
``ValueError`` or ``TypeError`` naming it. ``frames`` is ``(first, last)`` (a tuple of two
ints, inclusive) or any iterable of ints, read once; a frame given twice is rendered once.

One run at a time writes into a folder: a run locks ``DIR/.glint-farm.lock`` (a POSIX file
lock, released when the run ends or its process dies), and a second run raises
``FolderInUseError`` naming the lock file and the holder's pid. On starting, a run removes the
temporary files (``*.partial-PID.*``) that runs whose process is gone left behind.

The client writes ``DIR/<scene>_<frame>.exr``, ``.png`` and ``.json`` (the frame's summary)
atomically: each to a temporary file, then renamed, the JSON last, recording the size and
SHA-256 of the EXR and PNG. A frame is skipped as done when its JSON records the same scene
(SHA-256 of the scene file and its assets), resolution, samples and glint version, and the
EXR and PNG beside it are the files it records; so an interrupted run continues where it
stopped; ``--overwrite`` renders it again.

Every task hashes the scene file and its assets before and after rendering its tile; a tile
rendered from files other than the ones the run started with stops the run with
``SceneChangedError`` before its frame is written. Every frame's camera is checked before any
is rendered, as ``cargo xtask render --frames`` does. A tile glint refuses (a ``ValueError``
of the scene, an asset, the camera) is not retried: it would fail the same on any worker, and
the run stops with glint's message alone. Tasks that raise otherwise are retried
(``retries``); tasks on a worker that dies are run again on another (Dask's own
rescheduling). Each option is given at most once; an unreachable ``--scheduler`` fails after
``--connect-timeout`` seconds; Ctrl-C stops the run with status 130, its workers quietly.
Workers need the ``glint`` package (install the same wheel everywhere) and must see the scene
file and its assets at the same path (a shared file system). See ``docs/farm.md`` in the
repository for clusters (Slurm through dask-jobqueue).

From Python: ``glint.farm.render_frames(scene, frames, out, ...)`` returns the paths written.
"""

import argparse
import asyncio
import collections
import errno
import gc
import hashlib
import itertools
import json
import math
import os
import re
import signal
import socket
import sys
import threading
import time
import uuid

import numpy as np

from . import __version__, _glint
from ._render import render, write_exr, write_png

try:
    import fcntl
except ImportError:  # not POSIX (Windows): the lock falls back to a file with the holder's pid
    fcntl = None

try:
    import tomllib
except ImportError:  # Python < 3.11
    try:
        import tomli as tomllib
    except ImportError:
        tomllib = None

#: The most frames one run renders, as ``cargo xtask render --frames``.
MAX_FRAMES = 100_000

#: The largest frame number, either sign: frames reach the camera as doubles, exact to 2⁵³.
MAX_FRAME_NUMBER = 2**53

#: The most samples per pixel: the tracer's sampler's limit (``MAX_SAMPLES_PER_PIXEL`` in
#: ``crates/tracer/src/sampler.rs``, the Sobol sequence's length).
MAX_SPP = 1 << 16

#: The largest image width or height, the tracer's.
MAX_SIDE = 16384

#: The most render threads per task, as ``glint.render`` (glint's limit for every pool).
MAX_THREADS = _glint.MAX_THREADS

#: The most worker processes of a local cluster (one machine).
MAX_LOCAL_WORKERS = 1024

#: The lock file a run holds in its output folder.
LOCK_NAME = ".glint-farm.lock"

#: The summary fields summed over a frame's tiles.
_SUMMED = ("seconds", "rays", "clamped_samples", "discarded_samples")

#: A temporary output of a run: ``<name>.partial-<pid>.<extension>`` (``_atomic``).
_PARTIAL = re.compile(r"\.partial-(\d+)\.(exr|png|json)$")


class FolderInUseError(OSError):
    """Another farm run holds the output folder's lock: two runs never write one folder."""


class SceneChangedError(RuntimeError):
    """A tile was rendered from scene files other than the ones its run started with."""


def tiles(width, height, size):
    """The (x0, x1, y0, y1) tiles of side ``size`` covering a width × height image, row by row."""
    if size < 1:
        raise ValueError(f"the tile size must be at least 1 pixel, not {size}")
    return [(x0, min(x0 + size, width), y0, min(y0 + size, height))
            for y0 in range(0, height, size) for x0 in range(0, width, size)]


class TileError:
    """What a task returns instead of raising when glint refuses its tile (a ``ValueError`` of
    ``glint.render``: the scene, an asset, the camera at the frame): such an error is a function
    of the input and would be the same on any worker, so it is never retried, and the client
    raises it as a ``ValueError`` with glint's message alone (no worker traceback)."""

    def __init__(self, message):
        self.message = message


def render_tile(scene, frame, bounds, resolution, spp, threads, sources=None):
    """One task: the tile ``bounds`` of ``frame``.

    Returns (bounds, float32 image, stats, before, after): ``before`` is the ``sources_sha256``
    of ``sources`` (the files the client's run started with) taken before rendering, ``after``
    that of the files the render read (``stats["sources"]``) taken after it. Both equal the
    run's only if the files were the same throughout, unless they changed and changed back
    in between. A tile glint refuses returns a ``TileError`` instead (never retried).
    """
    before = None if sources is None else sources_sha256(sources)
    try:
        result = render(scene, frame=frame, pixel_bounds=bounds, resolution=resolution, spp=spp,
                        threads=threads)
    except ValueError as error:
        return TileError(str(error))
    after = sources_sha256(result["stats"]["sources"])
    return bounds, result["image"], result["stats"], before, after


def _file_record(path):
    """The size and SHA-256 of a file, as a frame's JSON records its EXR and PNG."""
    digest = hashlib.sha256()
    size = 0
    with open(path, "rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
            size += len(block)
    return {"bytes": size, "sha256": digest.hexdigest()}


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
    """Runs ``write(temporary)``, renames the temporary file to ``path`` and returns its size
    and SHA-256 (``_file_record``)."""
    root, extension = os.path.splitext(path)
    temporary = f"{root}.partial-{os.getpid()}{extension}"
    try:
        write(temporary)
        record = _file_record(temporary)
        os.replace(temporary, path)
        return record
    finally:
        if os.path.exists(temporary):
            os.remove(temporary)


def _outputs(out, stem, frame):
    base = os.path.join(out, f"{stem}_{frame:04d}")
    return base + ".exr", base + ".png", base + ".json"


def _is_done(paths, identity):
    """Whether a frame's outputs are complete: its JSON is an object whose ``farm`` records
    ``identity`` and the size and SHA-256 of the EXR and PNG, and those files match them."""
    try:
        with open(paths[2], encoding="utf-8") as file:
            summary = json.load(file)
    except (OSError, ValueError, RecursionError):
        return False
    farm = summary.get("farm") if isinstance(summary, dict) else None
    if not isinstance(farm, dict) or farm.get("identity") != identity:
        return False
    outputs = farm.get("outputs")
    if not isinstance(outputs, dict):
        return False
    records = [(path, outputs.get(key)) for path, key in zip(paths, ("exr", "png"))]
    try:
        # Sizes first: a truncated file is told apart without reading anything.
        if not all(isinstance(r, dict) and os.path.getsize(p) == r.get("bytes")
                   for p, r in records):
            return False
        return all(_file_record(p)["sha256"] == r.get("sha256") for p, r in records)
    except OSError:
        return False


def _pid_alive(pid):
    """Whether a process ``pid`` exists on this machine."""
    import psutil  # a dependency of distributed
    return psutil.pid_exists(pid)


class _FolderLock:
    """The output folder's lock, held for a whole run (a context manager).

    Where the platform has POSIX file locks (``fcntl.flock``), the lock is ``flock`` on
    ``LOCK_NAME``: the operating system releases it when the holder exits or is killed, so a
    lock file left by a dead run is simply taken; the file records the holder's pid and host
    for the error a second run raises. Elsewhere the file is created exclusively, and one
    whose holder on this host is gone is taken over.
    """

    def __init__(self, folder):
        self.path = os.path.join(folder, LOCK_NAME)
        self.descriptor = None

    def _holder(self):
        try:
            with open(self.path, encoding="utf-8", errors="replace") as file:
                pid, _, host = file.read().strip().partition(" ")
            return int(pid), host
        except (OSError, ValueError):
            return None, ""

    def _busy(self):
        pid, host = self._holder()
        holder = "an unknown process" if pid is None else f"pid {pid}" + (
            f" on {host}" if host else "")
        return FolderInUseError(
            f"another farm run ({holder}) is writing into {os.path.dirname(self.path)}: it holds "
            f"the lock {self.path}; wait for it to end or use another output folder")

    def _lock_posix(self):
        while True:
            descriptor = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as error:
                os.close(descriptor)
                if error.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.EACCES):
                    raise self._busy() from None
                raise OSError(f"cannot lock {self.path}: {error}") from error
            # A run that ends removes the file (holding the lock): locked, it must still be
            # the file at the path, or another run may lock a new one there.
            try:
                current = os.stat(self.path).st_ino == os.fstat(descriptor).st_ino
            except FileNotFoundError:
                current = False
            if current:
                return descriptor
            os.close(descriptor)

    def _lock_exclusive(self):
        while True:
            try:
                return os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                pid, host = self._holder()
                if pid is None or host != socket.gethostname() or _pid_alive(pid):
                    raise self._busy() from None
                os.remove(self.path)  # its holder is gone: take it over

    def __enter__(self):
        descriptor = self._lock_posix() if fcntl is not None else self._lock_exclusive()
        os.ftruncate(descriptor, 0)
        os.write(descriptor, f"{os.getpid()} {socket.gethostname()}\n".encode())
        self.descriptor = descriptor
        return self

    def __exit__(self, *exception):
        try:
            os.remove(self.path)
        except OSError:
            pass
        os.close(self.descriptor)
        self.descriptor = None


def _remove_dead_partials(out):
    """Removes the temporary outputs (``*.partial-PID.*``) that runs no longer alive left in
    ``out``; returns how many."""
    removed = 0
    for name in os.listdir(out):
        match = _PARTIAL.search(name)
        if match and int(match[1]) != os.getpid() and not _pid_alive(int(match[1])):
            try:
                os.remove(os.path.join(out, name))
                removed += 1
            except FileNotFoundError:
                pass
    return removed


def _integer(name, value, low, high=None):
    """``value`` as an int in [low, high] (``high`` None: no upper limit): a ``TypeError``
    naming ``name`` if it is not an integer (``bool`` is not), a ``ValueError`` if outside."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, not {value!r}")
    value = int(value)
    if value < low or (high is not None and value > high):
        limits = f"at least {low}" if high is None else f"in {low}..={high}"
        raise ValueError(f"{name} must be {limits}, not {value}")
    return value


def _frame_list(frames):
    """The frames a run renders, in order, each once.

    ``frames`` is ``(first, last)``, a tuple of two ints (first..last inclusive; a reversed
    pair is an error), or any other iterable of ints (a list, a range, a generator), read once;
    a frame listed twice is kept where it first appears. At most ``MAX_FRAMES`` frames (as
    given), each within ±``MAX_FRAME_NUMBER``.
    """
    def frame(name, value):
        return _integer(name, value, -MAX_FRAME_NUMBER, MAX_FRAME_NUMBER)

    if isinstance(frames, tuple) and len(frames) == 2:
        first, last = frame("frames[0] (the first frame)", frames[0]), frame(
            "frames[1] (the last frame)", frames[1])
        if last < first:
            raise ValueError(f"frames = ({first}, {last}): the last frame comes before the first "
                             "(a pair is first..last inclusive; list the frames to go backwards)")
        if last - first + 1 > MAX_FRAMES:
            raise ValueError(f"frames = ({first}, {last}): {last - first + 1} frames, more than "
                             f"the limit of {MAX_FRAMES} per run (as cargo xtask render "
                             "--frames; split the range)")
        return list(range(first, last + 1))
    if isinstance(frames, (str, bytes, bytearray, dict)):
        raise TypeError(f"frames must be (first, last) or an iterable of ints, not {frames!r}")
    try:
        iterator = iter(frames)
    except TypeError:
        raise TypeError(f"frames must be (first, last) or an iterable of ints, not {frames!r}"
                        ) from None
    given = list(itertools.islice(iterator, MAX_FRAMES + 1))
    if len(given) > MAX_FRAMES:
        raise ValueError(f"frames: more than the limit of {MAX_FRAMES} frames per run (as cargo "
                         "xtask render --frames; split them)")
    return list(dict.fromkeys(frame(f"frames[{i}]", f) for i, f in enumerate(given)))


def _scene_pixel_bounds(scene):
    """The scene file's ``[render] pixel_bounds``, or None (also when it cannot be read here:
    Python < 3.11 without ``tomli``)."""
    if tomllib is None:
        return None
    try:
        with open(scene, "rb") as file:
            settings = tomllib.load(file).get("render")
    except (OSError, ValueError):
        return None  # the probe render reported any problem of the file already
    return settings.get("pixel_bounds") if isinstance(settings, dict) else None


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


def _glint_sums(stats):
    """The glint counters behind a summary's per-query means: queries, negligible queries and
    their bound, nodes visited, nodes overlapping and particles found (summed over queries)."""
    queries, negligible = stats["glint_queries"], stats["negligible_queries"]
    traversed = max(1, queries - negligible)
    return [queries, negligible, stats["negligible_bound"],
            round(stats["nodes_per_query"] * traversed),
            round(stats["overlapping_nodes_per_query"] * traversed),
            stats["particles_per_query"] * max(1, queries)]


def _glint_means(sums):
    """A summary's glint statistics from summed counters (``_glint_sums``), as the tracer
    computes them: nodes per traversed query, particles per query."""
    queries, negligible, bound, nodes, overlapping, particles = sums
    traversed = max(1, queries - negligible)
    return {"glint_queries": queries, "negligible_queries": negligible,
            "negligible_bound": bound, "nodes_per_query": nodes / traversed,
            "overlapping_nodes_per_query": overlapping / traversed,
            "particles_per_query": particles / max(1, queries)}


def _merged_glint(parts):
    """The glint statistics of a frame from its tiles' (``parts``, in frame order): totals
    and per material, with the per-query means of the summed counters. The node counts are
    exact, so nodes per query equal the whole frame's; particles per query agree to rounding."""
    def total(sums):
        return [sum(column) for column in zip(*sums)]

    merged = _glint_means(total(_glint_sums(p) for p in parts))
    merged.update(_merged_histogram(parts))
    if not all("materials" in p for p in parts):
        return merged
    # Materials in the tiles' order: each name after the one before it in the tile that has it.
    names, by_name = [], collections.defaultdict(list)
    for part in parts:
        place = 0
        for material in part["materials"]:
            if material["name"] in by_name:
                place = names.index(material["name"]) + 1
            else:
                names.insert(place, material["name"])
                place += 1
            by_name[material["name"]].append(_glint_sums(material))
    merged["materials"] = [
        {"name": name, **_glint_means(total(by_name[name])),
         **_merged_histogram([m for p in parts for m in p["materials"] if m["name"] == name])}
        for name in names]
    return merged


def _merged_histogram(parts):
    """The particles-per-query histogram of summaries ``parts`` (each's
    ``particles_histogram``, pairs of a bin's upper edge and its queries), summed bin by bin,
    with its 99th-percentile bound computed as the tracer computes it: the upper edge of the
    bin where the cumulative share reaches 0.99. Empty when a part has no histogram."""
    if not all("particles_histogram" in p for p in parts):
        return {}
    bins = collections.Counter()
    for part in parts:
        for edge, queries in part["particles_histogram"]:
            bins[edge] += queries
    pairs = sorted(bins.items())
    total, below, p99 = sum(bins.values()), 0, 0.0
    for edge, queries in pairs:
        below += queries
        if below >= 0.99 * total:
            p99 = edge
            break
    return {"particles_histogram": [list(pair) for pair in pairs],
            "particles_per_query_p99": p99}


def _frame_summary(frame, parts, identity, resolution, workers, outputs):
    """One frame's summary from its tiles' stats (``parts``, in frame order): the first tile's
    settings, sums of counts, merged glint statistics, and the farm's record (``identity``,
    the EXR's and PNG's sizes and SHA-256 in ``outputs``)."""
    first = parts[0]
    summary = {key: first[key] for key in (
        "scene", "sources", "frame", "resolution", "spp", "smooth", "glint_footprints", "exposure",
        "bloom", "expected_footprint_areas", "particles_per_square") if key in first}
    summary["pixel_bounds"] = [0, resolution[0], 0, resolution[1]]
    for key in _SUMMED:
        summary[key] = sum(p[key] for p in parts)
    summary.update(_merged_glint(parts))
    summary["tiles"] = len(parts)
    summary["farm"] = {"identity": identity, "workers": workers, "outputs": outputs}
    return summary


def _checked_arguments(scene, frames, out, tile, spp, resolution, client, scheduler, workers,
                       threads, retries, frames_in_flight, worker_timeout, on_tile,
                       connect_timeout=5.0):
    """``render_frames``'s arguments checked and normalised; raises before anything starts."""
    def path(name, value):
        try:
            text = os.fspath(value)
        except TypeError:
            text = None
        if not isinstance(text, str):
            raise TypeError(f"{name} must be a path (str or os.PathLike), not {value!r}")
        return text

    scene = os.path.abspath(path("scene", scene))
    out = path("out", out)
    frames = _frame_list(frames)
    tile = _integer("tile", tile, 1)
    spp = None if spp is None else _integer("spp", spp, 1, MAX_SPP)
    if resolution is not None:
        if isinstance(resolution, (str, bytes)) or not hasattr(resolution, "__len__") or len(
                resolution) != 2:
            raise TypeError(f"resolution must be (width, height), not {resolution!r}")
        resolution = tuple(_integer(f"resolution[{i}]", v, 1, MAX_SIDE)
                           for i, v in enumerate(resolution))
    given = [name for name, value in (("client", client), ("scheduler", scheduler),
                                      ("workers", workers)) if value is not None]
    if len(given) > 1:
        raise ValueError(f"give at most one of client, scheduler and workers, not "
                         f"{' and '.join(given)}")
    if scheduler is not None and not isinstance(scheduler, str):
        raise TypeError(f"scheduler must be an address (str), not {scheduler!r}")
    workers = None if workers is None else _integer("workers", workers, 1, MAX_LOCAL_WORKERS)
    threads = None if threads is None else _integer("threads", threads, 1, MAX_THREADS)
    retries = _integer("retries", retries, 0)
    if frames_in_flight is not None:
        frames_in_flight = _integer("frames_in_flight", frames_in_flight, 1)
    if worker_timeout is not None:
        if isinstance(worker_timeout, (bool, np.bool_)) or not isinstance(
                worker_timeout, (int, float, np.integer, np.floating)):
            raise TypeError(f"worker_timeout must be seconds (a number) or None, not "
                            f"{worker_timeout!r}")
        if not (math.isfinite(worker_timeout) and worker_timeout > 0):
            raise ValueError(f"worker_timeout must be a positive number of seconds or None, "
                             f"not {worker_timeout}")
        worker_timeout = float(worker_timeout)
    if on_tile is not None and not callable(on_tile):
        raise TypeError(f"on_tile must be callable or None, not {on_tile!r}")
    if connect_timeout is not None:
        if isinstance(connect_timeout, (bool, np.bool_)) or not isinstance(
                connect_timeout, (int, float, np.integer, np.floating)):
            raise TypeError(f"connect_timeout must be seconds (a number), not "
                            f"{connect_timeout!r}")
        if not (math.isfinite(connect_timeout) and connect_timeout > 0):
            raise ValueError(f"connect_timeout must be a positive number of seconds, not "
                             f"{connect_timeout}")
        connect_timeout = float(connect_timeout)
    if not os.path.isfile(scene):
        raise FileNotFoundError(f"scene file {scene!r} does not exist")
    if os.path.exists(out) and not os.path.isdir(out):
        raise NotADirectoryError(f"out {out!r} is a file, not a folder: the frames are written "
                                 "into a folder (give a folder's path, new or existing)")
    return (scene, frames, out, tile, spp, resolution, workers, threads, retries,
            frames_in_flight, worker_timeout, connect_timeout)


def render_frames(scene, frames, out, *, tile=64, spp=None, resolution=None, client=None,
                  scheduler=None, workers=None, threads=None, overwrite=False, retries=3,
                  frames_in_flight=None, worker_timeout=60.0, progress=True, on_tile=None,
                  connect_timeout=5.0):
    """Renders frames of a scene file on a Dask cluster, tile by tile, into a folder.

    Parameters
    ----------
    scene : str or os.PathLike
        The scene file (TOML). It must not set ``[render] pixel_bounds``: the farm renders
        whole frames.
    frames : tuple of two ints or iterable of ints
        ``(first, last)``: frames first..last inclusive (``first <= last``). Any other
        iterable (a list, a range, a generator) lists the frames, read once; a frame listed
        twice is rendered once, where it first appears. At most ``MAX_FRAMES`` frames, each
        within ±2⁵³.
    out : str or os.PathLike
        The output folder (created if missing); one run at a time writes into it.
    tile : int
        Tile side in pixels, at least 1.
    spp : int, optional
        Samples per pixel, 1..=65536 (default: the scene's).
    resolution : (int, int), optional
        (width, height), each 1..=16384 (default: the scene's).
    client : distributed.Client, optional
        The cluster to use, left open.
    scheduler : str, optional
        The address of a running Dask scheduler, e.g. ``"tcp://10.0.0.1:8786"``.
    workers : int, optional
        A ``LocalCluster`` of this many worker processes (1..=1024), closed at the end. The
        default when none of ``client``, ``scheduler`` and ``workers`` is given: 2. At most
        one of the three may be given.
    threads : int, optional
        Each task's render threads, 1..=1024 (``MAX_THREADS``; default: the machine's cores
        shared among a local cluster's workers; all of a remote worker's cores).
    overwrite : bool
        Render frames that are done too.
    retries : int
        How often a task that raises is run again, at least 0. A tile glint refuses (the
        scene, an asset, the camera at its frame) is never retried: the error is the same on
        any worker.
    frames_in_flight : int, optional
        The most frames rendered at once, at least 1 (default: twice the workers, at least 2):
        the client holds that many frame buffers whatever the length of the animation.
    worker_timeout : float or None
        Seconds to wait for the cluster's first worker before raising ``TimeoutError``;
        None waits as long as it takes (a batch queue's workers may start hours later).
    connect_timeout : float
        Seconds to try to reach ``scheduler`` before raising ``OSError`` (5).
    progress : bool
        Print progress to stderr.
    on_tile : callable, optional
        ``on_tile(frame, bounds)``, called on the client as each tile arrives.

    Returns
    -------
    list of str
        The EXR, PNG and JSON paths of every frame written; frames already done are skipped
        and not listed.

    Raises
    ------
    TypeError, ValueError
        An argument of the wrong type or out of range, named; a scene with ``pixel_bounds``;
        a scheduler address that cannot be parsed; a camera degenerate at one of the frames
        (every frame is checked before any is rendered, as ``cargo xtask render --frames``
        does); a tile glint refuses. Raised before anything starts, but for the last.
    NotADirectoryError
        ``out`` is a file.
    FileNotFoundError
        The scene file does not exist.
    FolderInUseError
        Another run holds ``out``'s lock.
    TimeoutError
        No worker joined the cluster within ``worker_timeout`` seconds.
    OSError
        The scheduler cannot be reached, or an output cannot be written.
    SceneChangedError
        The scene file or an asset changed during the run; the frames written so far are
        complete, and a new run renders the rest from the files as they are then.
    """
    from dask.distributed import Client, LocalCluster

    (scene, frames, out, tile, spp, resolution, workers, threads, retries, frames_in_flight,
     worker_timeout, connect_timeout) = _checked_arguments(
        scene, frames, out, tile, spp, resolution, client, scheduler, workers, threads, retries,
        frames_in_flight, worker_timeout, on_tile, connect_timeout)
    if not frames:
        return []
    # The camera at every frame, before anything is created or rendered (as cargo xtask render
    # --frames): keyframes valid alone may pass through a degenerate pose between them.
    _glint.check_camera_frames(scene, frames, resolution, spp)
    os.makedirs(out, exist_ok=True)
    with _FolderLock(out):
        removed = _remove_dead_partials(out)
        if removed and progress:
            print(f"removed {removed} temporary file(s) of runs that ended without finishing",
                  file=sys.stderr)
        # The frame size (and a check of the scene and the options) from a one-pixel render.
        probe = render(scene, frame=frames[0], pixel_bounds=(0, 1, 0, 1),
                       resolution=resolution, spp=spp, threads=1)["stats"]
        bounds = _scene_pixel_bounds(scene)
        if bounds is not None:
            raise ValueError(
                f"scene file {scene!r} sets [render] pixel_bounds = {bounds}: the farm renders "
                "whole frames (remove the setting, or render the crop with cargo xtask render)")
        width, height = probe["resolution"]
        identity = {"sources_sha256": sources_sha256(probe["sources"]),
                    "resolution": [width, height], "spp": probe["spp"], "glint": __version__}
        stem = os.path.splitext(os.path.basename(scene))[0]
        todo = [f for f in frames if overwrite or not _is_done(_outputs(out, stem, f), identity)]
        if progress:
            pending = set(todo)
            for f in frames:
                if f not in pending:
                    print(f"frame {f}: done already ({_outputs(out, stem, f)[0]}), skipped",
                          file=sys.stderr)
        if not todo:
            return []
        cluster = None
        own_client = client is None
        if own_client:
            if scheduler is not None:
                problem = None
                try:
                    client = Client(scheduler, timeout=connect_timeout)
                except ValueError as error:
                    problem = ValueError(f"scheduler {scheduler!r} is not a Dask scheduler "
                                         f"address (tcp://HOST:PORT): {error}")
                except (OSError, TimeoutError, asyncio.TimeoutError) as error:
                    problem = OSError(f"cannot reach the Dask scheduler at {scheduler!r} "
                                      f"within {connect_timeout:g} s (--connect-timeout): "
                                      f"{error}")
                if problem is not None:
                    # The Client that failed is left in reference cycles (its traceback's
                    # frames); collected at some later time, its __del__ can deadlock inside
                    # the start of another Client in this process (both take distributed's
                    # event-loop lock). Collected here, once the except block let it go.
                    gc.collect()
                    raise problem
            else:
                count = 2 if workers is None else workers
                if threads is None:
                    threads = max(1, (os.cpu_count() or 1) // count)
                # The workers start with Ctrl-C ignored (an ignored signal stays ignored
                # across exec, and Python then installs no KeyboardInterrupt handler): a
                # terminal's Ctrl-C reaches the whole process group, and only this process
                # should answer it, without a traceback from every worker.
                ignoring = threading.current_thread() is threading.main_thread()
                previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if ignoring else None
                try:
                    cluster = LocalCluster(n_workers=count, threads_per_worker=1,
                                           processes=True, dashboard_address=None)
                finally:
                    if ignoring:
                        signal.signal(signal.SIGINT, previous)
                client = Client(cluster)
        try:
            return _render_on(client, scene, stem, todo, out, (width, height), identity,
                              probe["sources"], tile, threads, retries, frames_in_flight,
                              worker_timeout, progress, on_tile)
        finally:
            if own_client:
                client.close()
            if cluster is not None:
                cluster.close()


def _render_on(client, scene, stem, todo, out, resolution, identity, sources, tile, threads,
               retries, frames_in_flight, worker_timeout, progress, on_tile):
    """Renders frames ``todo`` on ``client``'s cluster and writes them (``render_frames``)."""
    from dask.distributed import as_completed

    try:
        client.wait_for_workers(1, timeout=worker_timeout)
    except (TimeoutError, asyncio.TimeoutError):
        raise TimeoutError(
            f"no Dask worker joined the scheduler at {client.scheduler.address} within "
            f"{worker_timeout:g} s (worker_timeout): start workers, or wait longer") from None
    width, height = resolution
    samples = identity["spp"]
    boxes = tiles(width, height, tile)
    worker_count = len(client.scheduler_info()["workers"])
    # Frames in flight at once: enough to keep every worker busy across a frame's last tiles,
    # few enough that the merge buffers (one image per frame) stay bounded.
    window = max(2, 2 * worker_count) if frames_in_flight is None else frames_in_flight
    waiting = collections.deque(todo)
    futures = {}
    pending = as_completed()
    images, parts = {}, {}

    def submit_next_frame():
        f = waiting.popleft()
        for bounds in boxes:
            key = f"glint-tile-{stem}-{f}-{bounds[0]}-{bounds[2]}-{uuid.uuid4().hex}"
            future = client.submit(render_tile, scene, f, bounds, resolution, samples, threads,
                                   sources, retries=retries, pure=False, key=key)
            futures[future] = f
            pending.add(future)
        images[f] = np.zeros((height, width, 3), dtype=np.float32)
        parts[f] = []

    try:
        while waiting and len(images) < window:
            submit_next_frame()
        meter = _Progress(len(boxes) * len(todo), len(todo), progress)
        written = []
        for future in pending:
            f = futures.pop(future)
            result = future.result()
            if isinstance(result, TileError):
                raise ValueError(f"frame {f}: {result.message}")
            (x0, x1, y0, y1), image, stats, before, after = result
            if not (before == after == identity["sources_sha256"]) or stats.get(
                    "resolution") != [width, height] or stats.get("spp") != samples:
                raise SceneChangedError(
                    f"the scene changed during the run: tile {(x0, x1, y0, y1)} of frame {f} was "
                    f"rendered from files whose SHA-256 is {after} (before the render: {before}), "
                    f"not the run's {identity['sources_sha256']} ({', '.join(sources)}); frames "
                    "written so far are complete, run again to render the rest")
            images[f][y0:y1, x0:x1] = image
            parts[f].append(((y0, x0), stats))
            meter.tile()
            if on_tile is not None:
                on_tile(f, (x0, x1, y0, y1))
            if len(parts[f]) < len(boxes):
                continue
            paths = _outputs(out, stem, f)
            frame_parts = [stats for _, stats in sorted(parts.pop(f), key=lambda p: p[0])]
            frame_image = images.pop(f)
            outputs = {
                "exr": _atomic(paths[0], lambda p, im=frame_image: write_exr(p, im)),
                "png": _atomic(paths[1], lambda p, im=frame_image, s=frame_parts[0]: write_png(
                    p, im, s.get("exposure", 0.0), s.get("bloom")))}
            summary = _frame_summary(f, frame_parts, identity, resolution, worker_count, outputs)

            def write_json(p, s=summary):
                with open(p, "w", encoding="utf-8") as file:
                    json.dump(s, file, indent=2)
                    file.write("\n")

            _atomic(paths[2], write_json)
            written.extend(paths)
            meter.frame(os.path.basename(paths[0]))
            if waiting:
                submit_next_frame()
        return written
    finally:
        if futures:
            client.cancel(list(futures))


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


class _Once(argparse.Action):
    """An option that may be given once: a second ``--frames`` (or any option) is an error,
    not a silent override of the first."""

    def __init__(self, option_strings, dest, flag=False, **kwargs):
        if flag:
            kwargs.update(nargs=0, default=False)
        self.flag = flag
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given", set())
        if self.dest in given:
            parser.error(f"{option_string} is given twice: give each option once")
        given.add(self.dest)
        setattr(namespace, self.dest, True if self.flag else values)


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m glint.farm",
        description="Render frames of a glint scene file on a Dask cluster, tile by tile.")
    parser.register("action", "once", _Once)
    parser.add_argument("scene", help="the scene file (TOML, scenes/README.md)")
    parser.add_argument("--frames", action="once", type=_frames, default=(0, 0), metavar="A..B",
                        help="camera frames A to B inclusive (default 0..0)")
    parser.add_argument("--out", action="once", required=True,
                        help="output folder (one run at a time writes into it)")
    parser.add_argument("--tile", action="once", type=int, default=64,
                        help="tile side in pixels (64)")
    parser.add_argument("--spp", action="once", type=int,
                        help=f"samples per pixel, 1..={MAX_SPP} (default: the scene's)")
    parser.add_argument("--resolution", action="once", type=_resolution, metavar="WxH",
                        help="image size (default: the scene's)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--scheduler", action="once", metavar="ADDRESS",
                       help="a running Dask scheduler, e.g. tcp://10.0.0.1:8786")
    where.add_argument("--workers", action="once", type=int, metavar="K",
                       help="a local cluster of K worker processes (default 2)")
    parser.add_argument("--threads", action="once", type=int,
                        help=f"render threads per task, 1..={MAX_THREADS} (default: cores / "
                             "local workers)")
    parser.add_argument("--retries", action="once", type=int, default=3,
                        help="retries of a failed task (3; a tile glint refuses is never "
                             "retried)")
    parser.add_argument("--worker-timeout", action="once", type=float, default=60.0,
                        metavar="SECONDS",
                        help="how long to wait for the cluster's first worker (60)")
    parser.add_argument("--connect-timeout", action="once", type=float, default=5.0,
                        metavar="SECONDS", help="how long to try to reach --scheduler (5)")
    parser.add_argument("--overwrite", action="once", flag=True,
                        help="render frames whose outputs exist too")
    parser.add_argument("--quiet", action="once", flag=True, help="no progress")
    args = parser.parse_args(argv)
    try:
        written = render_frames(args.scene, args.frames, args.out, tile=args.tile, spp=args.spp,
                                resolution=args.resolution, scheduler=args.scheduler,
                                workers=args.workers, threads=args.threads,
                                overwrite=args.overwrite, retries=args.retries,
                                worker_timeout=args.worker_timeout,
                                connect_timeout=args.connect_timeout, progress=not args.quiet)
    except KeyboardInterrupt:
        print("\ninterrupted: frames written so far are kept; run again to render the rest",
              file=sys.stderr)
        return 130
    except (ValueError, TypeError, OSError, SceneChangedError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"{len(written) // 3} frame(s) written to {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
