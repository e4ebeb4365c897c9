"""Maps in the Mitsuba 3 glint BSDF (python/mitsuba/glint_maps.py): density, roughness and tint
maps given as bitmap textures or filenames answer as ``glint.Material`` with the same NumPy maps,
bit for bit, in ``scalar_rgb`` and ``llvm_ad_rgb``, each texel constant or (``map_filter``
``bilinear``) interpolated; the maps lie where Mitsuba's own bitmap lookups put the image, and a
bilinear density where its bilinear lookups put the values; the llvm plugin reads a bilinear
density in Dr.Jit as the package does; the reading rules (8-bit, raw, sRGB, channels, files);
refusals name the parameter; the example renders a mapped floor.

The llvm tests skip, saying why, where Mitsuba's LLVM backend cannot start
(test_mitsuba_vectorized.py's probe)."""

import inspect
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

mi = pytest.importorskip(
    "mitsuba", reason="Mitsuba 3 is not installed (pip install -r python/mitsuba/requirements.txt)")

import glint  # noqa: E402
from test_glint import _queries  # noqa: E402
from test_mitsuba_vectorized import _WHY as _LLVM_WHY  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "mitsuba"
sys.path.insert(0, str(EXAMPLE))
mi.set_variant("scalar_rgb")
import glint_mitsuba as gm  # noqa: E402  (the scalar plugins)

LLVM = "llvm_ad_rgb"
needs_llvm = pytest.mark.skipif(_LLVM_WHY is not None, reason=_LLVM_WHY or "")

# 4 × 3 texels, rows from the image's top: a masked texel, roughness of seven values over four
# levels (8-bit, k/255), a coloured 8-bit sRGB tint.
DENSITY = np.array([[1.0, 0.5, 0.0, 0.25],
                    [0.75, 1.0, 0.6, 0.3],
                    [0.2, 0.9, 1.0, 0.4]], dtype=np.float32)
ALPHA_BYTES = np.array([[13, 26, 51, 77],
                        [102, 13, 26, 51],
                        [77, 102, 128, 13]], dtype=np.uint8)
TINT_BYTES = np.stack([np.linspace(50, 255, 12).reshape(3, 4), np.full((3, 4), 150),
                       np.linspace(255, 20, 12).reshape(3, 4)], axis=2).astype(np.uint8)
KWARGS = dict(particles=1e8, gamma_degrees=2.0, seed=5, roughness_levels=4)
UV_SCALE = 0.75


def _srgb(c):
    """The sRGB decoding, written here independently of glint_maps."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


#: The maps glint.Material must receive: glint's row order is the image's bottom first.
EXPECTED = dict(density_map=np.flipud(DENSITY.astype(np.float64)),
                alpha_map=np.flipud(ALPHA_BYTES / 255.0),
                tint_map=np.flipud(_srgb(TINT_BYTES / 255.0)))


def _grey(array):
    return mi.Bitmap(array[:, :, None], mi.Bitmap.PixelFormat.Y)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("maps")
    paths = {"alpha": folder / "alpha.png", "tint": folder / "tint.png",
             "density": folder / "density.exr"}
    _grey(ALPHA_BYTES).write(str(paths["alpha"]))
    mi.Bitmap(TINT_BYTES, mi.Bitmap.PixelFormat.RGB).write(str(paths["tint"]))
    _grey(DENSITY).write(str(paths["density"]))
    return paths


def _props(files, map_filter=None):
    """The three maps in the three ways: an in-memory float bitmap, a filename (8-bit PNG, read
    linearly), an 8-bit sRGB bitmap texture (decoded); ``map_filter`` when given."""
    filtered = {} if map_filter is None else {"map_filter": map_filter}
    return {"type": "glint", **KWARGS, **filtered, "uv_scale": UV_SCALE,
            "density_map": {"type": "bitmap", "bitmap": _grey(DENSITY)},
            "alpha_map": str(files["alpha"]),
            "tint_map": {"type": "bitmap", "filename": str(files["tint"])}}


def _reference(map_filter=None):
    filtered = {} if map_filter is None else {"map_filter": map_filter}
    return glint.Material(**KWARGS, **filtered, **EXPECTED)


#: Each texel constant (the default), or the density and roughness bilinear.
FILTERS = [None, "bilinear"]


def _footprint_queries(n, seed):
    """Queries as the plugins see them: float32 directions, uv and partials, and the float64
    numbers the package gets from them (uv and partials times uv_scale in double precision)."""
    wi, wo, uv, dx, dy, u = _queries(n, seed)
    dx, dy = dx * 0.3, dy * 0.3
    f32 = [np.asarray(a, dtype=np.float32) for a in (wi, wo, uv, dx, dy)]
    f64 = [a.astype(np.float64) for a in f32]
    for k in (2, 3, 4):
        f64[k] = f64[k] * UV_SCALE
    return f32, f64, np.asarray(u[:, :3], dtype=np.float32)


@pytest.mark.parametrize("map_filter", FILTERS)
def test_scalar_plugin_answers_as_the_material_bit_for_bit(files, map_filter):
    """scalar_rgb: f̂ (in colour), the smooth limit at the texture position, the sampler's pdf
    and sample there are ``glint.Material``'s with the NumPy maps, bit for bit."""
    mi.set_variant("scalar_rgb")
    bsdf = mi.load_dict(_props(files, map_filter))
    assert isinstance(bsdf, gm.GlintBSDF)
    assert bsdf.params["map_filter"] == (map_filter or "nearest")
    for name, expected in EXPECTED.items():
        assert np.array_equal(bsdf.maps[name], expected), name
    reference = _reference(map_filter)
    (wi, wo, uv, dx, dy), (wi64, wo64, uv64, dx64, dy64), u = _footprint_queries(150, seed=8)
    r = reference.eval(wi64, wo64, uv64, dx64, dy64)
    zero = np.zeros_like(uv64)
    smooth = reference.eval(wi64, wo64, uv64, zero, zero)["f_smooth"]
    pdf = reference.pdf(wi64, wo64, uv64)
    u64 = np.minimum(u.astype(np.float64), math.nextafter(1.0, 0.0))[:, [1, 2, 0]]
    s = reference.sample(wi64, u64, uv64, zero, zero)
    ctx = mi.BSDFContext()
    compared = lit = 0
    for i in range(len(wi)):
        si = mi.SurfaceInteraction3f()
        si.wi, si.uv = mi.Vector3f(*wi[i]), mi.Point2f(*uv[i])
        si.duv_dx, si.duv_dy = mi.Vector2f(*dx[i]), mi.Vector2f(*dy[i])
        w = mi.Vector3f(*wo[i])
        if r["error"][i] == "":
            f = bsdf.brdf(si, w)
            assert f.shape == (3,) and np.array_equal(f, r["f_hat"][i]), (i, f, r["f_hat"][i])
            compared += 1
            lit += np.any(f > 0)
        if wi[i, 2] > 0 and wo[i, 2] > 0:
            assert bsdf.pdf(ctx, si, w) == pdf[i]
        bs, weight = bsdf.sample(ctx, mi.SurfaceInteraction3f(si), float(u[i, 0]),
                                 mi.Point2f(*u[i, 1:]))
        si.duv_dx, si.duv_dy = mi.Vector2f(0.0), mi.Vector2f(0.0)
        if r["error"][i] == "":
            assert np.array_equal(bsdf.brdf(si, w), smooth[i]), i
        if wi[i, 2] > 0 and s["pdf"][i] > 0:
            assert np.array_equal(np.array(bs.wo), np.float32(s["wo"][i]))
            assert bs.pdf == np.float32(s["pdf"][i])
            _, weight = bsdf.sample(ctx, si, float(u[i, 0]), mi.Point2f(*u[i, 1:]))
            assert np.array_equal(np.array(weight), np.float32(s["smooth_weight"][i]))
    assert compared > 100 and lit > 10, (compared, lit)


