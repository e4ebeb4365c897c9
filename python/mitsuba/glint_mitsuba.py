"""glint in Mitsuba 3: a ``glint`` BSDF plugin backed by the ``glint`` package, a
``glint_direct`` integrator that gives it pixel footprints, and a small version of the
sphere-lights scene (``scenes/sphere_lights.toml``, Fig. 4 of Jakob et al. 2014).

Importing this module selects the variant ``scalar_rgb`` unless one is already set, and
registers the plugins for it: in a ``scalar_*`` RGB variant the ones below (the plugins call the
package once per shading query), in a vectorized RGB variant (``llvm_ad_rgb``, ``cuda_ad_rgb``)
those of ``glint_vectorized.py`` (``glint``, ``glint_direct`` and ``glint_path``), which answer
whole wavefronts with one batch call of the package. ``llvm_*`` variants need LLVM 19's
``libLLVM.so`` (Debian: ``apt-get install libllvm19``, then ``DRJIT_LIBLLVM_PATH`` set to the
``libLLVM.so.19.1`` that ``dpkg -L libllvm19`` lists): with LLVM 15 or 16 Mitsuba 3.9's JIT
aborts.

Conventions (Mitsuba 3.9, checked against its ``roughconductor``): BSDF methods work in the local
shading frame (z = the normal); ``si.wi`` points away from the surface toward the previous
vertex and ``wo`` away from it toward the next, which are glint's ``wi`` and ``wo``.
``eval`` returns f·cos θ_o (the cosine foreshortening of ``wo`` is included), ``sample``'s
weight is f·cos θ_o / pdf, ``pdf`` is per unit solid angle.

Footprints: Mitsuba's ``path`` integrator leaves ``si.duv_dx`` and ``si.duv_dy`` at zero, and
Mitsuba's film loop scales the camera's ray differentials by 1/√spp before calling an
integrator. ``glint_direct`` undoes that scaling (the differentials then span
``footprint_scale`` pixels, 1 by default, as in glint-tracer whatever spp) and calls
``si.compute_uv_partials`` at the first hit, which is glint-tracer's ``texture_footprint``
(the offset rays met with the tangent plane, solved for (u, v) by least squares). Mitsuba's
offset rays start at the main ray's near-clip point rather than at the eye, so footprints come
out smaller by near_clip/distance: the scene here sets ``near_clip`` to 10⁻⁴. A ``glint``
BSDF evaluates f̂ when the interaction carries uv partials and its smooth limit f otherwise
(after the first bounce, as the paper does).
"""

import contextlib
import math
import sys
from pathlib import Path

import mitsuba as mi
import numpy as np

import glint

sys.path.insert(0, str(Path(__file__).resolve().parent))
from glint_vectorized import material_parameters  # noqa: E402
from glint_vectorized import scale_parameter as _scale  # noqa: E402

if mi.variant() is None:
    mi.set_variant("scalar_rgb")
if "rgb" not in mi.variant():
    raise ImportError(f"glint_mitsuba supports RGB variants, not {mi.variant()}")
#: Whether the plugins are the vectorized ones (``glint_vectorized.py``).
VECTORIZED = not mi.variant().startswith("scalar_")

_BELOW_ONE = math.nextafter(1.0, 0.0)
#: The largest ``footprint_scale``, as glint-tracer's (a footprint of 10⁶ pixels).
_MAX_FOOTPRINT_SCALE = 1e6
_FLAGS = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
          | mi.BSDFFlags.SpatiallyVarying)


def _vec(v):
    return np.array([v[0], v[1], v[2]], dtype=np.float64)


