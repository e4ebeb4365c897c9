"""The Mitsuba 3 example (python/mitsuba/glint_mitsuba.py): the glint BSDF plugin and the
glint_direct integrator against the package and against Mitsuba's own roughconductor."""

import math
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
import glint_mitsuba as gm  # noqa: E402

RES = (48, 27)
# The film window holding the highlights of the 48×27 view (99% of their light).
BOX = dict(crop_offset_x=14, crop_offset_y=10, crop_width=20, crop_height=14)
PASSES, SPP = 12, 16
DENSE, SPARSE = 1e13, 1e6


def camera_rs_ray(film, width, height):
    """glint-tracer's CameraView::ray (crates/tracer/src/camera.rs) in float64."""
    eye, target, up = np.array([0, 1, 4.5]), np.array([0, 0.05, 0]), np.array([0.0, 1, 0])
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    hh = math.tan(math.radians(20.0))
    x, y = 2 * film[0] / width - 1, 1 - 2 * film[1] / height
    d = forward + x * right * hh * width / height + y * up * hh
    return eye, d / np.linalg.norm(d)


def camera_rs_footprint(px, py):
    """glint-tracer's texture_footprint on the floor (normal +y, ∂p/∂u = (40, 0, 0),
    ∂p/∂v = (0, 0, −40)) for the pixel centre (px + ½, py + ½), in float64."""
    hits = []
    for film in ((px + 0.5, py + 0.5), (px + 1.5, py + 0.5), (px + 0.5, py + 1.5)):
        o, d = camera_rs_ray(film, *RES)
        hits.append(o - d * o[1] / d[1])
    dpdu, dpdv = np.array([40.0, 0, 0]), np.array([0, 0, -40.0])
    a, b, c = dpdu @ dpdu, dpdu @ dpdv, dpdv @ dpdv
    det = a * c - b * b

    def solve(dp):
        r, s = dpdu @ dp, dpdv @ dp
        return np.array([(c * r - b * s) / det, (a * s - b * r) / det])

    return hits[0], solve(hits[1] - hits[0]), solve(hits[2] - hits[0])


def camera_ray(scene, px, py):
    """Mitsuba's camera ray differential through the centre of pixel (px, py)."""
    ray, _ = scene.sensors()[0].sample_ray_differential(
        0.0, 0.5, mi.Point2f((px + 0.5) / RES[0], (py + 0.5) / RES[1]), mi.Point2f(0.5, 0.5))
    return ray


def test_film_loop_scales_differentials_by_one_over_sqrt_spp():
    """The premise of glint_direct's rescaling: Mitsuba hands integrators camera ray
    differentials of 1/√spp pixels."""
    seen = []

    class Probe(mi.SamplingIntegrator):
        def sample(self, scene, sampler, ray, medium=None, active=True):
            seen.append(np.linalg.norm(np.array(ray.d_x) - np.array(ray.d)))
            return mi.Color3f(0.0), True, []

    mi.register_integrator("glint_test_probe", lambda props: Probe(props))
    d = gm.sphere_lights_scene(resolution=(8, 6), spp=4, floor="roughconductor")
    d["integrator"] = {"type": "glint_test_probe"}
    d["sensor"]["fov"] = 0.5  # a narrow view: one pixel is the same angle everywhere
    scene = mi.load_dict(d)
    mi.render(scene)
    ray, _ = scene.sensors()[0].sample_ray_differential(
        0.0, 0.5, mi.Point2f(0.5, 0.5), mi.Point2f(0.5, 0.5))
    one_pixel = np.linalg.norm(np.array(ray.d_x) - np.array(ray.d))
    assert len(seen) == 8 * 6 * 4
    assert np.allclose(seen, one_pixel / 2, rtol=1e-3)