@pytest.fixture(scope="module")
def vectorized():
    """The vectorized glint BSDF class (llvm_ad_rgb); the variant is llvm_ad_rgb inside the
    tests and scalar_rgb again after them."""
    mi.set_variant(LLVM)
    import glint_vectorized

    classes = glint_vectorized.register()
    yield classes[0]
    mi.set_variant("scalar_rgb")


def _wavefront(wi, uv, dx, dy):
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wi[:, k])) for k in range(3)])
    si.uv = mi.Point2f(*[mi.Float(np.ascontiguousarray(uv[:, k])) for k in range(2)])
    si.duv_dx = mi.Vector2f(*[mi.Float(np.ascontiguousarray(dx[:, k])) for k in range(2)])
    si.duv_dy = mi.Vector2f(*[mi.Float(np.ascontiguousarray(dy[:, k])) for k in range(2)])
    return si


def _colours(c):
    """(n, 3) float32 from a Dr.Jit Color3f."""
    return np.asarray(c.numpy()).T


@needs_llvm
@pytest.mark.parametrize("map_filter", FILTERS)
def test_vectorized_plugin_answers_as_the_material_bit_for_bit(files, vectorized, map_filter):
    """llvm_ad_rgb, the same maps: f̂ on a wavefront is the package's in float32, bit for bit;
    the smooth limit, the pdf and the samples (from the package at the texture position: a
    roughness map) too; eval, pdf and sample equal the scalar plugin's."""
    bsdf = mi.load_dict(_props(files, map_filter))
    assert isinstance(bsdf, vectorized) and bsdf.lobe_varies and bsdf.coloured
    for name, expected in EXPECTED.items():
        assert np.array_equal(bsdf.maps[name], expected), name
    reference = _reference(map_filter)
    (wi, wo, uv, dx, dy), (wi64, wo64, uv64, dx64, dy64), u = _footprint_queries(300, seed=9)
    r = reference.eval(wi64, wo64, uv64, dx64, dy64)
    ok = r["error"] == ""
    si = _wavefront(wi, uv, dx, dy)
    w = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k])) for k in range(3)])
    f = _colours(bsdf.brdf(si, w, mi.Bool(True)))
    assert np.array_equal(f[ok], np.float32(r["f_hat"][ok]))
    assert np.sum(np.any(f > 0, axis=1)) > 20
    zero = np.zeros_like(dx)
    still = _wavefront(wi, uv, zero, zero)
    smooth = reference.eval(wi64, wo64, uv64, zero, zero)["f_smooth"]
    f = _colours(bsdf.brdf(still, w, mi.Bool(True)))
    assert np.array_equal(f[ok], np.float32(smooth[ok]))
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    ctx = mi.BSDFContext()
    pdf = np.asarray(bsdf.pdf(ctx, si, w).numpy())
    assert np.array_equal(pdf[above], np.float32(reference.pdf(wi64, wo64, uv64)[above]))

    bs, weight = bsdf.sample(ctx, still, mi.Float(u[:, 0]),
                             mi.Point2f(mi.Float(u[:, 1]), mi.Float(u[:, 2])))
    u64 = np.minimum(u.astype(np.float64), math.nextafter(1.0, 0.0))[:, [1, 2, 0]]
    s = reference.sample(wi64, u64, uv64, zero.astype(float), zero.astype(float))
    sampled = (s["pdf"] > 0) & (wi[:, 2] > 0)
    assert np.array_equal(np.asarray(bs.pdf.numpy()) > 0, sampled) and sampled.sum() > 100
    assert np.array_equal(np.asarray(bs.wo.numpy()).T[sampled], np.float32(s["wo"][sampled]))

    # The scalar plugin's eval, pdf and sample on the same queries.
    mi.set_variant("scalar_rgb")
    scalar = mi.load_dict(_props(files, map_filter))
    expected = []
    for i in range(0, len(wi), 5):
        sj = mi.SurfaceInteraction3f()
        sj.wi, sj.uv = mi.Vector3f(*wi[i]), mi.Point2f(*uv[i])
        sj.duv_dx, sj.duv_dy = mi.Vector2f(*dx[i]), mi.Vector2f(*dy[i])
        wj = mi.Vector3f(*wo[i])
        sample = scalar.sample(mi.BSDFContext(), mi.SurfaceInteraction3f(sj), float(u[i, 0]),
                               mi.Point2f(*u[i, 1:]))
        expected.append((np.array(scalar.eval(mi.BSDFContext(), sj, wj)),
                         scalar.pdf(mi.BSDFContext(), sj, wj), np.array(sample[1])))
    mi.set_variant(LLVM)
    bs, weight = bsdf.sample(ctx, si, mi.Float(u[:, 0]),
                             mi.Point2f(mi.Float(u[:, 1]), mi.Float(u[:, 2])))
    value = _colours(bsdf.eval(ctx, si, w))[::5]
    weight = _colours(weight)[::5]
    for k, (e, p, sw) in enumerate(expected):
        assert value[k] == pytest.approx(e, rel=1e-6, abs=1e-30)
        assert pdf[::5][k] == pytest.approx(p, rel=1e-6, abs=1e-30)
        assert weight[k] == pytest.approx(sw, rel=1e-5, abs=1e-30)