class GlintBSDF(mi.BSDF):
    """The discrete multiscale BRDF (f̂, Eq. 5) of ``glint.Material``.

    Parameters: ``distribution`` ("beckmann"), ``alpha`` (0.1), ``alpha_y`` (= alpha),
    ``particles`` (1e6), ``gamma_degrees`` (1; ``gamma_deg``, its older name, still works,
    deprecated), ``epsilon`` (0.1), ``seed`` (0), ``multinomial``
    ("exact"), ``negligible_count`` (1e-12), ``expected_footprint_area`` (1e-6),
    ``pdf_quadrature`` ("cubature", or "qmc"), ``pdf_points`` (64), ``dense`` ("lattice",
    "sampled" or "exact"), ``dense_node_scale`` (1), ``roughness_levels`` (8;
    without an ``alpha_map`` it changes nothing), ``map_filter`` ("nearest", or "bilinear":
    how ``density_map`` and ``alpha_map`` are reconstructed between texels; ``tint_map`` stays
    nearest): as ``glint.Material``, which checks them (an
    invalid one raises ``ValueError`` naming it); ``uv_scale`` (1): texture repetitions per
    unit of the shape's (u, v), positive and finite, as in the scene files. F = 1 (no Fresnel).

    Maps (none by default): ``density_map``, ``alpha_map`` and ``tint_map``, each a ``bitmap``
    texture or an image filename, read by ``glint_maps.py`` (which states what is read and how
    texels are placed) into ``glint.Material``'s maps; they tile with the texture square, so
    ``uv_scale`` scales them with the flakes. With maps, the smooth limit, the sampler and its
    pdf are the material's at the interaction's texture position (``glint.Material`` with
    ``uv``); a coloured tint answers in colour.

    Sampling: Mitsuba gives three numbers (``sample1``, ``sample2``); the glint sampler takes
    them in its three-number form u = (sample2.x, sample2.y, sample1): the 2-D sample chooses
    the facet normal of the widened lobe, and ``sample1``'s bits are split into the cone's two
    numbers (docs/eval.md). ``sample1`` is a float32 here, so each cone number has 12 bits (a
    4096 × 4096 grid over the cone of radius γ). The weight is f̂·cos θ_o / pdf at the
    sampled direction when the interaction has a footprint, f·cos θ_o / pdf otherwise.
    """

    def __init__(self, props):
        super().__init__(props)

        # uv_scale as in scene files (positive and finite, glint-tracer's); the package
        # checks every material parameter, naming it (a seed of 1.7 is an error, not 1).
        self.params, self.maps, self.map_sources, self.uv_scale = material_parameters(props)
        self.material = glint.Material(**self.params, **self.maps)
        self.m_components = [_FLAGS]
        self.m_flags = _FLAGS

    # -- helpers over float64 numbers (also used by the tests) --------------------------------

    def footprint(self, si):
        """(uv, duv_dx, duv_dy) · uv_scale as float64, or None when si has no uv partials."""
        dx, dy = np.array([si.duv_dx[0], si.duv_dx[1]]), np.array([si.duv_dy[0], si.duv_dy[1]])
        if not (np.any(dx != 0) or np.any(dy != 0)):
            return None
        s = self.uv_scale
        return np.array([si.uv[0], si.uv[1]]) * s, dx * s, dy * s

    def texture_position(self, si):
        """Where a material with maps is read: si.uv · uv_scale as float64 (None without
        maps: the answers do not depend on it)."""
        if not self.maps:
            return None
        return np.array([si.uv[0], si.uv[1]]) * self.uv_scale

    def brdf(self, si, wo):
        """f (no cosine) at (si.wi, wo): f̂ with si's footprint, the smooth limit without
        (at si's texture position, for a material with maps), and also where the package
        refuses the footprint (an edge beyond ±1e15 texture units, where glint-tracer shades
        the smooth limit too); 0 where it refuses the directions. A float, or an (r, g, b)
        array for a coloured tint. A row the package reports as an error never becomes a NaN
        pixel."""
        wi, wo = _vec(si.wi), _vec(wo)
        fp = self.footprint(si)
        if fp is not None:
            r = self.material.eval(wi, wo, *fp)
            if r["error"] == "":
                return _value(r["f_hat"])
        at = self.texture_position(si)
        zero = [0.0, 0.0]
        r = self.material.eval(wi, wo, zero if at is None else at, zero, zero)
        return _value(r["f_smooth"]) if r["error"] == "" else 0.0

    def _active(self, ctx, si, active):
        return bool(active) and ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 0) and si.wi[2] > 0

    # -- the mi.BSDF interface -----------------------------------------------------------------

    def eval(self, ctx, si, wo, active=True):
        if not self._active(ctx, si, active) or not wo[2] > 0:
            return mi.Color3f(0.0)
        w = _vec(wo)
        return _colour(self.brdf(si, wo) * w[2] / np.linalg.norm(w))

    def pdf(self, ctx, si, wo, active=True):
        if not self._active(ctx, si, active) or not wo[2] > 0:
            return 0.0
        p = float(self.material.pdf(_vec(si.wi), _vec(wo), self.texture_position(si)))
        return p if math.isfinite(p) else 0.0

    def eval_pdf(self, ctx, si, wo, active=True):
        return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        bs = mi.BSDFSample3f()
        bs.pdf, bs.eta, bs.sampled_component = 0.0, 1.0, 0
        bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
        if not self._active(ctx, si, active):
            return bs, mi.Color3f(0.0)
        u = [min(float(x), _BELOW_ONE) for x in (sample2[0], sample2[1], sample1)]
        at = self.texture_position(si)
        if at is None:
            s = self.material.sample(_vec(si.wi), u)
        else:
            # A material with maps samples (and weighs) its lobes at the texture position; the
            # package takes it with a footprint, here an empty one (its f̂ is not used).
            s = self.material.sample(_vec(si.wi), u, at, [0.0, 0.0], [0.0, 0.0])
        if not (np.all(np.isfinite(s["wo"])) and s["pdf"] > 0):
            return bs, mi.Color3f(0.0)
        bs.wo = mi.Vector3f(*s["wo"])
        bs.pdf = float(s["pdf"])
        if self.footprint(si) is None:
            weight = _value(s["smooth_weight"])
        else:
            wo = _vec(bs.wo)
            weight = self.brdf(si, bs.wo) * wo[2] / np.linalg.norm(wo) / float(s["pdf"])
        return bs, _colour(weight)

    def to_string(self):
        fields = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
        maps = "".join(f", {k}={v}" for k, v in self.map_sources.items())
        return f"GlintBSDF[{fields}{maps}, uv_scale={self.uv_scale!r}]"


