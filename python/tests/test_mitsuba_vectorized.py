"""The vectorized Mitsuba 3 plugins (python/mitsuba/glint_vectorized.py) in ``llvm_ad_rgb``:
the scalar plugin's values on fixed queries, dense glints against roughconductor in the same
integrator, sparse glints glitter, glint_path against Mitsuba's path, bad parameters named.

Skipped (saying why) when Mitsuba's LLVM backend cannot start: it needs LLVM 19's libLLVM
(``DRJIT_LIBLLVM_PATH``; python/ci.sh installs Debian's libllvm19 where it can). The probe
runs in a subprocess, since Dr.Jit aborts the process with an older LLVM."""

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

mi = pytest.importorskip(
    "mitsuba", reason="Mitsuba 3 is not installed (pip install -r python/mitsuba/requirements.txt)")

import glint  # noqa: E402

EXAMPLE = Path(__file__).resolve().parents[1] / "mitsuba"
sys.path.insert(0, str(EXAMPLE))

VARIANT = "llvm_ad_rgb"
PROBE = ("import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
         "assert float((mi.Float([1, 2]) * 2).numpy().sum()) == 6")


def _llvm_works():
    if VARIANT not in mi.variants():
        return f"Mitsuba has no {VARIANT} variant"
    run = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         timeout=300)
    if run.returncode != 0:
        path = os.environ.get("DRJIT_LIBLLVM_PATH", "unset")
        return (f"Mitsuba's {VARIANT} cannot run here (DRJIT_LIBLLVM_PATH={path}; it needs "
                f"LLVM 19, see python/README.md): {run.stderr.strip()[-300:]}")
    return None


_WHY = _llvm_works()
pytestmark = pytest.mark.skipif(_WHY is not None, reason=_WHY or "")

RES = (48, 27)
BOX = dict(crop_offset_x=14, crop_offset_y=10, crop_width=20, crop_height=14)
PASSES, SPP = 8, 16


@pytest.fixture(scope="module")
def plugins():
    """The scalar module (scalar_rgb) and the vectorized classes (llvm_ad_rgb); the variant is
    llvm_ad_rgb inside the tests and scalar_rgb again after them."""
    previous = mi.variant()
    mi.set_variant("scalar_rgb")
    import glint_mitsuba as gm  # the scalar plugins (imported under scalar_rgb)

    mi.set_variant(VARIANT)
    import glint_vectorized

    classes = glint_vectorized.register()
    yield gm, classes
    mi.set_variant(previous or "scalar_rgb")


def _scene(gm, floor, **kw):
    return gm.sphere_lights_scene(RES, spp=SPP, floor=floor, hide_emitters=True, rfilter="box",
                                  **kw)


def _render(gm, d, passes=PASSES):
    """Passes of the highlight window with the vectorized plugins."""
    d["sensor"]["film"].update(BOX)
    scene = mi.load_dict(d)
    import drjit as dr

    out = []
    for k in range(passes):
        with dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False), \
                dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
            out.append(np.array(mi.render(scene, seed=k))[..., 0])
    return np.array(out)


