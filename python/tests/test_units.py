"""Flake density in physical units (``glint.particles_per_square``, ``glint.mesh_areas``): the
conversion against its definition on meshes whose areas are known in closed form."""

import math

import numpy as np
import pytest

import glint


def _grid(nu, nv, surface_point, uv_scale=(1.0, 1.0)):
    """A (nu × nv)-quad mesh of a parametric surface over [0, 1]², (u, v) scaled by uv_scale."""
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    positions = np.stack(surface_point(u.ravel(), v.ravel()), axis=1)
    uvs = np.stack([u.ravel() * uv_scale[0], v.ravel() * uv_scale[1]], axis=1)
    index = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return positions, uvs, triangles


def test_a_flat_rectangle_has_its_areas_and_n_counts_flakes_per_square():
    # 0.2 × 0.5 units, (u, v) over [0, 2] × [0, 1]: two texture squares at uv_scale 1.
    positions, uvs, triangles = _grid(
        4, 3, lambda u, v: (0.2 * u, 0.5 * v, 0 * u), uv_scale=(2.0, 1.0))
    surface, uv = glint.mesh_areas(positions, uvs, triangles)
    assert surface == pytest.approx(0.1, rel=1e-12) and uv == pytest.approx(2.0, rel=1e-12)
    # 5 flakes per mm² on 0.1 m² is 500 000 flakes over two squares.
    n = glint.particles_per_square(5.0, surface_area=surface, uv_area=uv)
    assert n == pytest.approx(250_000.0, rel=1e-12)
    # Centimetres as the unit: 10⁻⁴ of the area; uv_scale 3 spreads the flakes over 9× squares.
    assert glint.particles_per_square(5.0, surface_area=surface, uv_area=uv,
                                      metres_per_unit=0.01, uv_scale=3.0) == pytest.approx(
        250_000.0 * 1e-4 / 9.0, rel=1e-12)


def test_a_sphere_mesh_converges_to_four_pi_r_squared():
    r = 0.3

    def sphere(u, v):
        phi, theta = 2 * math.pi * u, math.pi * (1 - v)
        return (r * np.sin(theta) * np.cos(phi), r * np.cos(theta), -r * np.sin(theta) * np.sin(phi))

    surface, uv = glint.mesh_areas(*_grid(256, 128, sphere))
    assert surface == pytest.approx(4 * math.pi * r * r, rel=1e-3)
    assert uv == pytest.approx(1.0, rel=1e-12)


def test_mirrored_uvs_count_their_area_once():
    positions, uvs, triangles = _grid(2, 2, lambda u, v: (u, v, 0 * u))
    mirrored = uvs * [-1.0, 1.0]
    assert glint.mesh_areas(positions, mirrored, triangles)[1] == pytest.approx(1.0)


@pytest.mark.parametrize("name, kwargs", [
    ("flakes_per_mm2", dict(flakes_per_mm2=0.0)),
    ("surface_area", dict(surface_area=math.inf)),
    ("uv_area", dict(uv_area=-1.0)),
    ("metres_per_unit", dict(metres_per_unit=math.nan)),
    ("uv_scale", dict(uv_scale="x")),
])
def test_bad_arguments_are_named(name, kwargs):
    arguments = dict(flakes_per_mm2=1.0, surface_area=1.0, uv_area=1.0, **{})
    arguments.update(kwargs)
    density = arguments.pop("flakes_per_mm2")
    with pytest.raises(ValueError, match=name):
        glint.particles_per_square(density, **arguments)


def test_bad_meshes_are_named():
    positions, uvs, triangles = _grid(1, 1, lambda u, v: (u, v, 0 * u))
    with pytest.raises(ValueError, match="positions"):
        glint.mesh_areas(positions[:, :2], uvs, triangles)
    with pytest.raises(ValueError, match="uvs"):
        glint.mesh_areas(positions, uvs[:-1], triangles)
    with pytest.raises(ValueError, match="triangles index"):
        glint.mesh_areas(positions, uvs, triangles + 10)
    with pytest.raises(ValueError, match="triangles"):
        glint.mesh_areas(positions, uvs, triangles.astype(float))