def test_pixel_value_is_f_hat_of_the_package():
    """(a) A pixel lit by a directional light: footprint, f̂ and the integrator's value."""
    params = dict(particles=1e10, gamma_degrees=0.5, alpha=0.1, seed=1, epsilon=0.1,
                  negligible_count=1e-12)
    reference = glint.Material(distribution="beckmann", **params)
    pixels = [(px, 16) for px in range(20, 29)]
    base = gm.sphere_lights_scene(RES, spp=4, **params)
    for i in range(len(gm.SPHERE_LIGHTS)):
        del base[f"light_{i}"]
    # The light in the mirror direction of the middle pixel's camera ray.
    d = np.array(camera_ray(mi.load_dict(base), 24, 16).d, dtype=np.float64)
    to_light = np.array([d[0] + 0.01, -d[1], d[2]])
    to_light /= np.linalg.norm(to_light)
    irradiance = 3.0
    base["sun"] = {"type": "directional", "direction": list(-to_light),
                   "irradiance": {"type": "rgb", "value": irradiance}}
    scene = mi.load_dict(base)
    bsdf = scene.shapes()[0].bsdf()
    if not isinstance(bsdf, gm.GlintBSDF):
        bsdf = scene.shapes()[1].bsdf()
    integrator = scene.integrator()
    assert isinstance(bsdf, gm.GlintBSDF) and isinstance(integrator, gm.GlintDirectIntegrator)
    sampler = scene.sensors()[0].sampler().clone()
    spp = sampler.sample_count()
    nonzero = 0
    for px, py in pixels:
        # The camera agrees with glint-tracer's, and so does the footprint.
        ray = camera_ray(scene, px, py)
        _, d_rs = camera_rs_ray((px + 0.5, py + 0.5), *RES)
        assert np.allclose(np.array(ray.d), d_rs, atol=2e-6)
        # What glint_direct does with the differential Mitsuba's film loop hands it.
        ray.scale_differential(1.0 / math.sqrt(spp))
        rescaled = mi.RayDifferential3f(ray)
        rescaled.o_x, rescaled.o_y, rescaled.d_x, rescaled.d_y = ray.o_x, ray.o_y, ray.d_x, ray.d_y
        rescaled.has_differentials = True
        rescaled.scale_differential(math.sqrt(spp))
        si = scene.ray_intersect(rescaled)
        si.compute_uv_partials(rescaled)
        _, dx_rs, dy_rs = camera_rs_footprint(px, py)
        size = max(np.linalg.norm(dx_rs), np.linalg.norm(dy_rs))
        assert np.linalg.norm(np.array(si.duv_dx) - dx_rs) < 2e-4 * size
        assert np.linalg.norm(np.array(si.duv_dy) - dy_rs) < 2e-4 * size

        wi = np.array(si.wi, dtype=np.float64)
        wo32 = si.to_local(mi.Vector3f(to_light))
        wo = np.array(wo32, dtype=np.float64)
        s = 0.5  # uv_scale
        uv = np.array(si.uv, dtype=np.float64) * s
        dx = np.array(si.duv_dx, dtype=np.float64) * s
        dy = np.array(si.duv_dy, dtype=np.float64) * s
        f_hat = reference.eval(wi, wo, uv, dx, dy)["f_hat"]
        nonzero += f_hat > 0
        assert bsdf.brdf(si, wo32) == pytest.approx(f_hat, rel=1e-9, abs=0)
        cos_o = wo[2] / np.linalg.norm(wo)
        value = np.array(bsdf.eval(mi.BSDFContext(), si, wo32))
        assert value == pytest.approx([f_hat * cos_o] * 3, rel=1e-6, abs=0)
        assert bsdf.pdf(mi.BSDFContext(), si, wo32) == pytest.approx(
            reference.pdf(wi, wo), rel=1e-9, abs=0)

        # The integrator's value: light sampling only (a delta light; BSDF samples escape).
        sampler.seed(px)
        radiance, valid, _ = integrator.sample(scene, sampler, ray)
        assert valid
        assert np.array(radiance) == pytest.approx(
            [irradiance * f_hat * cos_o] * 3, rel=1e-5, abs=1e-30)

        # Sampling weighs with f̂ at the sampled direction.
        for k in range(4):
            u = [float(np.float32(x)) for x in (0.1 + 0.2 * k, 0.37, 0.61)]  # Mitsuba's floats
            bs, weight = bsdf.sample(mi.BSDFContext(), si, u[0], mi.Point2f(u[1], u[2]))
            direct = reference.sample(wi, [u[1], u[2], u[0]])
            assert np.array(bs.wo) == pytest.approx(direct["wo"], abs=1e-6)
            assert bs.pdf == pytest.approx(direct["pdf"], rel=1e-6)
            f = np.array(bsdf.eval(mi.BSDFContext(), si, bs.wo))
            assert np.array(weight) == pytest.approx(f / bs.pdf, rel=1e-5, abs=1e-30)

        # Without uv partials (after the first bounce): the smooth limit.
        si.duv_dx, si.duv_dy = mi.Vector2f(0.0), mi.Vector2f(0.0)
        f_smooth = reference.eval(wi, wo, uv, dx, dy)["f_smooth"]
        assert bsdf.brdf(si, wo32) == pytest.approx(f_smooth, rel=1e-9, abs=0)
    print(f"f̂ > 0 in {nonzero} of {len(pixels)} pixels")
    assert nonzero >= 3, "the light should light several of the pixels' footprints"