@needs_llvm
def test_density_and_tint_maps_keep_the_dr_jit_lobe_and_its_skips_exact(vectorized):
    """A density map and a coloured tint (of another size) leave the lobe in Dr.Jit, with the
    negligible-query test of the material without maps: lanes it skips are ones the package
    answers 0, f̂ on the wavefront is the package's, bit for bit, and the smooth limit
    d(uv)·t(uv)·f the package's to float32 rounding (queries near and away from the highlight,
    as in test_mitsuba_vectorized's test of the skips)."""
    stripes = np.repeat(((np.arange(64) // 2) % 2).astype(np.float32)[:, None], 3, axis=1)
    stripes[5, 1] = 0.3
    stripes[9, 0] = 0.7
    tint = np.random.default_rng(1).uniform(0.1, 1.0, (7, 5, 3)).astype(np.float32)
    material = dict(particles=1e7, gamma_degrees=0.5, seed=2, negligible_count=1e-4)
    bsdf = mi.load_dict({"type": "glint", **material, "uv_scale": UV_SCALE,
                         "density_map": {"type": "bitmap", "bitmap": _grey(stripes),
                                         "raw": True},
                         "tint_map": {"type": "bitmap", "bitmap": mi.Bitmap(tint)}})
    assert not bsdf.lobe_varies and bsdf.coloured and bsdf.lobe.negligible is not None
    reference = glint.Material(**material, density_map=np.flipud(stripes.astype(np.float64)),
                               tint_map=np.flipud(tint.astype(np.float64)))
    rng = np.random.default_rng(3)
    n = 4000
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    wo = np.where(np.arange(n)[:, None] % 2 == 0, mirror + rng.normal(0, 0.1, (n, 3)),
                  rng.normal(size=(n, 3)))
    wo[:, 2] = np.abs(wo[:, 2])
    side = 10 ** rng.uniform(-4.5, -1.5, n)
    dx = np.stack([side, 0.3 * side * rng.normal(size=n)], 1)
    dy = np.stack([0.3 * side * rng.normal(size=n), side], 1)
    uv = rng.uniform(-2, 3, (n, 2))
    wi, wo, uv, dx, dy = (np.asarray(a, dtype=np.float32) for a in (wi, wo, uv, dx, dy))
    wi64, wo64 = wi.astype(np.float64), wo.astype(np.float64)
    uv64, dx64, dy64 = (a.astype(np.float64) * UV_SCALE for a in (uv, dx, dy))
    r = reference.eval(wi64, wo64, uv64, dx64, dy64)
    ok = r["error"] == ""
    si = _wavefront(wi, uv, dx, dy)
    w = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k])) for k in range(3)])
    f = _colours(bsdf.brdf(si, w, mi.Bool(True)))
    assert np.array_equal(f[ok], np.float32(r["f_hat"][ok]))
    skipped = np.asarray(bsdf.lobe.skips(mi.Vector3d(si.wi), mi.Vector3d(w),
                                         *bsdf.footprint(si)[:3]).numpy())
    assert skipped.mean() > 0.1 and np.sum(np.any(f > 0, axis=1)) > 10, skipped.mean()
    assert np.all(r["f_hat"][skipped] == 0)

    zero = np.zeros_like(dx)
    smooth = reference.eval(wi64, wo64, uv64, zero, zero)["f_smooth"]
    f = _colours(bsdf.brdf(_wavefront(wi, uv, zero, zero), w, mi.Bool(True)))
    masked = np.all(smooth == 0, axis=1)
    assert 0.3 < masked.mean() < 0.7 and np.all(f[masked] == 0)
    assert f == pytest.approx(smooth, rel=2e-6, abs=1e-30)


