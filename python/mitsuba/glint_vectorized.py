"""glint in Mitsuba 3's vectorized variants (``llvm_ad_rgb``; written for ``cuda_ad_rgb`` too):
the ``glint`` BSDF, the ``glint_direct`` and ``glint_path`` integrators, working on whole
wavefronts through the ``glint`` package's batch calls.

``register()`` defines the plugins for the current variant and registers them;
``glint_mitsuba`` calls it on import when a vectorized variant is set. The conventions are
the scalar plugin's (``glint_mitsuba.py``): local frame, ``si.wi`` is glint's ``wi``, ``eval``
includes cos θ_o, the pixel footprint comes from the camera's ray differential at the first
hit (``si.compute_uv_partials``), and a glint BSDF shades f̂ where the interaction carries uv
partials and its smooth limit elsewhere.

In a vectorized variant a Python BSDF receives a wavefront: its arrays are gathered to NumPy
(``.numpy()``, one row per lane), answered by one batch call of the package for the active
lanes (the package answers rows in parallel, keeping neighbouring footprints on one thread),
and returned as ``mi.Float``/``mi.Color3f``. The integrators call BSDFs with
``dr.JitFlag.SymbolicCalls`` off (a Python method cannot be traced symbolically) and loop over
bounces in Python, each bounce evaluated at once. Mitsuba's own ``path`` integrator also runs
Python BSDFs (with ``SymbolicLoops`` and ``SymbolicCalls`` off) but leaves the uv partials at
zero: glint BSDFs then shade their smooth limit.

Rows the package reports as errors never become NaN: a footprint it refuses shades the smooth
limit (as glint-tracer does), a direction it refuses shades 0.
"""

import math

import drjit as dr
import mitsuba as mi
import numpy as np

import glint

_BELOW_ONE = math.nextafter(1.0, 0.0)
_MAX_DOUBLE = float(np.finfo(np.float64).max)
#: The largest ``footprint_scale``, as glint-tracer's (a footprint of 10⁶ pixels).
_MAX_FOOTPRINT_SCALE = 1e6