def render_passes(floor, passes=PASSES, **kw):
    d = gm.sphere_lights_scene(RES, spp=SPP, floor=floor, hide_emitters=True, rfilter="box",
                               **kw)
    d["sensor"]["film"].update(BOX)
    scene = mi.load_dict(d)
    return np.array([np.array(mi.render(scene, seed=k))[..., 0] for k in range(passes)])


@pytest.fixture(scope="module")
def smooth_reference():
    return render_passes("roughconductor")


def test_dense_glints_average_to_roughconductor(smooth_reference):
    """(b) N = 10¹³ against Mitsuba's roughconductor at equal spp: the means of the highlight
    window agree within 3% + 4 standard errors of the paired per-pass difference (the passes
    use the same seeds, so light samples are shared)."""
    dense = render_passes("glint", particles=DENSE)
    g, r = dense.mean(axis=(1, 2)), smooth_reference.mean(axis=(1, 2))
    difference = g - r
    se = difference.std(ddof=1) / math.sqrt(PASSES)
    print(f"dense glint {g.mean():.5f} ± {g.std(ddof=1) / math.sqrt(PASSES):.5f}, "
          f"roughconductor {r.mean():.5f} ± {r.std(ddof=1) / math.sqrt(PASSES):.5f}, "
          f"difference {difference.mean():+.5f} ± {se:.5f}")
    assert r.mean() > 0.1
    assert abs(difference.mean()) <= 0.03 * r.mean() + 4 * se


def test_sparse_glints_glitter(smooth_reference):
    """(c) N = 10⁶: over the highlight (pixels above 10% of the smooth image's peak) the
    pixel variance is at least 10× the roughconductor image's at equal spp."""
    sparse = render_passes("glint", passes=1, particles=SPARSE)[0]
    smooth = smooth_reference[0]
    region = smooth_reference.mean(axis=0) > 0.1 * smooth_reference.mean(axis=0).max()
    ratio = sparse[region].var() / smooth[region].var()
    print(f"{region.sum()} pixels: variance sparse {sparse[region].var():.3f}, "
          f"smooth {smooth[region].var():.3f}, ratio {ratio:.1f}; "
          f"{np.mean(sparse[region] == 0):.0%} of the sparse pixels are black")
    assert ratio >= 10