def _bilinear_reference(x, y, texels):
    """glint-tree's ``DensityMap::value_at`` under the bilinear filter, written here from its
    definition for float64 ``x``, ``y`` (arrays) and a map in glint's row order (row 0 at the
    top): the fixed-point texels round(d·2³²) at their centres ((i + ½)/W, (j + ½)/H), j from
    the bottom row, interpolated in the package's order of operations, wrapping, over 2³²."""
    height, width = texels.shape
    scaled = np.flipud(texels) * 2.0**32
    fixed = np.floor(scaled) + (scaled - np.floor(scaled) >= 0.5)
    x, y = x - np.floor(x), y - np.floor(y)
    s, t = x * width - 0.5, y * height - 0.5
    i, j = np.floor(s), np.floor(t)
    fs, ft = s - i, t - j
    i, j = i.astype(np.int64), j.astype(np.int64)

    def q(di, dj):
        return fixed[(j + dj) % height, (i + di) % width]

    return ((1.0 - ft) * ((1.0 - fs) * q(0, 0) + fs * q(1, 0))
            + ft * ((1.0 - fs) * q(0, 1) + fs * q(1, 1))) / 2.0**32


@needs_llvm
def test_a_bilinear_density_is_read_in_dr_jit_as_the_package_reads_it(vectorized):
    """A density map alone keeps the lobe in Dr.Jit, and with ``map_filter`` ``bilinear`` the
    plugin's Dr.Jit lookup d(uv) is the package's, bit for bit: it equals the definition
    written here, and d(uv) times the unmapped material's smooth f is the mapped material's
    smooth f in double precision exactly (the package's smooth limit is d·f). The plugin's
    smooth limit is the package's to float32 rounding; "nearest" still reads the texel."""
    density = np.array([[1.0, 0.0, 0.3, 0.77],
                        [0.25, 0.5, 0.0, 1.0],
                        [0.9, 1.0, 0.123456789, 0.0]], dtype=np.float32)
    material = dict(particles=1e7, gamma_degrees=2.0, seed=4)
    bitmap = {"type": "bitmap", "bitmap": _grey(density)}
    bsdf = mi.load_dict({"type": "glint", **material, "uv_scale": UV_SCALE,
                         "density_map": bitmap, "map_filter": "bilinear"})
    nearest = mi.load_dict({"type": "glint", **material, "uv_scale": UV_SCALE,
                            "density_map": bitmap, "map_filter": "nearest"})
    assert not bsdf.lobe_varies and bsdf.density.bilinear and not nearest.density.bilinear
    glint_map = np.flipud(density.astype(np.float64))
    rng = np.random.default_rng(7)
    n = 3000
    # Texture positions anywhere, on texel centres and edges, and a hair from the tile's edge.
    centres = np.stack(np.meshgrid((np.arange(8) + 0.5) / 8, (np.arange(6) + 0.5) / 6), -1)
    uv = np.concatenate([
        rng.uniform(-3, 4, (n, 2)), centres.reshape(-1, 2),
        np.array([[0.0, 0.0], [1.0, 1.0], [-1e-17, 0.5], [0.5, -1e-17], [0.999999, 0.999999]])])
    d = bsdf.density.at(mi.Vector2d(uv[:, 0], uv[:, 1]))[0].numpy()
    expected = _bilinear_reference(uv[:, 0], uv[:, 1], glint_map)
    assert np.array_equal(d, expected)
    assert np.sum((d > 0) & ~np.isin(d, density.astype(np.float64))) > n // 2

    # Against the package: its smooth limit at uv is d(uv)·f, bit for bit.
    reference = glint.Material(**material, density_map=glint_map, map_filter="bilinear")
    flat = glint.Material(**material)
    wi = np.tile([0.2, 0.1, 0.97], (len(uv), 1))
    wo = np.tile([-0.25, -0.05, 0.96], (len(uv), 1))
    zero = np.zeros_like(uv)
    f_mapped = reference.eval(wi, wo, uv, zero, zero)["f_smooth"]
    f_flat = flat.eval(wi, wo, uv, zero, zero)["f_smooth"]
    assert np.all(f_flat > 0) and np.array_equal(d * f_flat, f_mapped)

    # The plugin's smooth limit on a wavefront (uv in float32, times uv_scale in double).
    uv32 = np.asarray(uv[:n], dtype=np.float32)
    wi32, wo32 = np.asarray(wi[:n], np.float32), np.asarray(wo[:n], np.float32)
    uv64 = uv32.astype(np.float64) * UV_SCALE
    smooth = reference.eval(wi32.astype(float), wo32.astype(float), uv64, zero[:n],
                            zero[:n])["f_smooth"]
    si = _wavefront(wi32, uv32, np.zeros_like(uv32), np.zeros_like(uv32))
    w = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo32[:, k])) for k in range(3)])
    f = np.asarray(bsdf.brdf(si, w, mi.Bool(True)).numpy())
    assert f == pytest.approx(smooth, rel=2e-6, abs=1e-30)
    g = np.asarray(nearest.brdf(si, w, mi.Bool(True)).numpy())
    assert np.sum(f != g) > n // 2