def scale_parameter(name, value, lowest, highest, zero=False):
    """A positive scale in (lowest, highest] (or 0 when ``zero``), else ``ValueError`` naming
    it, as the package names a material parameter."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a number, not {value!r}")
    value = float(value)
    if not ((zero and value == 0.0) or lowest < value <= highest):
        allowed = f"{'0 or ' if zero else ''}in ({lowest:g}, {highest:g}]"
        raise ValueError(f"{name} = {value!r} must be {allowed}")
    return value


def material_parameters(props):
    """The ``glint`` BSDF's parameters from Mitsuba properties: (``glint.Material`` keyword
    arguments, ``uv_scale``), both checked (``ValueError`` naming a bad one)."""

    def get(name, default):
        return props.get(name, default) if name in props else default

    uv_scale = scale_parameter("glint.uv_scale", get("uv_scale", 1.0), 0.0, _MAX_DOUBLE)
    params = dict(
        distribution=get("distribution", "beckmann"), alpha=get("alpha", 0.1),
        alpha_y=get("alpha_y", None), particles=get("particles", 1e6),
        gamma_degrees=get("gamma_degrees", None), gamma_deg=get("gamma_deg", None),
        epsilon=get("epsilon", 0.1), seed=get("seed", 0),
        multinomial=get("multinomial", "exact"),
        negligible_count=get("negligible_count", 1e-12))
    return params, uv_scale


def _rows(v, n):
    """A Mitsuba vector of k components over a wavefront as an (n, k) float64 array (a lane
    count of 1 is broadcast to n)."""
    a = np.asarray(v.numpy(), dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    return np.broadcast_to(a, (a.shape[0], n)).T


def _lanes(x, n):
    a = np.asarray(x.numpy()) if hasattr(x, "numpy") else np.asarray(x)
    return np.broadcast_to(a.reshape(-1), (n,)) if a.size in (1, n) else a


def _width(*values):
    return max(dr.width(v) if not isinstance(v, (bool, int, float)) else 1 for v in values)


def _float(a):
    return mi.Float(np.ascontiguousarray(a, dtype=np.float32))


def register():
    """Defines the plugins for the current (vectorized) variant and registers them as
    ``glint``, ``glint_direct`` and ``glint_path``; returns the three classes."""
    variant = mi.variant()
    if variant is None or variant.startswith("scalar_") or "rgb" not in variant:
        raise ImportError(f"glint_vectorized needs a vectorized RGB variant, not {variant}")
    flags = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
             | mi.BSDFFlags.SpatiallyVarying)

    class GlintBSDF(mi.BSDF):
        """The discrete multiscale BRDF (f̂, Eq. 5) of ``glint.Material``, on wavefronts.

        .. list-table::
           :header-rows: 1

           * - name
             - type
             - default
             - meaning
           * - distribution
             - string
             - beckmann
             - ``beckmann`` or ``ggx``
           * - alpha, alpha_y
             - float
             - 0.1, = alpha
             - roughness
           * - particles
             - float
             - 1e6
             - N per unit texture square
           * - gamma_degrees
             - float
             - 1
             - cone radius γ
           * - epsilon, seed, multinomial
             - float, int, string
             - 0.1, 0, exact
             - as ``glint.Material``
           * - negligible_count
             - float
             - 1e-12
             - skip queries provably below this expected count (0: never)
           * - uv_scale
             - float
             - 1
             - texture repetitions per unit of the shape's (u, v)

        Every parameter is checked (``ValueError`` naming it). F = 1. Sampling uses the glint
        sampler's three-number form u = (sample2.x, sample2.y, sample1), as the scalar plugin.
        """

        def __init__(self, props):
            super().__init__(props)
            self.params, self.uv_scale = material_parameters(props)
            self.material = glint.Material(**self.params)
            self.m_components = [flags]
            self.m_flags = flags

        # -- over NumPy rows (also used by the tests) --------------------------------------

        def footprint_rows(self, si, n):
            """(uv, duv_dx, duv_dy) · uv_scale as (n, 2) float64 rows, and the mask of rows
            that carry uv partials."""
            dx, dy = _rows(si.duv_dx, n), _rows(si.duv_dy, n)
            has = np.any(dx != 0, axis=1) | np.any(dy != 0, axis=1)
            s = self.uv_scale
            return _rows(si.uv, n) * s, dx * s, dy * s, has

        def brdf_rows(self, wi, wo, uv, dx, dy, has):
            """f (no cosine) per row: f̂ where ``has``, f_smooth elsewhere and where the
            package refuses the footprint, 0 where it refuses the directions."""
            n = len(wi)
            zero = np.zeros((n, 2))
            uv = np.where(has[:, None], uv, zero)
            dx = np.where(has[:, None], dx, zero)
            dy = np.where(has[:, None], dy, zero)
            r = self.material.eval(wi, wo, uv, dx, dy, expected_count=False)
            ok = r["error"] == ""
            f = np.where(ok, np.where(has, r["f_hat"], r["f_smooth"]), 0.0)
            refused = has & ~ok
            if np.any(refused):
                k = np.flatnonzero(refused)
                s = self.material.eval(wi[k], wo[k], zero[k], zero[k], zero[k],
                                       expected_count=False)
                f[k] = np.where(s["error"] == "", s["f_smooth"], 0.0)
            return np.nan_to_num(f, nan=0.0, posinf=0.0, neginf=0.0)

        def _gather(self, ctx, si, wo, active):
            n = _width(si.wi, si.uv, active, *([] if wo is None else [wo]))
            on = np.array(_lanes(active, n), dtype=bool)
            on &= bool(ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 0))
            wi = _rows(si.wi, n)
            on &= wi[:, 2] > 0
            wo_rows = None
            if wo is not None:
                wo_rows = _rows(wo, n)
                on &= wo_rows[:, 2] > 0
            return n, on, wi, wo_rows

        def _value_pdf(self, ctx, si, wo, active, value=True, pdf=True):
            n, on, wi, w = self._gather(ctx, si, wo, active)
            f, p = np.zeros(n), np.zeros(n)
            k = np.flatnonzero(on)
            if len(k):
                if value:
                    uv, dx, dy, has = self.footprint_rows(si, n)
                    cos_o = w[k, 2] / np.linalg.norm(w[k], axis=1)
                    f[k] = self.brdf_rows(wi[k], w[k], uv[k], dx[k], dy[k], has[k]) * cos_o
                if pdf:
                    q = self.material.pdf(wi[k], w[k])
                    p[k] = np.where(np.isfinite(q), q, 0.0)
            return f, p

        # -- the mi.BSDF interface -------------------------------------------------------------

        def eval(self, ctx, si, wo, active=True):
            f, _ = self._value_pdf(ctx, si, wo, active, pdf=False)
            return mi.Color3f(_float(f))

        def pdf(self, ctx, si, wo, active=True):
            _, p = self._value_pdf(ctx, si, wo, active, value=False)
            return _float(p)

        def eval_pdf(self, ctx, si, wo, active=True):
            f, p = self._value_pdf(ctx, si, wo, active)
            return mi.Color3f(_float(f)), _float(p)

        def sample(self, ctx, si, sample1, sample2, active=True):
            n, on, wi, _ = self._gather(ctx, si, None, active)
            n = max(n, _width(sample1, sample2))
            if len(on) != n:
                on = np.broadcast_to(on, (n,)).copy()
                wi = np.broadcast_to(wi, (n, 3))
            wo = np.zeros((n, 3))  # where nothing is sampled (pdf 0), as the scalar plugin
            pdf, weight = np.zeros(n), np.zeros(n)
            k = np.flatnonzero(on)
            if len(k):
                u2 = _rows(sample2, n)[k]
                u1 = np.asarray(_lanes(sample1, n), dtype=np.float64)[k]
                u = np.minimum(np.stack([u2[:, 0], u2[:, 1], u1], axis=1), _BELOW_ONE)
                s = self.material.sample(wi[k], u)
                good = ((s["error"] == "") & np.all(np.isfinite(s["wo"]), axis=1)
                        & (s["pdf"] > 0))
                k, s_wo, s_pdf = k[good], s["wo"][good], s["pdf"][good]
                smooth = s["smooth_weight"][good]
                if len(k):
                    # Where there is no footprint, the package's smooth weight (bit for bit
                    # the scalar plugin's); with one, f̂·cos θ_o / pdf at the sampled wo.
                    weight[k] = smooth
                    uv, dx, dy, has = self.footprint_rows(si, n)
                    j = np.flatnonzero(has[k])
                    if len(j):
                        w = s_wo[j]
                        f = self.brdf_rows(wi[k[j]], w, uv[k[j]], dx[k[j]], dy[k[j]],
                                           has[k[j]])
                        weight[k[j]] = f * w[:, 2] / np.linalg.norm(w, axis=1) / s_pdf[j]
                    wo[k], pdf[k] = s_wo, s_pdf
            weight = np.nan_to_num(weight, nan=0.0, posinf=0.0, neginf=0.0)
            bs = dr.zeros(mi.BSDFSample3f, n)
            bs.wo = mi.Vector3f(_float(wo[:, 0]), _float(wo[:, 1]), _float(wo[:, 2]))
            bs.pdf = _float(pdf)
            bs.eta = mi.Float(1.0)
            bs.sampled_component = mi.UInt32(0)
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            return bs, mi.Color3f(_float(weight))

        def traverse(self, callback):
            pass

        def to_string(self):
            fields = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
            return f"GlintBSDF[{fields}, uv_scale={self.uv_scale!r}] (vectorized)"

    def power_heuristic(a, b):
        a2, b2 = dr.square(a), dr.square(b)
        return dr.select(a2 > 0, a2 / (a2 + b2), 0.0)

    def footprint_ray(ray, sampler, footprint_scale):
        """The camera ray with differentials spanning ``footprint_scale`` pixels (Mitsuba's
        film loop scaled them by 1/√spp)."""
        if ray.has_differentials and footprint_scale > 0:
            ray.scale_differential(footprint_scale * math.sqrt(sampler.sample_count()))
        return ray

    def integrator_parameters(name, props):
        scale = scale_parameter(
            f"{name}.footprint_scale",
            props.get("footprint_scale", 1.0) if "footprint_scale" in props else 1.0,
            0.0, _MAX_FOOTPRINT_SCALE, zero=True)
        hide = bool(props.get("hide_emitters", False) if "hide_emitters" in props else False)
        return scale, hide

    class GlintDirectIntegrator(mi.SamplingIntegrator):
        """Direct illumination (emission and one bounce), light and BSDF sampling combined by
        MIS (power heuristic), as glint-tracer's ``direct`` with ``light_strategy = "mis"``,
        on wavefronts; glint BSDFs see the pixel footprint.

        ============== ======= ======= ===================================================
        name           type    default meaning
        ============== ======= ======= ===================================================
        footprint_scale float  1       footprint size in pixels (0: none, smooth limit)
        hide_emitters  bool    false   hide directly visible emitters
        samples_per_pass int   all     samples per pixel per pass (bounds memory)
        ============== ======= ======= ===================================================
        """

        def __init__(self, props):
            super().__init__(props)
            self.footprint_scale, self.hide = integrator_parameters("glint_direct", props)

        def sample(self, scene, sampler, ray, medium=None, active=True):
            ray = footprint_ray(ray, sampler, self.footprint_scale)
            si = scene.ray_intersect(ray, active)
            valid = si.is_valid()
            result = mi.Color3f(0.0)
            if not self.hide:
                result += si.emitter(scene, valid).eval(si, valid)
            if self.footprint_scale > 0:
                si.compute_uv_partials(ray)
            ctx = mi.BSDFContext()
            with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
                result += direct_light(scene, sampler, si, ctx, valid)
                value, _, _ = bsdf_sample_emission(scene, sampler, si, ctx, valid,
                                                   self.footprint_scale > 0,
                                                   lambda si_next, hit: hit)
                result += value
            return result, valid, []

        def aov_names(self):
            return []

        def to_string(self):
            return f"GlintDirectIntegrator[footprint_scale={self.footprint_scale}] (vectorized)"

    def direct_light(scene, sampler, si, ctx, active):
        """Light sampling at si, weighted by MIS against the BSDF's pdf."""
        bsdf = si.bsdf()
        active = active & mi.has_flag(bsdf.flags(), mi.BSDFFlags.Smooth)
        ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(active), True,
                                                       active)
        # Occluded samples (zero weight) cost no BSDF query, as in glint-tracer.
        active &= (ds.pdf != 0) & dr.any(em_weight != 0)
        wo = si.to_local(ds.d)
        value, bsdf_pdf = bsdf.eval_pdf(ctx, si, wo, active)
        mis = dr.select(ds.delta, 1.0, power_heuristic(ds.pdf, bsdf_pdf))
        return dr.select(active, em_weight * value * mis, 0.0)

    def bsdf_sample_emission(scene, sampler, si, ctx, active, footprint, needed):
        """A BSDF sample at si: (the emission it reaches weighted by MIS, (the sample, its
        weight, the next interaction), the lanes whose ray left).

        With ``footprint`` (si carries uv partials), the direction is sampled without them and
        f at that direction is evaluated with them only where the ray's end needs it
        (``needed(si_next)``: an emitter for direct light, any surface for a path), as
        glint-tracer traces a BSDF sample's ray before its f: rays that escape cost no glint
        query. The weight is then f·cos θ_o / pdf (the sample's own weight for delta lobes)."""
        bsdf = si.bsdf()
        at = si
        if footprint:
            at = mi.SurfaceInteraction3f(si)
            at.duv_dx, at.duv_dy = mi.Vector2f(0.0), mi.Vector2f(0.0)
        bs, weight = bsdf.sample(ctx, at, sampler.next_1d(active), sampler.next_2d(active),
                                 active)
        active = active & (bs.pdf > 0)
        ray = si.spawn_ray(si.to_world(bs.wo))
        si_next = scene.ray_intersect(ray, active)
        emitter = si_next.emitter(scene, active)
        hit = active & (emitter != None)  # noqa: E711  (a drjit mask)
        delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        if footprint:
            need = active & needed(si_next, hit) & ~delta
            value = bsdf.eval(ctx, si, bs.wo, need)
            weight = dr.select(delta, weight, dr.select(need, value / bs.pdf, 0.0))
        ds = mi.DirectionSample3f(scene, si_next, si)
        light_pdf = dr.select(delta, 0.0, scene.pdf_emitter_direction(si, ds, hit & ~delta))
        value = dr.select(hit, weight * emitter.eval(si_next, hit)
                          * power_heuristic(bs.pdf, light_pdf), 0.0)
        return value, (bs, weight, si_next, ray), active

    class GlintPathIntegrator(mi.SamplingIntegrator):
        """Path tracing with emitter sampling and MIS (power heuristic) as Mitsuba's ``path``,
        on wavefronts, giving glint BSDFs the pixel footprint at the first hit and their smooth
        limit after (glint-tracer's ``glint_footprints = "first_hit"``).

        ================ ======= ======= ================================================
        name             type    default meaning
        ================ ======= ======= ================================================
        max_depth        int     6       longest path, in vertices (−1: unbounded)
        rr_depth         int     5       depth where Russian roulette starts
        footprint_scale  float   1       footprint size in pixels (0: none)
        hide_emitters    bool    false   hide directly visible emitters
        samples_per_pass int     all     samples per pixel per pass (bounds memory)
        ================ ======= ======= ================================================
        """

        def __init__(self, props):
            super().__init__(props)
            self.footprint_scale, self.hide = integrator_parameters("glint_path", props)
            self.max_depth = int(props.get("max_depth", 6) if "max_depth" in props else 6)
            self.rr_depth = int(props.get("rr_depth", 5) if "rr_depth" in props else 5)
            if self.max_depth < -1:
                raise ValueError(f"glint_path.max_depth = {self.max_depth} must be ≥ -1")
            if self.rr_depth < 1:
                raise ValueError(f"glint_path.rr_depth = {self.rr_depth} must be ≥ 1")

        def sample(self, scene, sampler, ray, medium=None, active=True):
            ray = footprint_ray(ray, sampler, self.footprint_scale)
            ctx = mi.BSDFContext()
            result = mi.Color3f(0.0)
            throughput = mi.Color3f(1.0)
            eta = mi.Float(1.0)
            si = scene.ray_intersect(ray, active)
            valid = si.is_valid()
            active = mi.Bool(valid)
            if not self.hide:
                result += si.emitter(scene, active).eval(si, active)
            if self.footprint_scale > 0:
                si.compute_uv_partials(ray)
            depth = 1
            max_depth = self.max_depth if self.max_depth >= 0 else 1 << 30
            with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
                while depth < max_depth:
                    # Emitter sampling, and a BSDF sample whose emission is MIS-weighted.
                    result += throughput * direct_light(scene, sampler, si, ctx, active)
                    value, (bs, weight, si_next, _), moving = bsdf_sample_emission(
                        scene, sampler, si, ctx, active, depth == 1 and self.footprint_scale > 0,
                        lambda si_next, hit: si_next.is_valid())
                    result += throughput * value
                    throughput *= weight
                    eta *= bs.eta
                    active = moving & si_next.is_valid() & dr.any(throughput != 0)
                    depth += 1
                    if depth >= self.rr_depth:
                        q = dr.minimum(dr.max(throughput) * dr.square(eta), 0.95)
                        survive = sampler.next_1d(active) < q
                        throughput = dr.select(survive, throughput / q, throughput)
                        active &= survive
                    si = si_next  # no uv partials after the first hit: the smooth limit
                    dr.eval(result, throughput, active, si)
                    if not dr.any(active):
                        break
            return result, valid, []

        def aov_names(self):
            return []

        def to_string(self):
            return (f"GlintPathIntegrator[max_depth={self.max_depth}, "
                    f"footprint_scale={self.footprint_scale}] (vectorized)")

    mi.register_bsdf("glint", lambda props: GlintBSDF(props))
    mi.register_integrator("glint_direct", lambda props: GlintDirectIntegrator(props))
    mi.register_integrator("glint_path", lambda props: GlintPathIntegrator(props))
    return GlintBSDF, GlintDirectIntegrator, GlintPathIntegrator
