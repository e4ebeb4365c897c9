"""The ``glint`` BSDF's maps in Mitsuba 3: ``density_map``, ``alpha_map`` and ``tint_map``
given as a Mitsuba ``bitmap`` texture or as an image filename, read into the NumPy maps
``glint.Material`` takes. Both plugins (``glint_mitsuba.py``, scalar; ``glint_vectorized.py``)
read them here, so a map gives the same ``glint.Material`` in every variant.

What is accepted, per parameter:

- a ``bitmap`` texture (``<texture type="bitmap" name="density_map">`` in XML,
  ``{"type": "bitmap", ...}`` in a dict): its texels as Mitsuba stores them
  (``mi.traverse(texture)["data"]``). Mitsuba 3.9 stores an 8-bit image as its 8-bit values
  k and decodes sRGB on lookup unless ``raw`` is true: glint reads k/255 and, for a tint,
  decodes sRGB as those lookups do (in double precision). Density and roughness are data,
  read linearly, so an 8-bit bitmap of them must be ``raw`` (refused otherwise: Mitsuba
  would decode it as a colour). Other bitmaps (OpenEXR, 16-bit images, ``format``
  ``variant`` or ``float16``) are read as stored: Mitsuba decoded sRGB sources to linear on
  loading unless ``raw``. The texture's ``to_uv`` must be the identity (``uv_scale`` scales
  the maps with the flakes, which share one texture square); its ``filter_type`` and
  ``wrap_mode`` do not apply: glint's maps tile, and the BSDF's ``map_filter`` says how the
  density and roughness are reconstructed between texels (each texel constant, ``nearest``,
  the default; or ``bilinear`` between the texels' centres, where Mitsuba's own bilinear
  lookups put the image's values; the tint is nearest).
  Mitsuba pads an image smaller than 2 × 2 to 2 × 2 by repeating its last row or column,
  which is the same map.
- a filename (a string): a PNG or OpenEXR image read by glint-tracer's own reader
  (``glint.read_map_image``), as it reads a scene file's ``density_texture``,
  ``alpha_texture`` and ``tint_texture`` and under its limits (the size checked from the
  file's header before any pixel is decoded, at most 16384 pixels wide and high and 2²⁶ in
  all; every texel finite): 8- and 16-bit values as k/255 and k/65535, floating-point ones as
  stored; density and roughness linearly, a PNG tint decoded from sRGB. A relative path is
  resolved as Mitsuba resolves a bitmap's filename (a scene file's folder first).

Anything else (another texture type such as ``checkerboard``, a constant ``rgb`` or float,
a ``mi.Bitmap``) is refused with a ``ValueError`` naming the parameter.

Channels: a density or roughness map has one channel: a grey image, or an RGB one whose
channels are equal in every texel (else ``ValueError`` naming the first texel where they
differ). A tint is RGB; a grey image is a grey tint. Alpha channels are ignored.

Placement: texels lie where Mitsuba's own bitmap lookups put them: image row 0 (its top) at
v ∈ [0, 1/H) and column 0 at u ∈ [0, 1/W) of glint's texture square (the shape's (u, v)
times ``uv_scale``), the map tiling with the square. glint's maps count row 0 from the top of
the texture square (v near 1), so the map ``glint.Material`` receives is the image's rows
bottom first (``np.flipud``). On a mesh from an OBJ file, whose v Mitsuba flips on loading,
an image then lies where glint-tracer puts the same image given as a scene file's texture.

Values: a density in [0, 1] (0 masks: no flake), a roughness in [1e-4, 1], a tint's channels
in [0, 1]; a texel out of range, or not finite, is a ``ValueError`` naming the parameter and
the texel (column, row), rows counted from the image's top, and values printed exactly.
"""

import re

import mitsuba as mi
import numpy as np

import glint

#: The maps, and whether each is data (one channel, read linearly) or a colour.
MAPS = {"density_map": "data", "alpha_map": "data", "tint_map": "colour"}
#: Names a user may reach for, and the parameter each one means.
MISNAMED = {"roughness_map": "alpha_map", "density_texture": "density_map",
            "alpha_texture": "alpha_map", "roughness_texture": "alpha_map",
            "tint_texture": "tint_map"}
#: Each map's range, as glint.Material checks it.
RANGES = {"density_map": (0.0, 1.0), "alpha_map": (1e-4, 1.0), "tint_map": (0.0, 1.0)}
#: What to give instead of a constant map.
_CONSTANT = {"density_map": "a constant density d is the material with d times the particles",
             "alpha_map": "a constant roughness is alpha",
             "tint_map": "a constant tint is a bitmap of one texel"}
#: The fields of a bitmap texture's to_string that glint reads: raw, and the file's name.
_RAW = re.compile(r"^\s*raw = (\d)", re.MULTILINE)
_NAME = re.compile(r'^\s*name = "(.*)",$', re.MULTILINE)