def test_a_bilinear_density_lies_where_mitsubas_bilinear_lookups_put_the_values():
    """``map_filter`` ``bilinear``: the density the package reads at (u, v) is what Mitsuba's
    own ``bitmap`` texture of the image returns there with its default bilinear filter and
    repeating wrap, to float32 rounding (the package's d is d(uv)·f / f; Mitsuba's lookup runs
    in float32)."""
    mi.set_variant("scalar_rgb")
    texture = mi.load_dict({"type": "bitmap", "bitmap": _grey(DENSITY), "raw": True})
    bsdf = mi.load_dict({"type": "glint", "particles": 1e6, "map_filter": "bilinear",
                         "density_map": {"type": "bitmap", "bitmap": _grey(DENSITY)}})
    flat = glint.Material(particles=1e6)
    rng = np.random.default_rng(12)
    uv = np.asarray(rng.uniform(-1, 2, (200, 2)), dtype=np.float32)
    # Directions as Mitsuba holds them (float32), so that both materials see the same ones.
    wi, wo = (np.array(v, dtype=np.float32).astype(float)
              for v in ([0.1, 0.0, 0.995], [-0.1, 0.02, 0.995]))
    f = float(flat.eval(wi, wo, [0.0, 0.0], [0.0, 0.0], [0.0, 0.0])["f_smooth"])
    between = 0
    for u, v in uv:
        si = mi.SurfaceInteraction3f()
        si.wi, si.uv = mi.Vector3f(*wi), mi.Point2f(u, v)
        looked_up = texture.eval_1(si)
        d = bsdf.brdf(si, mi.Vector3f(*wo)) / f
        assert d == pytest.approx(looked_up, abs=2e-6), (u, v)
        between += not np.isin(np.float32(looked_up), DENSITY)
    assert between > 150


def _material_maps(props, variant="scalar_rgb"):
    mi.set_variant(variant)
    return mi.load_dict({"type": "glint", "particles": 1e6, **props}).maps


def test_the_maps_lie_where_mitsubas_bitmap_lookups_put_the_image(tmp_path):
    """An image whose top row alone has flakes: Mitsuba's bitmap texture reads the top row at
    v < 1/2, and the glint BSDF finds flakes there and none at v > 1/2, from a bitmap texture
    or the file."""
    mi.set_variant("scalar_rgb")
    image = np.array([[255, 255], [0, 0]], dtype=np.uint8)
    path = tmp_path / "top.png"
    _grey(image).write(str(path))
    texture = mi.load_dict({"type": "bitmap", "filename": str(path), "raw": True,
                            "filter_type": "nearest"})
    lookups = []
    for v in (0.25, 0.75):
        si = mi.SurfaceInteraction3f()
        si.uv = mi.Point2f(0.5, v)
        lookups.append(texture.eval_1(si))
    assert lookups == [1.0, 0.0]
    for given in ({"type": "bitmap", "filename": str(path), "raw": True}, str(path)):
        bsdf = mi.load_dict({"type": "glint", "alpha": 0.5, "particles": 1e7,
                             "gamma_degrees": 40.0, "epsilon": 0.0, "density_map": given})
        found = []
        for v in (0.25, 0.75):
            si = mi.SurfaceInteraction3f()
            si.wi, si.uv = mi.Vector3f(0.0, 0.0, 1.0), mi.Point2f(0.3, v)
            si.duv_dx, si.duv_dy = mi.Vector2f(0.05, 0.0), mi.Vector2f(0.0, 0.05)
            found.append(bsdf.brdf(si, mi.Vector3f(0.1, 0.0, 1.0)))
        assert found[0] > 0 and found[1] == 0, found


