"""Rendering scene files: ``glint.render``, ``glint.write_exr`` and ``glint.write_png``; and
``glint.read_map_image``, which reads a map image as the tracer does.

These run glint-tracer's render job, the one ``cargo xtask render`` runs, so a frame (or a
crop of one, ``pixel_bounds``) rendered here is bit for bit the command line's. Scene files
are documented in ``scenes/README.md`` of the repository.
"""

import json
import math
import os

import numpy as np

from . import _glint


def _whole(name, value, low, high):
    """``value`` as an int in [low, high], or a ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be a whole number, not {value!r}")
    value = int(value)
    if not low <= value <= high:
        raise ValueError(f"{name} = {value} is outside [{low}, {high}]")
    return value


def render(scene, *, frame=None, pixel_bounds=None, resolution=None, spp=None, threads=None,
           smooth=False):
    """Renders camera frame ``frame`` (default 0) of the scene file ``scene``.

    ``pixel_bounds=(x0, x1, y0, y1)`` renders only columns x0..x1 and rows y0..y1 (half-open,
    row 0 at the top), exactly the full image's pixels there. ``resolution=(width, height)``,
    ``spp`` and ``smooth`` (every glint material replaced by its smooth limit) override the
    scene's settings as ``cargo xtask render``'s options do; ``threads`` defaults to every core.

    Returns a dict: ``"image"``, a float32 array of shape (height, width, 3) of linear radiance
    over the bounds, and ``"stats"``, the render's summary (what ``cargo xtask render`` writes
    to its JSON file: settings, ``pixel_bounds``, Table 1 statistics, seconds).

    The GIL is released while rendering; Ctrl-C stops the render with ``KeyboardInterrupt``.
    Errors raise ``ValueError`` with the tracer's message (file, field and problem), and
    ``FileNotFoundError`` when the scene file does not exist.
    """
    path = os.fspath(scene)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"scene file {path!r} does not exist")
    frame = 0 if frame is None else _whole("frame", frame, -2**53, 2**53)
    if pixel_bounds is not None:
        if len(pixel_bounds) != 4:
            raise ValueError(f"pixel_bounds must be (x0, x1, y0, y1), not {pixel_bounds!r}")
        pixel_bounds = [_whole("pixel_bounds", v, 0, 2**32 - 1) for v in pixel_bounds]
    if resolution is not None:
        if len(resolution) != 2:
            raise ValueError(f"resolution must be (width, height), not {resolution!r}")
        resolution = tuple(_whole("resolution", v, 1, 16384) for v in resolution)
    if spp is not None:
        # glint-tracer's MAX_SAMPLES_PER_PIXEL (the Sobol sequence's length).
        spp = _whole("spp", spp, 1, 2**16)
    if threads is not None:
        threads = _whole("threads", threads, 1, _glint.MAX_THREADS)
    image, stats = _glint.render_scene(path, frame, pixel_bounds, resolution, spp, threads,
                                       bool(smooth))
    return {"image": image, "stats": json.loads(stats)}


def _image(image):
    array = np.ascontiguousarray(np.asarray(image, dtype=np.float32))
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError(f"image must have shape (height, width, 3), not {np.shape(image)}")
    return array


def write_exr(path, image):
    """Writes ``image`` (height, width, 3) as the tracer writes its linear 32-bit float EXR:
    the same pixels give the same bytes. Non-finite pixels raise ``ValueError``."""
    _glint.write_exr(os.fspath(path), _image(image))


def write_png(path, image, exposure=0.0, bloom=None):
    """Writes ``image`` (height, width, 3) as the tracer writes its PNG: ``bloom`` if given (a
    dict with ``threshold``, ``radius``, ``strength``, as a render's ``stats["bloom"]``), then
    exposure 2^``exposure``, clamped, sRGB-encoded to 8 bits."""
    if bloom is not None:
        try:
            bloom = (float(bloom["threshold"]), float(bloom["radius"]), float(bloom["strength"]))
        except (KeyError, TypeError) as error:
            raise ValueError(
                f"bloom must be a dict with threshold, radius and strength, not {bloom!r}"
            ) from error
    exposure = float(exposure)
    if not math.isfinite(exposure):
        raise ValueError(f"exposure must be finite, not {exposure}")
    _glint.write_png(os.fspath(path), _image(image), exposure, bloom)


def read_map_image(path, kind="data"):
    """Reads a map image as glint-tracer reads a scene file's ``density_texture``,
    ``alpha_texture`` and ``tint_texture``, under the tracer's limits.

    Parameters
    ----------
    path : str or os.PathLike
        A PNG or OpenEXR file. Its size is checked from its header against the tracer's limits
        (at most 16384 pixels wide and high, 2**26 pixels in all) before any pixel is decoded.
    kind : {"data", "colour"}
        ``"data"`` (density, roughness) reads a PNG's 8- and 16-bit values linearly, as k/255
        and k/65535; ``"colour"`` (a tint) decodes them from sRGB. EXR values are linear
        either way.

    Returns
    -------
    numpy.ndarray
        The texels, float64 of shape (height, width, 3), row 0 the image's top (a grey image
        has three equal channels).

    Raises
    ------
    ValueError
        With the tracer's message: an unknown format, a file or image beyond the limits, a
        damaged file, a texel that is not finite.
    """
    if kind not in ("data", "colour"):
        raise ValueError(f'kind must be "data" or "colour", not {kind!r}')
    return _glint.read_map_image(os.fspath(path), kind == "colour")