def test_bsdf_gives_the_scalar_plugins_values(plugins):
    """eval, pdf, eval_pdf and sample on a wavefront of fixed queries (with and without a
    footprint, and rows the package refuses) equal the scalar plugin's, query by query."""
    gm, (VBSDF, _, _) = plugins
    rng = np.random.default_rng(4)
    n = 64
    theta = rng.uniform(0.1, 1.3, n)
    wi = np.stack([np.sin(theta), np.zeros(n), np.cos(theta)], 1)
    wo = np.stack([-np.sin(theta) + rng.normal(0, 0.05, n), rng.normal(0, 0.05, n),
                   np.cos(theta)], 1)
    wo[3, 2] = -0.2  # below the horizon
    uv = rng.uniform(0, 1, (n, 2))
    side = 10 ** rng.uniform(-3.5, -2.5, n)
    dx = np.stack([side, np.zeros(n)], 1)
    dy = np.stack([np.zeros(n), side], 1)
    dx[5:9] = 0.0
    dy[5:9] = 0.0  # no footprint: the smooth limit
    dx[10] = [1e20, 0.0]  # a footprint the package refuses: smooth limit
    u = rng.uniform(0, 1, (n, 3)).astype(np.float32)
    props = {"type": "glint", "particles": 1e8, "seed": 3, "uv_scale": 0.5,
             "gamma_degrees": 1.0}

    mi.set_variant("scalar_rgb")
    scalar = mi.load_dict(props)
    assert isinstance(scalar, gm.GlintBSDF)
    ctx = mi.BSDFContext()
    expected = []
    for i in range(n):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi[i])
        si.uv = mi.Point2f(*uv[i])
        si.duv_dx, si.duv_dy = mi.Vector2f(*dx[i]), mi.Vector2f(*dy[i])
        w = mi.Vector3f(*wo[i])
        bs, weight = scalar.sample(ctx, si, float(u[i, 0]), mi.Point2f(*u[i, 1:]))
        expected.append((np.array(scalar.eval(ctx, si, w))[0], scalar.pdf(ctx, si, w),
                         np.array(bs.wo), bs.pdf, np.array(weight)[0]))
    expected = [np.array(c) for c in zip(*expected)]

    mi.set_variant(VARIANT)
    vector = mi.load_dict(props)
    assert isinstance(vector, VBSDF)
    ctx = mi.BSDFContext()
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*[mi.Float(wi[:, k].astype(np.float32)) for k in range(3)])
    si.uv = mi.Point2f(*[mi.Float(uv[:, k].astype(np.float32)) for k in range(2)])
    si.duv_dx = mi.Vector2f(*[mi.Float(dx[:, k].astype(np.float32)) for k in range(2)])
    si.duv_dy = mi.Vector2f(*[mi.Float(dy[:, k].astype(np.float32)) for k in range(2)])
    w = mi.Vector3f(*[mi.Float(wo[:, k].astype(np.float32)) for k in range(3)])
    f = np.array(vector.eval(ctx, si, w).numpy())[0]
    p = np.array(vector.pdf(ctx, si, w).numpy())
    f2, p2 = vector.eval_pdf(ctx, si, w)
    bs, weight = vector.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(mi.Float(u[:, 1]),
                                                                      mi.Float(u[:, 2])))
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(np.array(weight.numpy())))
    assert f == pytest.approx(expected[0], rel=1e-6, abs=1e-30)
    assert p == pytest.approx(expected[1], rel=1e-6, abs=1e-30)
    assert np.array(f2.numpy())[0] == pytest.approx(f, rel=0, abs=0)
    assert np.array(p2.numpy()) == pytest.approx(p, rel=0, abs=0)
    assert np.array(bs.wo.numpy()).T == pytest.approx(expected[2], abs=1e-6)
    assert np.array(bs.pdf.numpy()) == pytest.approx(expected[3], rel=1e-6, abs=1e-30)
    assert np.array(weight.numpy())[0] == pytest.approx(expected[4], rel=1e-5, abs=1e-30)
    assert np.sum(f > 0) > n // 4 and f[3] == 0.0


def test_every_distribution_has_a_dr_jit_port(plugins):
    """The Dr.Jit lobe cannot call Rust inside a kernel, so it ports each distribution; a kind
    of the package's table without a port fails here, not in a user's render."""
    import glint_lobe

    assert sorted(glint_lobe.PORTS) == sorted(glint.DISTRIBUTIONS)