def test_reading_rules(tmp_path):
    """8-bit data as k/255 from a file or a raw bitmap (the same map), an 8-bit tint decoded
    from sRGB from a file or a bitmap (the same map), 16-bit files as k/65535, float images as
    stored, a grey tint in three channels, equal RGB channels as one, images smaller than 2 × 2
    (which Mitsuba's bitmap pads by repeating its edge) the same function."""
    grey = np.array([[0, 128], [255, 64], [7, 200]], dtype=np.uint8)
    png = tmp_path / "grey.png"
    _grey(grey).write(str(png))
    linear = np.flipud(grey / 255.0)
    assert np.array_equal(_material_maps({"density_map": str(png)})["density_map"], linear)
    raw = {"type": "bitmap", "filename": str(png), "raw": True}
    assert np.array_equal(_material_maps({"density_map": raw})["density_map"], linear)
    tint_file = _material_maps({"tint_map": str(png)})["tint_map"]
    tint_bitmap = _material_maps({"tint_map": {"type": "bitmap", "filename": str(png)}})["tint_map"]
    assert np.array_equal(tint_file, np.repeat(_srgb(linear)[:, :, None], 3, axis=2))
    assert np.array_equal(tint_bitmap, tint_file)
    raw_tint = _material_maps({"tint_map": raw})["tint_map"]
    assert np.array_equal(raw_tint[:, :, 1], linear)

    wide = np.array([[0, 30000], [65535, 1]], dtype=np.uint16)
    png16 = tmp_path / "wide.png"
    _grey(wide).write(str(png16))
    assert np.array_equal(_material_maps({"density_map": str(png16)})["density_map"],
                          np.flipud(wide / 65535.0))

    exr = tmp_path / "alpha.exr"
    values = np.array([[0.05, 0.3], [0.7, 1.0]], dtype=np.float32)
    _grey(values).write(str(exr))
    for given in (str(exr), {"type": "bitmap", "filename": str(exr)}):
        assert np.array_equal(_material_maps({"alpha_map": given})["alpha_map"],
                              np.flipud(values.astype(np.float64)))

    rgb = tmp_path / "rgb.png"
    mi.Bitmap(np.repeat(grey[:, :, None], 3, axis=2), mi.Bitmap.PixelFormat.RGB).write(str(rgb))
    assert np.array_equal(_material_maps({"density_map": str(rgb)})["density_map"], linear)

    row = tmp_path / "row.png"
    _grey(np.array([[255, 0, 128]], dtype=np.uint8)).write(str(row))
    padded = _material_maps({"density_map": {"type": "bitmap", "filename": str(row),
                                             "raw": True}})["density_map"]
    as_file = _material_maps({"density_map": str(row)})["density_map"]
    assert padded.shape == (2, 3) and as_file.shape == (1, 3)
    assert np.array_equal(padded, np.repeat(as_file, 2, axis=0))


@pytest.mark.parametrize("props, message", [
    ({"density_map": {"type": "checkerboard"}},
     "glint.density_map must be a bitmap texture or an image filename, not a Checkerboard"),
    ({"density_map": 0.5}, "glint.density_map must be a bitmap texture or an image filename, "
                           "not the constant 0.5: a constant density d is the material with d"),
    ({"tint_map": {"type": "rgb", "value": [0.1, 0.2, 0.3]}},
     "glint.tint_map must be a bitmap texture or an image filename, not the constant"),
    ({"alpha_map": 0.2}, "glint.alpha_map must be a bitmap texture or an image filename, not "
                         "the constant 0.2: a constant roughness is alpha"),
    ({"roughness_map": "rough.png"}, "glint.roughness_map is not a parameter of the glint BSDF: "
                                     "its map is alpha_map"),
    ({"density_texture": "d.png"}, "glint.density_texture is not a parameter"),
    ({"density_map": "no/such/file.png"}, "glint.density_map: cannot read the image"),
    ({"density_map": mi.Bitmap(np.ones((2, 2, 1), dtype=np.float32))},
     "glint.density_map must be a bitmap texture or an image filename, not a Bitmap"),
    ({"tint_map": True}, "glint.tint_map must be a bitmap texture or an image filename, not a "
                         "bool"),
])
def test_other_kinds_are_refused_naming_the_parameter(props, message):
    mi.set_variant("scalar_rgb")
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", **props})
    assert "ValueError: " + message in str(error.value), str(error.value)


def _bitmap(array, **kw):
    return {"type": "bitmap", "bitmap": _grey(np.asarray(array, dtype=np.float32)), **kw}


@pytest.mark.parametrize("props, message", [
    ({"density_map": _bitmap([[1.0, 1.5], [0.0, 1.0]])},
     "glint.density_map: texel (column 1, row 0) is 1.5: it must be in [0, 1]"),
    ({"density_map": _bitmap([[1.0, 1.0], [0.0, math.nan]])},
     "glint.density_map: texel (column 1, row 1) is not finite"),
    ({"density_map": _bitmap([[1.0000001, 1.0], [0.0, 1.0]])},
     "glint.density_map: texel (column 0, row 0) is 1.0000001192092896: it must be in [0, 1]"),
    ({"alpha_map": _bitmap([[0.1, 0.2], [0.0, 0.3]])},
     "glint.alpha_map: texel (column 0, row 1) is 0: it must be in [0.0001, 1]"),
    ({"density_map": _bitmap([[0.0, 0.0], [0.0, 0.0]])},
     "glint.density_map: every texel is 0"),
    ({"density_map": _bitmap(np.ones((2, 3))), "alpha_map": _bitmap(np.full((2, 2), 0.1))},
     "glint.alpha_map is 2 × 2 texels and glint.density_map 3 × 2: they must have the same size"),
    ({"alpha_map": _bitmap([[0.1, 0.2], [0.3, 0.4]],
                           to_uv=mi.ScalarTransform4f().scale([2.0, 2.0, 1.0]))},
     "glint.alpha_map: the bitmap's to_uv is not the identity"),
    ({"density_map": {"type": "bitmap", "bitmap": _grey(np.array([[0, 9], [255, 3]],
                                                                 dtype=np.uint8))}},
     "glint.density_map: the bitmap is 8-bit and not raw"),
    ({"density_map": {"type": "bitmap", "bitmap": mi.Bitmap(
        np.array([[[1, 1, 1], [2, 2, 3]]], dtype=np.uint8), mi.Bitmap.PixelFormat.RGB),
        "raw": True}},
     "glint.density_map: texel (column 1, row 0) has channels (0.00784313725490196, "
     "0.00784313725490196, 0.011764705882352941) that differ"),
    ({"tint_map": _bitmap([[0.5, 2.0], [0.1, 0.2]])},
     "glint.tint_map: texel (column 1, row 0) is (2, 2, 2): every channel must be in [0, 1]"),
])
def test_bad_texels_are_refused_naming_the_parameter_and_texel(props, message):
    """Rows are the image's (row 0 at its top), whatever glint's order."""
    mi.set_variant("scalar_rgb")
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", **props})
    assert "ValueError: " + message in str(error.value), str(error.value)