def test_render_script_writes_an_image(tmp_path):
    out = tmp_path / "lights.png"
    run = subprocess.run([sys.executable, str(EXAMPLE / "render_sphere_lights.py"),
                          "--resolution", "16x9", "--spp", "1", "--out", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert out.stat().st_size > 0
    image = np.array(mi.Bitmap(str(out)))
    assert image.shape[:2] == (9, 16) and image.max() > 0


@pytest.mark.parametrize("plugin, name, value", [
    ("glint", "uv_scale", math.nan),
    ("glint", "uv_scale", 0.0),
    ("glint", "uv_scale", -1.0),
    ("glint", "uv_scale", math.inf),
    ("glint", "seed", 1.7),
    ("glint", "alpha", math.nan),
    ("glint", "particles", 0.5),
    ("glint", "map_filter", "cubic"),
    ("glint_direct", "footprint_scale", math.nan),
    ("glint_direct", "footprint_scale", -1.0),
    ("glint_direct", "footprint_scale", 1e300),
])
def test_plugins_refuse_bad_parameters_naming_them(plugin, name, value):
    """As the package (and glint-tracer's scene files): an error naming the parameter, never
    NaN pixels or a silently rounded seed."""
    with pytest.raises(Exception, match=rf"ValueError: \S*{name}"):
        mi.load_dict({"type": plugin, name: value})


def test_the_bsdf_takes_every_documented_material_field():
    """``expected_footprint_area``, ``pdf_quadrature``, ``pdf_points`` and ``roughness_levels``
    reach the package (Mitsuba refused them as unreferenced properties): the BSDF answers as
    the package's material with the same fields, and a bad value is named."""
    fields = {"expected_footprint_area": 1e-4, "pdf_quadrature": "qmc", "pdf_points": 16,
              "roughness_levels": 3, "particles": 1e8}
    bsdf = mi.load_dict({"type": "glint", **fields})
    reference = glint.Material(**fields)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0.3, 0.0, 0.954)
    si.uv = mi.Point2f(0.3, 0.4)
    si.duv_dx, si.duv_dy = mi.Vector2f(3e-3, 0.0), mi.Vector2f(0.0, 3e-3)
    wo = mi.Vector3f(-0.3, 0.01, 0.954)
    wi_np, wo_np = np.array(si.wi, dtype=float), np.array(wo, dtype=float)
    # The interaction's float32 uv and partials, as the plugin reads them.
    uv, dx, dy = (np.array(v, dtype=float) for v in (si.uv, si.duv_dx, si.duv_dy))
    r = reference.eval(wi_np, wo_np, uv, dx, dy)
    assert bsdf.brdf(si, wo) == r["f_hat"]
    assert bsdf.pdf(mi.BSDFContext(), si, wo) == pytest.approx(
        float(reference.pdf(wi_np, wo_np)), rel=1e-5)
    with pytest.raises(Exception, match=r"ValueError: \S*pdf_points"):
        mi.load_dict({"type": "glint", "pdf_points": 0})


def test_rows_the_package_refuses_never_become_nan():
    """A footprint the package refuses (edges beyond ±1e15 particle squares: uv_scale = 1e300)
    shades the smooth limit, as glint-tracer does; a direction it refuses shades 0."""
    bsdf = mi.load_dict({"type": "glint", "uv_scale": 1e300, "particles": 1e9})
    reference = glint.Material(particles=1e9)
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(0.3, 0.0, 0.954)
    si.uv = mi.Point2f(0.3, 0.4)
    si.duv_dx, si.duv_dy = mi.Vector2f(1e-3, 0.0), mi.Vector2f(0.0, 1e-3)
    wo = mi.Vector3f(-0.3, 0.01, 0.954)
    r = reference.eval(np.array(si.wi, dtype=float), np.array(wo, dtype=float), [0, 0],
                       [0, 0], [0, 0])
    f = bsdf.brdf(si, wo)
    assert math.isfinite(f) and f == r["f_smooth"] and f > 0
    value = np.array(bsdf.eval(mi.BSDFContext(), si, wo))
    assert np.all(np.isfinite(value)) and np.all(value > 0)
    bs, weight = bsdf.sample(mi.BSDFContext(), si, 0.3, mi.Point2f(0.4, 0.6))
    assert np.all(np.isfinite(np.array(weight)))
    si.wi = mi.Vector3f(0.0, 0.0, 0.0)
    assert bsdf.brdf(si, wo) == 0.0
