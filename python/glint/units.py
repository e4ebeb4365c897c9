"""Flake density in physical units: ``particles`` (N, flakes per unit texture square) from
flakes per mm² of surface and a mesh's areas.

A glint material's N counts flakes per *texture square*: the part of a shape's (u, v) that one
repetition of the particles covers (1/``uv_scale`` of it in each direction). How many flakes
that is per mm² of surface depends on how the mesh's (u, v) stretches over it, so the same N
looks denser on a small object than on a large one. For a shape of surface area S (in scene
units², one unit being ``metres_per_unit`` metres) whose (u, v) cover an area U of the uv
plane, a flake density of ρ per mm² needs

    N = ρ · 10⁶ · metres_per_unit² · S / (uv_scale² · U)

flakes per texture square: the shape holds ρ·10⁶·metres_per_unit²·S flakes, spread over
uv_scale²·U texture squares. Where the mesh's (u, v) stretch unevenly, the flakes follow the
(u, v) (uniform per texture square), so ρ is the mean over the surface.

>>> import glint
>>> glint.particles_per_square(5.0, surface_area=0.04, uv_area=1.0)   # 20 cm square, 5/mm²
200000.0
"""

import math

import numpy as np

__all__ = ["mesh_areas", "particles_per_square"]


def _positive(name, value):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, not {value!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} = {value!r} must be positive and finite")
    return value


def particles_per_square(flakes_per_mm2, *, surface_area, uv_area, metres_per_unit=1.0,
                         uv_scale=1.0):
    """N, the flakes per texture square, for ``flakes_per_mm2`` flakes per mm² of a shape of
    surface area ``surface_area`` (scene units²) whose (u, v) cover ``uv_area`` of the uv
    plane (``mesh_areas`` gives both for a triangle mesh; 1 for a shape whose (u, v) span
    [0, 1]² once), in a scene whose unit is ``metres_per_unit`` metres, with the material's
    ``uv_scale`` (texture repetitions per unit of (u, v)). Pass the result as
    ``glint.Material(particles=round(N))``.

    Every argument must be positive and finite (``ValueError`` naming it).
    """
    density = _positive("flakes_per_mm2", flakes_per_mm2)
    surface = _positive("surface_area", surface_area)
    uv = _positive("uv_area", uv_area)
    unit = _positive("metres_per_unit", metres_per_unit)
    scale = _positive("uv_scale", uv_scale)
    return density * 1e6 * unit * unit * surface / (scale * scale * uv)


def mesh_areas(positions, uvs, triangles):
    """(surface area, uv area) of a triangle mesh: ``positions`` (n, 3) in scene units,
    ``uvs`` (n, 2) per vertex, ``triangles`` (m, 3) vertex indices. The uv area sums each
    triangle's area in the uv plane, whatever its winding (a mirrored half of a mesh counts
    once, not as a negative area).

    ``ValueError`` for arrays of the wrong shape, indices out of range, or values that are not
    finite.
    """
    p = np.asarray(positions, dtype=np.float64)
    t = np.asarray(uvs, dtype=np.float64)
    f = np.asarray(triangles)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"positions must have shape (n, 3), not {p.shape}")
    if t.shape != (p.shape[0], 2):
        raise ValueError(f"uvs must have shape ({p.shape[0]}, 2), one per vertex, not {t.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or f.size == 0 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"triangles must be whole-number indices of shape (m, 3), not {f.shape}")
    if f.min() < 0 or f.max() >= p.shape[0]:
        raise ValueError(f"triangles index vertices 0 to {p.shape[0] - 1}, not "
                         f"{f.min()} to {f.max()}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(t))):
        raise ValueError("positions and uvs must be finite")
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    surface = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    ta, tb, tc = t[f[:, 0]], t[f[:, 1]], t[f[:, 2]]
    e1, e2 = tb - ta, tc - ta
    uv = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum()
    return float(surface), float(uv)