def _png(path, width, height, bit_depth, colour_type, compressed=None):
    """A PNG written by hand: its header says `width` × `height`, its image data are
    `compressed` (zlib), or the zlib of nothing (a file of a few dozen bytes that declares any
    size)."""
    import struct
    import zlib

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, bit_depth, colour_type, 0, 0, 0)
    data = zlib.compress(b"", 9) if compressed is None else compressed
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data)
                     + chunk(b"IEND", b""))
    return path


def test_map_files_are_read_under_the_tracers_pixel_limit(tmp_path):
    """A 16384² grey PNG (a few hundred kilobytes) is beyond the tracer's 2²⁶ pixels: refused
    with the tracer's message, as a scene file's density_texture is (Mitsuba's own reader took
    7.6 GB for it)."""
    import zlib
    mi.set_variant("scalar_rgb")
    side = 16384
    compressor = zlib.compressobj(6)
    row = b"\x00" * (side + 1)  # filter type 0, then the row's grey bytes
    data = b"".join(compressor.compress(row) for _ in range(side)) + compressor.flush()
    path = _png(tmp_path / "huge.png", side, side, 8, 0, data)
    assert path.stat().st_size < 1_000_000
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", "density_map": str(path)})
    assert ("ValueError: glint.density_map: cannot read the image" in str(error.value)
            and "16384 × 16384 pixels: more than the limit of 67108864 pixels"
            in str(error.value)), str(error.value)


def test_a_map_files_size_is_checked_from_its_header(tmp_path):
    """An 89-byte PNG declaring 60000² RGBA16 pixels is refused from its header, before any
    pixel is allocated (Mitsuba's reader tried 28.8 GB and ended in std::bad_alloc)."""
    mi.set_variant("scalar_rgb")
    path = _png(tmp_path / "liar.png", 60000, 60000, 16, 6)
    assert path.stat().st_size < 100
    for name in ("density_map", "tint_map"):
        with pytest.raises(Exception) as error:
            mi.load_dict({"type": "glint", name: str(path)})
        assert (f"ValueError: glint.{name}: cannot read the image" in str(error.value)
                and "60000 × 60000 pixels: wider or higher than the limit of 16384"
                in str(error.value)), str(error.value)


def test_a_nan_texel_in_a_map_file_is_not_finite(tmp_path):
    """The tracer's reader refuses a NaN texel in an EXR and says so ("is not finite"), where
    the channels were compared and said to differ."""
    mi.set_variant("scalar_rgb")
    texels = np.ones((3, 4, 3), dtype=np.float32)
    texels[2, 3] = np.nan
    path = tmp_path / "nan.exr"
    mi.Bitmap(texels, mi.Bitmap.PixelFormat.RGB).write(str(path))
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", "density_map": str(path)})
    assert "is not finite" in str(error.value) and "differ" not in str(error.value), \
        str(error.value)


def test_map_values_are_printed_exactly(tmp_path):
    """A texel just above 1 in a file prints as the double it holds, not as 1."""
    mi.set_variant("scalar_rgb")
    path = tmp_path / "above.exr"
    _grey(np.array([[1.0000001, 0.5], [0.5, 0.5]], dtype=np.float32)).write(str(path))
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", "density_map": str(path)})
    assert ("ValueError: glint.density_map: texel (column 0, row 0) is 1.0000001192092896: it "
            "must be in [0, 1]") in str(error.value), str(error.value)


@needs_llvm
@pytest.mark.parametrize("props, message", [
    ({"density_map": {"type": "checkerboard"}}, "glint.density_map must be a bitmap texture"),
    ({"roughness_map": "rough.png"}, "glint.roughness_map is not a parameter"),
    ({"tint_map": _bitmap([[0.5, 2.0], [0.1, 0.2]])}, "glint.tint_map: texel (column 1, row 0)"),
])
def test_the_vectorized_plugin_refuses_them_too(vectorized, props, message):
    with pytest.raises(Exception) as error:
        mi.load_dict({"type": "glint", **props})
    assert "ValueError: " + message in str(error.value), str(error.value)