def srgb_to_linear(c):
    """The sRGB transfer function's inverse, in double precision (glint-tracer's)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def maps_from_properties(props):
    """The maps among Mitsuba ``props``: a dict of ``glint.Material`` keyword arguments
    (``density_map``, ``alpha_map``, ``tint_map``; those given), each a float64 NumPy array in
    glint's row order, and a dict of what each was read from (for ``to_string``). Raises
    ``ValueError`` naming the parameter for anything it cannot take."""
    for wrong, right in MISNAMED.items():
        if wrong in props:
            raise ValueError(f"glint.{wrong} is not a parameter of the glint BSDF: its map is "
                             f"{right} (a bitmap texture or an image filename)")
    maps, sources = {}, {}
    for name, kind in MAPS.items():
        if name not in props:
            continue
        texels, source = image_texels(name, props.get(name), kind)
        maps[name] = glint_map(name, texels, kind)
        sources[name] = f"<{source}, {texels.shape[1]} × {texels.shape[0]}>"
    if "density_map" in maps and "alpha_map" in maps:
        d, a = maps["density_map"].shape, maps["alpha_map"].shape
        if d != a:
            raise ValueError(f"glint.alpha_map is {a[1]} × {a[0]} texels and glint.density_map "
                             f"{d[1]} × {d[0]}: they must have the same size")
    return maps, sources


def image_texels(name, value, kind):
    """(texels, source): the texels of ``value`` (a bitmap texture or a filename) as float64,
    (H, W, C) in the image's row order (row 0 at the top), C = 1 or 3, and a short description
    of the source."""
    if isinstance(value, str):
        return _file_texels(name, value, kind), f"file {value!r}"
    if isinstance(value, mi.Texture):
        cls = value.class_name()
        if not cls.startswith("BitmapTexture"):
            raise ValueError(f"glint.{name} must be a bitmap texture or an image filename, "
                             f"not a {cls} texture")
        found = _NAME.search(str(value))
        return _bitmap_texels(name, value, kind), (
            f"bitmap {found.group(1)!r}" if found and found.group(1) else "bitmap")
    wanted = f"glint.{name} must be a bitmap texture or an image filename"
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if number or type(value).__name__.startswith("Color"):
        raise ValueError(f"{wanted}, not the constant {value!r}: {_CONSTANT[name]}")
    raise ValueError(f"{wanted}, not a {type(value).__name__}")


def _bitmap_texels(name, texture, kind):
    params = mi.traverse(texture)
    to_uv = np.array(params["to_uv"].matrix, dtype=np.float64)
    if not np.array_equal(to_uv, np.eye(3)):
        raise ValueError(f"glint.{name}: the bitmap's to_uv is not the identity: glint's maps "
                         "share the flakes' texture square; scale both with the BSDF's uv_scale")
    stored = np.array(params["data"])
    if stored.ndim != 3 or stored.shape[2] not in (1, 3):
        raise ValueError(f"glint.{name}: the bitmap's texels have shape {stored.shape}, not "
                         "(H, W, 1) or (H, W, 3)")
    if stored.dtype != np.uint8:
        return stored.astype(np.float64)
    texels = stored.astype(np.float64) / 255.0
    found = _RAW.search(str(texture))
    raw = found is not None and found.group(1) == "1"
    if raw:
        return texels
    if kind == "data":
        raise ValueError(f"glint.{name}: the bitmap is 8-bit and not raw, so Mitsuba decodes "
                         "it from sRGB as a colour; a density or roughness map is data, read "
                         "linearly: give the bitmap raw = true, or the image's filename")
    return srgb_to_linear(texels)


def _file_texels(name, filename, kind):
    path = mi.file_resolver().resolve(filename)
    try:
        texels = glint.read_map_image(str(path), "colour" if kind == "colour" else "data")
    except ValueError as error:
        raise ValueError(f"glint.{name}: cannot read the image {filename!r}: {error}") from None
    return texels


def shown(x):
    """A number for a message, as glint-tracer writes one: exactly (the shortest decimal that
    reads back as the same double: 1.0000001 is not 1), positional between 1e-4 and 1e6 and
    scientific beyond (1e300, not 301 digits)."""
    x = float(x)
    if x == 0.0 or not np.isfinite(x) or 1e-4 <= abs(x) < 1e6:
        text = repr(x)
        if text.endswith(".0"):
            text = text[:-2]
        return {"nan": "NaN", "inf": "inf", "-inf": "-inf"}.get(text, text)
    mantissa, exponent = np.format_float_scientific(x, unique=True, trim="-").split("e")
    return f"{mantissa}e{int(exponent)}"


def glint_map(name, texels, kind):
    """The map ``glint.Material`` takes from ``texels`` (H, W, C) in the image's row order:
    (H, W) for data, (H, W, 3) for a tint, rows bottom first; every texel checked, naming the
    parameter and the texel (column, row from the image's top)."""
    channels = texels.shape[2]
    infinite = ~np.isfinite(texels)
    if np.any(infinite):
        row, column = np.argwhere(infinite)[0][:2]
        raise ValueError(f"glint.{name}: texel (column {column}, row {row}) is not finite")
    if kind == "data":
        if channels == 3:
            differ = (texels[:, :, 0] != texels[:, :, 1]) | (texels[:, :, 1] != texels[:, :, 2])
            if np.any(differ):
                row, column = np.argwhere(differ)[0]
                c = ", ".join(shown(x) for x in texels[row, column])
                raise ValueError(f"glint.{name}: texel (column {column}, row {row}) has channels "
                                 f"({c}) that differ: the map is one channel of data (a grey "
                                 "image, or a colour one with equal channels)")
        values = texels[:, :, 0]
    else:
        values = np.repeat(texels, 3, axis=2) if channels == 1 else texels
    low, high = RANGES[name]
    bad = ~((values >= low) & (values <= high))
    if np.any(bad):
        row, column = np.argwhere(bad)[0][:2]
        v = values[row, column]
        value = shown(v) if np.ndim(v) == 0 else "(" + ", ".join(shown(x) for x in v) + ")"
        what = "every channel must be" if kind == "colour" else "it must be"
        raise ValueError(f"glint.{name}: texel (column {column}, row {row}) is {value}: "
                         f"{what} in [{shown(low)}, {shown(high)}]")
    if name == "density_map" and not np.any(values > 0):
        raise ValueError(f"glint.{name}: every texel is 0: the material would hold no particle")
    return np.ascontiguousarray(np.flipud(values))