def _value(f):
    """A package answer as the plugin's BRDF value: a float when grey, else an (r, g, b)
    float64 array."""
    return float(f) if np.ndim(f) == 0 else np.asarray(f, dtype=np.float64)


def _colour(f):
    """mi.Color3f of a float or an (r, g, b) array."""
    return mi.Color3f(f) if np.ndim(f) == 0 else mi.Color3f(*(float(c) for c in f))


def _power_heuristic(a, b):
    a2, b2 = a * a, b * b
    return a2 / (a2 + b2) if a2 > 0 else 0.0


class GlintDirectIntegrator(mi.SamplingIntegrator):
    """Direct illumination (emission and one bounce), light and BSDF sampling combined by MIS
    (power heuristic), as glint-tracer's ``direct`` integrator with ``light_strategy = "mis"``.

    At the first hit it computes the uv partials from the camera's ray differential, rescaled
    to span ``footprint_scale`` pixels (default 1; at most 10⁶, as in glint-tracer), so glint
    BSDFs see the pixel footprint; ``footprint_scale = 0`` computes none, so glint BSDFs use
    their smooth limit everywhere (glint-tracer's ``glint_footprints = "never"``). NaN,
    negative and larger values are refused, naming the parameter.
    ``hide_emitters`` (false) hides directly visible emitters.
    """

    def __init__(self, props):
        super().__init__(props)
        self.footprint_scale = _scale(
            "glint_direct.footprint_scale",
            props.get("footprint_scale", 1.0) if "footprint_scale" in props else 1.0,
            0.0, _MAX_FOOTPRINT_SCALE, zero=True)
        self.hide = bool(props.get("hide_emitters", False)
                         if "hide_emitters" in props else False)

    def sample(self, scene, sampler, ray, medium=None, active=True):
        black = mi.Color3f(0.0)
        if not active:
            return black, False, []
        if ray.has_differentials:
            # Mitsuba's film loop scaled them by 1/√spp; make them footprint_scale pixels.
            # (The copy constructor drops the differentials: copy them by hand.)
            copy = mi.RayDifferential3f(ray)
            copy.o_x, copy.o_y, copy.d_x, copy.d_y = ray.o_x, ray.o_y, ray.d_x, ray.d_y
            copy.has_differentials = True
            copy.scale_differential(self.footprint_scale * math.sqrt(sampler.sample_count()))
            ray = copy
        si = scene.ray_intersect(ray)
        if not si.is_valid():
            return black, False, []
        result = mi.Color3f(0.0)
        emitter = si.emitter(scene)
        if emitter is not None and not self.hide:
            result += emitter.eval(si)
        if ray.has_differentials and self.footprint_scale > 0:
            si.compute_uv_partials(ray)
        bsdf = si.bsdf(ray)
        ctx = mi.BSDFContext()

        # Light sampling.
        ds, light_weight = scene.sample_emitter_direction(si, sampler.next_2d(), True)
        if ds.pdf > 0 and any(c != 0 for c in light_weight):
            value, bsdf_pdf = bsdf.eval_pdf(ctx, si, si.to_local(ds.d))
            mis = 1.0 if ds.delta else _power_heuristic(ds.pdf, bsdf_pdf)
            result += light_weight * value * mis

        # BSDF sampling.
        bs, weight = bsdf.sample(ctx, si, sampler.next_1d(), sampler.next_2d())
        if bs.pdf > 0 and any(c != 0 for c in weight):
            si_light = scene.ray_intersect(si.spawn_ray(si.to_world(bs.wo)))
            hit = si_light.emitter(scene) if si_light.is_valid() else None
            if hit is not None:
                delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
                light_pdf = 0.0 if delta else scene.pdf_emitter_direction(
                    si, mi.DirectionSample3f(scene, si_light, si))
                result += weight * hit.eval(si_light) * _power_heuristic(bs.pdf, light_pdf)
        return result, True, []

    def aov_names(self):
        return []

    def to_string(self):
        return f"GlintDirectIntegrator[footprint_scale={self.footprint_scale}]"