def _run_example(tmp_path, *extra, mapped=True):
    out = tmp_path / f"{'mapped' if mapped else 'plain'}.exr"
    args = ["--density-map", "stripes"] if mapped else []
    run = subprocess.run([sys.executable, str(EXAMPLE / "render_sphere_lights.py"), *args,
                          "--out", str(out), *extra], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert ("density map stripes" in run.stdout) == mapped
    image = np.array(mi.Bitmap(str(out)))
    assert np.all(np.isfinite(image)) and image.max() > 0
    return image


def test_the_example_renders_a_mapped_floor(tmp_path):
    mi.set_variant("scalar_rgb")
    _run_example(tmp_path, "--resolution", "16x9", "--spp", "1")


@needs_llvm
def test_the_example_renders_a_mapped_floor_in_the_llvm_variant(tmp_path):
    """The striped floor in llvm_ad_rgb (bands of flakes and bare floor, half and half): the
    floor below the lights holds about half the light of the unmapped floor, the lights
    themselves the same."""
    extra = ("--variant", LLVM, "--resolution", "96x54", "--spp", "16")
    mapped, plain = _run_example(tmp_path, *extra), _run_example(tmp_path, *extra, mapped=False)
    lights, floor = slice(0, 17), slice(20, 54)
    # (up to the order of the film's atomic additions, two threads)
    assert mapped[lights] == pytest.approx(plain[lights], rel=1e-5, abs=1e-6)
    ratio = mapped[floor].sum() / plain[floor].sum()
    assert 0.3 < ratio < 0.7, ratio


def blend_recipe(weight, glint_bsdf):
    """python/README.md's recipe: glitter over a diffuse base, mixed by ``weight``."""
    return {"type": "blendbsdf", "weight": weight,
            "bsdf_0": {"type": "diffuse",
                       "reflectance": {"type": "rgb", "value": [0.05, 0.05, 0.08]}},
            "bsdf_1": glint_bsdf}


def test_the_blendbsdf_recipe_mixes_by_weight():
    """scalar_rgb: the blend answers (1 − w)·base + w·glint, f̂ where the interaction has a
    footprint, the smooth limit without."""
    mi.set_variant("scalar_rgb")
    glint_bsdf = {"type": "glint", "particles": 1e9, "gamma_degrees": 2.0, "seed": 4}
    blend = mi.load_dict(blend_recipe(0.25, glint_bsdf))
    base = mi.load_dict(blend_recipe(0.25, glint_bsdf)["bsdf_0"])
    alone = mi.load_dict(glint_bsdf)
    ctx = mi.BSDFContext()
    (wi, wo, uv, dx, dy), _, _ = _footprint_queries(40, seed=12)
    lit = 0
    for i in range(len(wi)):
        si = mi.SurfaceInteraction3f()
        si.wi, si.uv = mi.Vector3f(*wi[i]), mi.Point2f(*uv[i])
        for partials in ((dx[i], dy[i]), (np.zeros(2), np.zeros(2))):
            si.duv_dx, si.duv_dy = (mi.Vector2f(*p) for p in partials)
            w = mi.Vector3f(*wo[i])
            expected = (0.75 * np.array(base.eval(ctx, si, w))
                        + 0.25 * np.array(alone.eval(ctx, si, w)))
            assert np.array(blend.eval(ctx, si, w)) == pytest.approx(expected, rel=1e-6,
                                                                     abs=1e-12)
            lit += np.any(np.array(alone.eval(ctx, si, w)) > 0)
    assert lit > 10


BLEND_RENDERS = """
import sys
import numpy as np
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
sys.path.insert(0, sys.argv[1])
import glint_mitsuba as gm
""" + inspect.getsource(blend_recipe) + """
means = []
for floor, integrator in [("diffuse", "glint_direct"), ("glint", "glint_direct"),
                          ("blend", "glint_direct"), ("blend", "path")]:
    d = gm.sphere_lights_scene((48, 27), spp=16, hide_emitters=True, rfilter="box",
                               integrator=integrator, density_map=gm.stripes_density_map())
    recipe = blend_recipe(0.25, d["floor"]["bsdf"])
    d["floor"]["bsdf"] = {"diffuse": recipe["bsdf_0"], "glint": recipe["bsdf_1"],
                          "blend": recipe}[floor]
    means.append(float(np.array(gm.render(mi.load_dict(d))).mean()))
print(*means)
"""


@needs_llvm
def test_the_blendbsdf_recipe_renders_in_the_llvm_variant():
    """llvm_ad_rgb, the striped floor: glint_direct renders the blend as the weights mix the
    two floors' renders (within 5%: the blend draws its samples differently), and Mitsuba's
    path renders it too (``glint_mitsuba.render`` finds the glint BSDF inside the blend and
    turns Dr.Jit's symbolic modes off)."""
    run = subprocess.run([sys.executable, "-c", BLEND_RENDERS, str(EXAMPLE)],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    diffuse, glint_floor, blend, path = (float(x) for x in run.stdout.split())
    assert blend == pytest.approx(0.75 * diffuse + 0.25 * glint_floor, rel=0.05)
    assert path > 0 and math.isfinite(path)