# Every kind of the package's table, anisotropic, and two isotropic Beckmann cones.
@pytest.mark.parametrize("kwargs", [
    dict(distribution=name, alpha=0.2, alpha_y=0.05, gamma_degrees=2.0)
    for name in glint.DISTRIBUTIONS
] + [
    dict(distribution="beckmann", alpha=0.1, gamma_degrees=0.5),
    dict(distribution="beckmann", alpha=0.02, gamma_degrees=3.0),
])
def test_the_dr_jit_lobe_and_sampler_are_the_packages(plugins, kwargs):
    """glint_lobe's sampler, its pdf and the smooth f (Dr.Jit, double precision) against the
    package's on random queries: the same directions from the same uniforms (float32 ones, as
    Mitsuba's samplers give), the same pdf where the cubature rules apply (the other lanes are
    reported for the package's slope-space rule), the same f and sample weight."""
    import drjit as dr

    import glint_lobe

    m = glint.Material(particles=1e6, **kwargs)
    lobe = glint_lobe.Lobe(m._spec, smith_table=m.smith_table)
    rng = np.random.default_rng(5)
    n = 4000
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1)[:, None]
    u = rng.random((n, 3)).astype(np.float32).astype(np.float64)

    def vector(a):
        return mi.Vector3d(*[mi.Float64(np.ascontiguousarray(a[:, k])) for k in range(3)])

    def rows(v):
        return np.stack([np.array(c.numpy()) for c in v], axis=1)

    wo, valid = lobe.sample(vector(wi), *[mi.Float64(u[:, k]) for k in range(3)])
    s = m.sample(wi, u)
    sampled = s["pdf"] > 0
    assert np.array_equal(np.array(valid.numpy()), sampled) and sampled.mean() > 0.5
    assert rows(wo)[sampled] == pytest.approx(s["wo"][sampled], abs=1e-12)
    at = np.where(sampled[:, None], s["wo"], [0.0, 0.0, 1.0])
    pdf, needs_package = (np.array(x.numpy()) for x in lobe.pdf(vector(wi), vector(at)))
    here = sampled & ~needs_package
    assert here.mean() > 0.3
    assert pdf[here] == pytest.approx(s["pdf"][here], rel=1e-9)
    assert np.all(pdf[needs_package] == 0)
    f = np.array(lobe.f_smooth(vector(wi), vector(at)).numpy())
    zero = np.zeros((n, 2))
    expected = m.eval(wi, at, zero, zero, zero, expected_count=False)["f_smooth"]
    assert f == pytest.approx(expected, rel=1e-9, abs=1e-300)
    weight = f * at[:, 2] / np.where(sampled, s["pdf"], 1.0)
    assert weight[sampled] == pytest.approx(s["smooth_weight"][sampled], rel=1e-9)
    assert dr.width(wo) == n

    # The negligible-query test: the lanes skipped here are skipped by the package, with its λ̄.
    m = glint.Material(particles=1e7, negligible_count=1e-4, **kwargs)
    lobe = glint_lobe.Lobe(m._spec, m.negligible_test, m.smith_table)
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    wo = np.where(np.arange(n)[:, None] % 2 == 0, mirror + rng.normal(0, 0.1, (n, 3)),
                  rng.normal(size=(n, 3)))
    wo[:, 2] = np.abs(wo[:, 2])
    side = 10 ** rng.uniform(-4.5, -1.5, n)
    dx = np.stack([side, 0.3 * side * rng.normal(size=n)], 1)
    dy = np.stack([0.3 * side * rng.normal(size=n), side], 1)
    dx[7] = [2e15, 0.0]  # refused by the package: never skipped
    uv = rng.uniform(0, 1, (n, 2))
    uv[8] = [math.nan, 0.5]  # refused too
    r = m.eval(wi, wo, uv, dx, dy, expected_count=False)
    packaged = np.isfinite(r["negligible_bound"])

    def vector2(a):
        return mi.Vector2d(*[mi.Float64(np.ascontiguousarray(a[:, k])) for k in range(2)])

    skips = np.array(lobe.skips(vector(wi), vector(wo), vector2(uv), vector2(dx),
                                vector2(dy)).numpy())
    bound = np.array(lobe.negligible_bound(vector(wi), vector(wo), vector2(dx),
                                           vector2(dy)).numpy())
    assert not np.any(skips & ~packaged) and not skips[7] and not skips[8]
    assert skips.sum() >= 0.99 * packaged.sum() and packaged.mean() > 0.1, packaged.mean()
    assert bound[packaged] == pytest.approx(r["negligible_bound"][packaged], rel=1e-12)
    assert np.all(bound[(r["error"] == "") & ~packaged] >= 1e-4 * (1 - 1e-12))