if VECTORIZED:
    import glint_vectorized  # noqa: E402

    GlintBSDF, GlintDirectIntegrator, GlintPathIntegrator = glint_vectorized.register()
else:
    mi.register_bsdf("glint", lambda props: GlintBSDF(props))
    mi.register_integrator("glint_direct", lambda props: GlintDirectIntegrator(props))


# -- the scene -----------------------------------------------------------------------------------

#: The four sphere lights of scenes/sphere_lights.toml: (centre, radius); 20 W each.
SPHERE_LIGHTS = [((-1.8, 1.0, -4.0), 0.02), ((-0.6, 1.0, -4.0), 0.06),
                 ((0.6, 1.0, -4.0), 0.15), ((1.8, 1.0, -4.0), 0.35)]
LIGHT_POWER = 20.0
EXPOSURE = -2.5


def sphere_lights_scene(resolution=(48, 27), spp=4, floor="glint", *, particles=1e9,
                        gamma_degrees=0.5, alpha=0.1, epsilon=0.1, seed=1, uv_scale=0.5,
                        negligible_count=1e-12, footprint_scale=1.0, hide_emitters=False,
                        rfilter="gaussian", sampler_seed=0, integrator="glint_direct",
                        max_depth=6, density_map=None):
    """A Mitsuba scene dict of ``scenes/sphere_lights.toml`` (frame 0), small by default.

    ``floor``: "glint" (the ``glint`` BSDF with the scene's material) or "roughconductor"
    (Mitsuba's, Beckmann with the same α, ``material: none`` = η 0 + 1i, hence F = 1, and its
    default visible-normal sampling). The floor's (u, v) are the scene file's: (0, 0) at
    (−20, 0, 20), u along +x, v along −z, normal +y. Lights: radiance Φ/(4π²r²), Φ = 20 W.
    Mitsuba's roughconductor uses the separable Smith G1(wi)·G1(wo), glint the
    height-correlated G2; at α = 0.1 and this view (θ ≈ 77°) they differ by ~10⁻⁴.

    ``integrator``: "glint_direct", "glint_path" (vectorized variants only; ``max_depth``) or
    Mitsuba's "path". Render it with ``render`` (below) to bound memory.

    ``density_map``: the glint floor's ``density_map`` (a bitmap texture dict or an image
    filename; ``stripes_density_map()`` gives bands across the view), tiling with the floor's
    texture square (``uv_scale`` = 0.5: one square per 80 m). Not for the roughconductor floor.
    """
    width, height = resolution
    if floor == "glint":
        bsdf = {"type": "glint", "distribution": "beckmann", "alpha": alpha,
                "particles": float(particles), "gamma_degrees": gamma_degrees, "epsilon": epsilon,
                "seed": int(seed), "uv_scale": uv_scale,
                "negligible_count": negligible_count}
        if density_map is not None:
            bsdf["density_map"] = density_map
    elif floor == "roughconductor":
        if density_map is not None:
            raise ValueError("density_map is for the glint floor: roughconductor has none")
        bsdf = {"type": "roughconductor", "distribution": "beckmann", "alpha": alpha,
                "material": "none"}
    else:
        raise ValueError(f"floor must be 'glint' or 'roughconductor', not {floor!r}")
    T = mi.ScalarTransform4f
    if integrator == "path":
        integrator_dict = {"type": "path", "max_depth": max_depth,
                           "hide_emitters": hide_emitters}
    elif integrator in ("glint_direct", "glint_path"):
        integrator_dict = {"type": integrator, "footprint_scale": footprint_scale,
                           "hide_emitters": hide_emitters}
        if integrator == "glint_path":
            integrator_dict["max_depth"] = max_depth
    else:
        raise ValueError(f"integrator must be 'glint_direct', 'glint_path' or 'path', "
                         f"not {integrator!r}")
    scene = {
        "type": "scene",
        "integrator": integrator_dict,
        "sensor": {
            "type": "perspective", "fov": 40.0, "fov_axis": "y",
            # Mitsuba starts all three rays of a differential at the main ray's near-clip
            # point, which shrinks footprints by near_clip/distance (0.3% at the default 1 cm).
            "near_clip": 1e-4,
            "to_world": T().look_at(origin=[0.0, 1.0, 4.5], target=[0.0, 0.05, 0.0],
                                    up=[0.0, 1.0, 0.0]),
            "film": {"type": "hdrfilm", "width": width, "height": height,
                     "pixel_format": "rgb", "rfilter": {"type": rfilter}},
            "sampler": {"type": "independent", "sample_count": spp, "seed": sampler_seed},
        },
        # Mitsuba's rectangle is [-1, 1]² in z = 0 with uv = (x + 1, y + 1)/2: rotate local y
        # to −z and z to +y, scale to 40 m × 40 m.
        "floor": {"type": "rectangle", "bsdf": bsdf,
                  "to_world": T().rotate(axis=[1, 0, 0], angle=-90.0).scale(20.0)},
    }
    for i, (centre, radius) in enumerate(SPHERE_LIGHTS):
        radiance = LIGHT_POWER / (4.0 * math.pi ** 2 * radius ** 2)
        scene[f"light_{i}"] = {"type": "sphere", "center": list(centre), "radius": radius,
                               "emitter": {"type": "area", "radiance": {
                                   "type": "rgb", "value": [radiance] * 3}}}
    return scene