def test_direct_integrator_gives_the_scalar_plugins_values(plugins):
    """A directional light in the mirror direction of the middle pixels: each pixel's value
    (light sampling only; BSDF samples escape) equals the scalar glint_direct's."""
    gm, _ = plugins
    params = dict(particles=1e10, gamma_degrees=0.5, alpha=0.1, seed=1, epsilon=0.1)
    pixels = [(px, 16) for px in range(20, 29)]

    def scene_dict(sun=None):
        d = gm.sphere_lights_scene(RES, spp=4, **params)
        for i in range(len(gm.SPHERE_LIGHTS)):
            del d[f"light_{i}"]
        if sun is not None:
            d["sun"] = {"type": "directional", "direction": sun,
                        "irradiance": {"type": "rgb", "value": 3.0}}
        return d

    # The light in the mirror direction of the middle pixel's camera ray.
    mi.set_variant("scalar_rgb")
    ray, _ = mi.load_dict(scene_dict()).sensors()[0].sample_ray_differential(
        0.0, 0.5, mi.Point2f(24.5 / RES[0], 16.5 / RES[1]), mi.Point2f(0.5, 0.5))
    d = np.array(ray.d, dtype=np.float64)
    to_light = np.array([d[0] + 0.01, -d[1], d[2]])
    sun = list(-to_light / np.linalg.norm(to_light))

    def values(variant):
        mi.set_variant(variant)
        scene = mi.load_dict(scene_dict(sun))
        sensor = scene.sensors()[0]
        sampler = sensor.sampler().clone()
        sampler.seed(0, len(pixels))
        xs = np.array([(px + 0.5) / RES[0] for px, _ in pixels], dtype=np.float32)
        ys = np.array([(py + 0.5) / RES[1] for _, py in pixels], dtype=np.float32)
        if variant == VARIANT:
            ray, _ = sensor.sample_ray_differential(
                0.0, 0.5, mi.Point2f(mi.Float(xs), mi.Float(ys)), mi.Point2f(0.5, 0.5))
            ray.scale_differential(1.0 / math.sqrt(sampler.sample_count()))
            radiance, _, _ = scene.integrator().sample(scene, sampler, ray)
            return np.array(radiance.numpy())[0]
        out = []
        for x, y in zip(xs, ys):
            ray, _ = sensor.sample_ray_differential(0.0, 0.5, mi.Point2f(x, y),
                                                    mi.Point2f(0.5, 0.5))
            ray.scale_differential(1.0 / math.sqrt(sampler.sample_count()))
            radiance, _, _ = scene.integrator().sample(scene, sampler, ray)
            out.append(radiance[0])
        return np.array(out)

    scalar = values("scalar_rgb")
    vector = values(VARIANT)
    print("scalar", scalar, "vectorized", vector)
    assert np.sum(scalar > 0) >= 3
    assert vector == pytest.approx(scalar, rel=1e-4, abs=1e-6 * scalar.max())


@pytest.fixture(scope="module")
def smooth_reference(plugins):
    gm, _ = plugins
    return _render(gm, _scene(gm, "roughconductor"))


def test_dense_glints_average_to_roughconductor(plugins, smooth_reference):
    """N = 10¹³ against roughconductor in the same (vectorized glint_direct) integrator: the
    means of the highlight window agree within 3% + 4 standard errors of the paired per-pass
    difference."""
    gm, _ = plugins
    dense = _render(gm, _scene(gm, "glint", particles=1e13))
    difference = dense.mean(axis=(1, 2)) - smooth_reference.mean(axis=(1, 2))
    se = difference.std(ddof=1) / math.sqrt(PASSES)
    r = smooth_reference.mean()
    print(f"dense {dense.mean():.5f}, roughconductor {r:.5f}, "
          f"difference {difference.mean():+.5f} ± {se:.5f}")
    assert r > 0.1 and np.all(np.isfinite(dense))
    assert abs(difference.mean()) <= 0.03 * r + 4 * se


def test_sparse_glints_glitter(plugins, smooth_reference):
    """N = 10⁵: over the highlight the pixel variance is at least 10× roughconductor's."""
    gm, _ = plugins
    sparse = _render(gm, _scene(gm, "glint", particles=1e5), passes=1)[0]
    smooth = smooth_reference[0]
    region = smooth_reference.mean(axis=0) > 0.1 * smooth_reference.mean(axis=0).max()
    ratio = sparse[region].var() / smooth[region].var()
    print(f"variance ratio {ratio:.1f}")
    assert np.all(np.isfinite(sparse)) and ratio >= 10