def stripes_density_map(rows=1024, period=8):
    """A density map of bands across the sphere-lights floor, as a bitmap texture dict: ``rows``
    × 2 texels (glint's texture square, 80 m of the floor at its ``uv_scale``) alternating
    ``period``/2 rows of density 1 and as many of 0 (no flakes), bands of constant v, so of
    constant depth in the view: 0.3125 m each by default. Float texels, so ``raw`` changes
    nothing; it says that they are data."""
    if not (isinstance(period, int) and period >= 2 and period % 2 == 0):
        raise ValueError(f"period = {period!r} must be an even whole number of rows ≥ 2")
    on = (np.arange(rows) // (period // 2)) % 2 == 0
    image = np.repeat(on.astype(np.float32)[:, None], 2, axis=1)[:, :, None]
    return {"type": "bitmap", "bitmap": mi.Bitmap(image), "raw": True,
            "filter_type": "nearest"}


def holds_glint(bsdf):
    """Whether ``bsdf`` is a glint BSDF or holds one among its nested BSDFs (a ``blendbsdf``'s,
    a ``twosided``'s, at any depth)."""
    if isinstance(bsdf, GlintBSDF):
        return True
    nested = []

    class Nested(mi.TraversalCallback):
        def put(self, name, value, flags):
            if isinstance(value, mi.BSDF):
                nested.append(value)

    if bsdf is not None:
        bsdf.traverse(Nested())
    return any(holds_glint(b) for b in nested)


#: The most samples a pass of ``render`` traces at once in a vectorized variant (each holds a
#: few hundred bytes in the plugins' NumPy rows and Dr.Jit's arrays: about 1 GB at this size).
MAX_WAVEFRONT = 1 << 21


def render(scene, samples_per_pass=None, seed=0):
    """``mi.render`` in passes of ``samples_per_pass`` samples per pixel (a divisor of the
    sensor's sample count), averaged, so that memory stays bounded at any resolution and spp.
    By default, in a vectorized variant, the largest divisor whose wavefront (pixels × samples
    per pass) stays within ``MAX_WAVEFRONT``; in a scalar one, all samples at once. Pass k uses
    the sampler seed ``seed + k``. Returns the image as ``mi.TensorXf``.

    (Mitsuba 3.9 deprecates its integrators' own ``samples_per_pass``; glint's integrators
    undo the film's differential scaling with the pass's sample count, so footprints stay one
    pixel whatever the split.)"""
    sensor = scene.sensors()[0]
    spp = sensor.sampler().sample_count()
    width, height = sensor.film().crop_size()
    if samples_per_pass is None:
        samples_per_pass = spp
        if VECTORIZED:
            samples_per_pass = max(k for k in range(1, spp + 1)
                                   if spp % k == 0 and (k == 1 or width * height * k
                                                        <= MAX_WAVEFRONT))
    if not (isinstance(samples_per_pass, (int, np.integer)) and not isinstance(
            samples_per_pass, bool) and 1 <= samples_per_pass <= spp
            and spp % samples_per_pass == 0):
        raise ValueError(f"samples_per_pass = {samples_per_pass!r} must be a whole divisor of "
                         f"the sample count {spp}")
    passes = spp // int(samples_per_pass)
    total = None
    python_bsdfs = VECTORIZED and any(holds_glint(shape.bsdf()) for shape in scene.shapes())
    with contextlib.ExitStack() as flags:
        if python_bsdfs:
            # Mitsuba's own integrators can call a Python BSDF only in evaluated mode.
            import drjit as dr

            flags.enter_context(dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False))
            flags.enter_context(dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False))
        # ``mi.render(spp=k)`` leaves the sampler at k samples per pixel: restore the scene's
        # count, so that the next render draws the scene's samples again.
        flags.callback(sensor.sampler().set_sample_count, spp)
        for k in range(passes):
            image = mi.render(scene, seed=seed + k, spp=int(samples_per_pass))
            total = image if total is None else total + image
    return total / passes if passes > 1 else total