def _indirect_scene(gm, floor, integrator):
    """The sphere lights with a white diffuse wall behind them, seen in the floor: the wall's
    light reaches the camera after two bounces (wall, floor)."""
    d = gm.sphere_lights_scene((24, 14), spp=32, floor=floor, integrator=integrator,
                               rfilter="box", hide_emitters=True, particles=1e13, max_depth=4)
    d["wall"] = {"type": "rectangle", "bsdf": {"type": "diffuse"},
                 "to_world": mi.ScalarTransform4f().translate([0.0, 2.0, -6.0]).scale(6.0)}
    return d


def test_path_integrator_matches_mitsubas_path(plugins):
    """glint_path against Mitsuba's path with roughconductor, on a scene with indirect light
    (max_depth 4): per-pass image means agree within 4 standard errors + 2%; and a dense glint
    floor in glint_path averages to the same."""
    gm, _ = plugins
    import drjit as dr

    def means(floor, integrator, passes=6):
        scene = mi.load_dict(_indirect_scene(gm, floor, integrator))
        out = []
        for k in range(passes):
            with dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False), \
                    dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
                image = np.array(mi.render(scene, seed=100 + k))
            assert np.all(np.isfinite(image))
            out.append(image.mean())
        return np.array(out)

    reference = means("roughconductor", "path")
    ours = means("roughconductor", "glint_path")
    glints = means("glint", "glint_path")
    direct_only = means("roughconductor", "glint_direct")
    print(f"path {reference.mean():.5f}, glint_path {ours.mean():.5f}, "
          f"glint_path with glints {glints.mean():.5f}, direct only {direct_only.mean():.5f}")
    for a in (ours, glints):
        se = math.sqrt(a.var(ddof=1) / len(a) + reference.var(ddof=1) / len(reference))
        assert abs(a.mean() - reference.mean()) <= 0.02 * reference.mean() + 4 * se
    # The scene has indirect light: a direct-only render is clearly darker.
    assert direct_only.mean() < 0.9 * reference.mean()


@pytest.mark.parametrize("plugin, name, value", [
    ("glint", "uv_scale", math.nan),
    ("glint", "uv_scale", -1.0),
    ("glint", "seed", 1.7),
    ("glint", "particles", 0.5),
    ("glint", "map_filter", "cubic"),
    ("glint_direct", "footprint_scale", math.nan),
    ("glint_path", "footprint_scale", -1.0),
    ("glint_path", "max_depth", -5),
])
def test_plugins_refuse_bad_parameters_naming_them(plugins, plugin, name, value):
    with pytest.raises(Exception, match=rf"ValueError: \S*{name}"):
        mi.load_dict({"type": plugin, name: value})


def test_render_script_runs_in_the_llvm_variant(tmp_path):
    out = tmp_path / "lights.exr"
    run = subprocess.run([sys.executable, str(EXAMPLE / "render_sphere_lights.py"),
                          "--variant", VARIANT, "--integrator", "glint_path", "--resolution", "16x9",
                          "--spp", "2", "--samples-per-pass", "1", "--out", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert out.stat().st_size > 0


def test_renders_in_passes_keep_the_scenes_sample_count(plugins):
    """``glint_mitsuba.render`` in passes averages passes of the given size, and leaves the
    sampler at the scene's count: a second render draws the same samples again (Mitsuba's
    ``mi.render(spp=k)`` sets the sampler's count to k)."""
    gm, _ = plugins
    scene = mi.load_dict(gm.sphere_lights_scene((16, 9), spp=4, floor="roughconductor"))
    first = np.array(gm.render(scene, samples_per_pass=2))
    assert scene.sensors()[0].sampler().sample_count() == 4
    again = np.array(gm.render(scene, samples_per_pass=2))
    # Equal up to the order of the film's atomic additions (two threads); one pass of 2 spp
    # instead of two would differ by the noise.
    assert again == pytest.approx(first, rel=1e-5, abs=1e-12)
    passes = [np.array(mi.render(scene, seed=k, spp=2)) for k in range(2)]
    assert first == pytest.approx((passes[0] + passes[1]) / 2, rel=1e-5, abs=1e-7)
