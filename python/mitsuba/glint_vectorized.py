"""glint in Mitsuba 3's vectorized variants (``llvm_ad_rgb``; written for ``cuda_ad_rgb`` too):
the ``glint`` BSDF, the ``glint_direct`` and ``glint_path`` integrators, working on whole
wavefronts through the ``glint`` package's batch calls.

``register()`` defines the plugins for the current variant and registers them;
``glint_mitsuba`` calls it on import when a vectorized variant is set. The conventions are
the scalar plugin's (``glint_mitsuba.py``): local frame, ``si.wi`` is glint's ``wi``, ``eval``
includes cos θ_o, the pixel footprint comes from the camera's ray differential at the first
hit (``si.compute_uv_partials``), and a glint BSDF shades f̂ where the interaction carries uv
partials and its smooth limit elsewhere.

In a vectorized variant a Python BSDF receives a wavefront. What needs no particles runs in
Dr.Jit's own kernels (``glint_lobe.py``, the package's formulas checked against it): the
glint sampler, its pdf by the cubature rules, and the smooth f. Only f̂ goes to the package:
the lanes that carry a footprint are compressed, packed into one (n, 12) NumPy array, answered
by one ``Material.f_hat`` call (rows in parallel, neighbouring footprints on one thread) and
scattered back; so are the rare lanes whose pdf needs the package's slope-space rule (wide
cones, cones across the horizon). ``glint_direct`` and ``glint_path`` ask for the BSDF's pdf
of a light sample only where it carries light (f̂ is 0 on most light samples of a sparse
material). The integrators call BSDFs with
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
from glint_lobe import Lobe
from glint_maps import maps_from_properties

_MAX_DOUBLE = float(np.finfo(np.float64).max)
_BELOW_ONE = math.nextafter(1.0, 0.0)
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
    arguments but the maps, the maps (``glint.Material`` keyword arguments: NumPy arrays),
    what each map was read from, ``uv_scale``), all checked (``ValueError`` naming a bad
    one; ``glint_maps.maps_from_properties`` reads the maps)."""

    def get(name, default):
        return props.get(name, default) if name in props else default

    uv_scale = scale_parameter("glint.uv_scale", get("uv_scale", 1.0), 0.0, _MAX_DOUBLE)
    params = dict(
        distribution=get("distribution", "beckmann"), alpha=get("alpha", 0.1),
        alpha_y=get("alpha_y", None), particles=get("particles", 1e6),
        gamma_degrees=get("gamma_degrees", None), gamma_deg=get("gamma_deg", None),
        epsilon=get("epsilon", 0.1), seed=get("seed", 0),
        multinomial=get("multinomial", "exact"),
        negligible_count=get("negligible_count", 1e-12),
        expected_footprint_area=get("expected_footprint_area", 1e-6),
        pdf_quadrature=get("pdf_quadrature", "cubature"), pdf_points=get("pdf_points", 64),
        roughness_levels=get("roughness_levels", 8), dense=get("dense", "lattice"),
        dense_node_scale=get("dense_node_scale", 1.0), map_filter=get("map_filter", "nearest"))
    maps, sources = maps_from_properties(props)
    return params, maps, sources, uv_scale


def _packed_rows(index, vectors):
    """The lanes ``index`` of Dr.Jit ``vectors`` as one (n, k) float64 NumPy array, k their
    components in order: packed in one Dr.Jit buffer and copied out once."""
    n = dr.width(index)
    # Gathers read memory: evaluate every source in one kernel rather than one each.
    dr.eval(*vectors)
    components = [c for v in vectors for c in v]
    k = len(components)
    packed = dr.zeros(mi.Float64, n * k)
    at = dr.arange(mi.UInt32, n) * k
    for j, c in enumerate(components):
        dr.scatter(packed, mi.Float64(dr.gather(type(c), c, index)), at + j)
    return packed.numpy().reshape(n, k)


def _width(*values):
    return max(dr.width(v) if not isinstance(v, (bool, int, float)) else 1 for v in values)


def _float(a):
    return mi.Float(np.ascontiguousarray(a, dtype=np.float32))


def _fixed_point(values):
    """round(d·2³²) as the package stores a density (Rust's ``round``: halves away from 0),
    exact: d·2³² is exact, and so is its fraction above its floor."""
    scaled = np.asarray(values, dtype=np.float64) * 2.0**32
    whole = np.floor(scaled)
    return whole + (scaled - whole >= 0.5)


class TexelLookup:
    """A glint map's texels in Dr.Jit arrays, read at texture positions as the package reads
    them (glint-tree's ``DensityMap::value_at``, glint-brdf's ``TintMap::value_at``), uv
    wrapped into the unit square: the texel holding uv (``nearest``), or (``bilinear``, a
    density only) the four texel centres around uv interpolated as
    ``DensityMap::value_at`` does, centre of texel (i, j) at ((i + ½)/W, (j + ½)/H), j counted
    from the bottom row, indices wrapping. Densities are in the package's fixed point (steps
    of 2⁻³²)."""

    def __init__(self, texels, fixed_point=False, bilinear=False):
        """``texels``: a glint map, (H, W) or (H, W, 3) float64, row 0 at the top (v near 1);
        ``bilinear`` needs ``fixed_point`` (it interpolates the fixed-point integers, as the
        package does, and scales by 2⁻³² after)."""
        if bilinear and not fixed_point:
            raise ValueError("a bilinear TexelLookup reads a density: give fixed_point=True")
        texels = np.asarray(texels, dtype=np.float64)
        self.bilinear = bilinear
        if fixed_point:
            texels = _fixed_point(texels)
            if not bilinear:
                texels = texels / 2.0**32
        self.height, self.width = texels.shape[:2]
        from_bottom = np.flipud(texels).reshape(self.height * self.width, -1)
        self.channels = [mi.Float64(np.ascontiguousarray(from_bottom[:, c]))
                         for c in range(from_bottom.shape[1])]

    def at(self, uv):
        """The map's values at ``uv`` (Vector2d), one Float64 per channel."""
        x = uv - dr.floor(uv)
        if self.bilinear:
            return self._bilinear_at(x)
        column = dr.minimum(mi.UInt32(x.x * self.width), self.width - 1)
        row = dr.minimum(mi.UInt32(x.y * self.height), self.height - 1)
        index = row * self.width + column
        return [dr.gather(mi.Float64, c, index) for c in self.channels]

    def _bilinear_at(self, x):
        """``DensityMap::value_at`` under the bilinear filter (``bilinear_fixed_at``), the
        same operations in the same order: s = x·W − ½, t = y·H − ½, i = ⌊s⌋, j = ⌊t⌋, the
        fractions fs, ft, and (1 − ft)((1 − fs)q₀₀ + fs·q₁₀) + ft((1 − fs)q₀₁ + fs·q₁₁) over
        the fixed-point texels, then divided by 2³²."""
        s = x.x * float(self.width) - 0.5
        t = x.y * float(self.height) - 0.5
        i, j = dr.floor(s), dr.floor(t)
        fs, ft = s - i, t - j
        # i ∈ [−1, W − 1] and j ∈ [−1, H − 1]: wrap by adding W (H) before the remainder.
        i, j = mi.Int32(i) + self.width, mi.Int32(j) + self.height
        columns = [mi.UInt32((i + d) % self.width) for d in (0, 1)]
        rows = [mi.UInt32((j + d) % self.height) for d in (0, 1)]

        def q(c, di, dj):
            return dr.gather(mi.Float64, c, rows[dj] * self.width + columns[di])

        return [((1.0 - ft) * ((1.0 - fs) * q(c, 0, 0) + fs * q(c, 1, 0))
                 + ft * ((1.0 - fs) * q(c, 0, 1) + fs * q(c, 1, 1))) / 2.0**32
                for c in self.channels]


def _rows_finite(f):
    """Rows of the package's answers ((n,) or (n, 3)) that are finite."""
    return np.isfinite(f) if f.ndim == 1 else np.all(np.isfinite(f), axis=1)


def _where(rows, f, other):
    """``f`` on the ``rows`` (a mask of n), ``other`` elsewhere, for (n,) or (n, 3) answers."""
    return np.where(rows if np.ndim(f) == 1 else rows[:, None], f, other)


def _finite(value):
    """The lanes where a Float or Color3f value is finite (every channel)."""
    finite = dr.isfinite(value)
    return finite if isinstance(value, mi.Float) else dr.all(finite)


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
             - a name in ``glint.DISTRIBUTIONS`` (``beckmann``, ``ggx``, ``ashikhmin_shirley``)
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
           * - dense, dense_node_scale
             - string, float
             - lattice, 1
             - as ``glint.Material``
           * - negligible_count
             - float
             - 1e-12
             - skip queries provably below this expected count (0: never)
           * - expected_footprint_area
             - float
             - 1e-6
             - the footprint area the tree's shape plans for (Eq. 11)
           * - pdf_quadrature, pdf_points
             - string, int
             - cubature, 64
             - the sampler pdf's rule; here ``cubature`` only (its pdf runs in Dr.Jit), the
               scalar plugin also takes ``qmc`` over ``pdf_points``
           * - density_map, alpha_map, tint_map
             - texture or string
             - none
             - a ``bitmap`` texture or an image filename (``glint_maps.py``): the flakes'
               density d ∈ [0, 1] (0 masks), their roughness α ∈ [1e-4, 1] (replacing
               ``alpha``), a colour scaling their reflectance
           * - roughness_levels
             - int
             - 8
             - as ``glint.Material``: an ``alpha_map`` of at most this many distinct α is
               exact (without one it changes nothing)
           * - map_filter
             - string
             - nearest
             - as ``glint.Material``: ``density_map`` and ``alpha_map`` constant over each
               texel (``nearest``) or bilinear between the texels' centres (``bilinear``);
               ``tint_map`` stays nearest
           * - uv_scale
             - float
             - 1
             - texture repetitions per unit of the shape's (u, v)

        Every parameter is checked (``ValueError`` naming it). F = 1. Sampling uses the glint
        sampler's three-number form u = (sample2.x, sample2.y, sample1), as the scalar plugin.

        With maps, f̂ is the package's and a coloured tint answers in colour. A density or tint
        map leaves the lobe the same everywhere: the sampler, its pdf, the negligible-query
        test (the material's without maps, which bounds the mapped one's: a density is at most
        1) and the smooth limit d(uv)·t(uv)·f (the texels read as the package reads them:
        d bilinearly under ``map_filter`` ``bilinear``, t nearest) stay in Dr.Jit. A roughness
        map varies the lobe over the surface: the sampler, its pdf and the smooth limit are
        then the package's at the texture position (one row per lane that needs one), and every
        footprint query goes to the package.
        """

        def __init__(self, props):
            super().__init__(props)
            self.params, self.maps, self.map_sources, self.uv_scale = material_parameters(
                props)
            self.material = glint.Material(**self.params, **self.maps)
            self.coloured = not self.material.gray
            #: Whether the lobe varies over the surface (a roughness map): the package samples.
            self.lobe_varies = "alpha_map" in self.maps
            #: The density and tint maps' texels in Dr.Jit, for the smooth limit of one lobe.
            self.density = self.tint = None
            if self.lobe_varies:
                self.lobe = Lobe(self.material._spec, None, self.material.smith_table)
            else:
                uniform = glint.Material(**self.params) if self.maps else self.material
                self.lobe = Lobe(uniform._spec, uniform.negligible_test, uniform.smith_table)
                if "density_map" in self.maps:
                    self.density = TexelLookup(
                        self.maps["density_map"], fixed_point=True,
                        bilinear=self.params["map_filter"] == "bilinear")
                if "tint_map" in self.maps:
                    self.tint = TexelLookup(self.maps["tint_map"])
            self.m_components = [flags]
            self.m_flags = flags

        # -- the parts: the smooth lobe and the sampler in Dr.Jit, f̂ from the package ------

        def footprint(self, si):
            """(uv, duv_dx, duv_dy) · uv_scale in double precision (the scalar plugin's
            numbers), and the mask of lanes that carry uv partials."""
            has = dr.any(si.duv_dx != 0.0) | dr.any(si.duv_dy != 0.0)
            s = self.uv_scale
            return (mi.Vector2d(si.uv) * s, mi.Vector2d(si.duv_dx) * s,
                    mi.Vector2d(si.duv_dy) * s, has)

        def _zeros(self, width):
            """A BRDF value of 0 on ``width`` lanes: Float, or Color3f for a coloured tint."""
            return dr.zeros(mi.Color3f if self.coloured else mi.Float, width)

        def _scatter(self, target, rows, index):
            """Scatter the package's answers ``rows`` ((n,) or (n, 3) NumPy) to ``index``."""
            if rows.ndim == 1:
                dr.scatter(target, _float(rows), index)
            else:
                dr.scatter(target, mi.Color3f(*(_float(rows[:, c]) for c in range(3))), index)

        def f_hat(self, si, wo, lanes):
            """(f̂ without the cosine, refused): the package's f̂ on the ``lanes`` (a mask),
            gathered to NumPy and scattered back; 0 and False elsewhere. ``refused`` marks the
            lanes whose row the package refused (an error, never NaN)."""
            width = _width(si.wi, si.uv, wo, lanes)
            value, refused = self._zeros(width), dr.zeros(mi.Bool, width)
            index = dr.compress(mi.Bool(lanes) if isinstance(lanes, bool) else lanes)
            if dr.width(index) == 0:
                return value, refused
            uv, dx, dy, _ = self.footprint(si)
            rows = _packed_rows(index, (si.wi, wo, uv, dx, dy))
            f = self.material.f_hat(rows[:, 0:3], rows[:, 3:6], rows[:, 6:8], rows[:, 8:10],
                                    rows[:, 10:12])
            ok = _rows_finite(f)
            self._scatter(value, _where(ok, f, 0.0), index)
            dr.scatter(refused, mi.Bool(~ok), index)
            return value, refused

        def f_smooth_at(self, si, wo, index):
            """The package's smooth limit at the texture position (si.uv · uv_scale) of the
            lanes ``index``, for a material with a roughness map: (n,) or (n, 3) NumPy, 0 where
            the package refuses the row."""
            rows = _packed_rows(index, (si.wi, wo, si.uv))
            zero = np.zeros((len(rows), 2))
            r = self.material.eval(rows[:, 0:3], rows[:, 3:6], rows[:, 6:8] * self.uv_scale,
                                   zero, zero, expected_count=False)
            return _where(r["error"] == "", r["f_smooth"], 0.0)

        def brdf(self, si, wo, active):
            """f (no cosine): f̂ where the lane carries a footprint (the smooth f where the
            package refuses it), the smooth f elsewhere. Float, or Color3f for a coloured
            tint."""
            uv, dx, dy, has = self.footprint(si)
            wi64, wo64 = mi.Vector3d(si.wi), mi.Vector3d(wo)
            ask = active & has
            # Queries the package would skip as negligible are answered here (f̂ = 0).
            skips = self.lobe.skips(wi64, wo64, uv, dx, dy)
            if skips is not None:
                ask &= ~skips
            value, refused = self.f_hat(si, wo, ask)
            # The smooth f on the lanes without a footprint or whose footprint was refused
            # (none at a first hit, all after it).
            smooth = mi.Bool(active) & (~has | refused)
            lanes = dr.compress(smooth)
            if dr.width(lanes) and self.lobe_varies:
                self._scatter(value, self.f_smooth_at(si, wo, lanes), lanes)
            elif dr.width(lanes):
                dr.eval(si.wi, wo, si.uv)
                wi_s, wo_s = (mi.Vector3d(dr.gather(mi.Vector3f, v, lanes)) for v in (si.wi, wo))
                f = self.lobe.f_smooth(wi_s, wo_s)
                if self.density is not None or self.tint is not None:
                    # The one lobe's f times d(uv) and t(uv), as the package's smooth limit
                    # (Σ_k d_k·f_k times t, one level).
                    uv_s = mi.Vector2d(dr.gather(type(si.uv), si.uv, lanes)) * self.uv_scale
                    if self.density is not None:
                        f = f * self.density.at(uv_s)[0]
                    if self.tint is not None:
                        t = self.tint.at(uv_s)
                        channels = range(3) if self.coloured else range(1)
                        f = [t[c] * f for c in channels]
                        f = mi.Color3f(*f) if self.coloured else f[0]
                dr.scatter(value, f if self.coloured else mi.Float(f), lanes)
            return value

        def sample_at(self, si, sample1, sample2, active):
            """(wo, valid): the package's sampler at the texture position on the ``active``
            lanes (a roughness map's lobes there), from the same three numbers as the
            Dr.Jit sampler's."""
            width = _width(si.wi, si.uv, sample1, sample2, active)
            wo, valid = dr.zeros(mi.Vector3f, width), dr.zeros(mi.Bool, width)
            lanes = dr.compress(mi.Bool(active) if isinstance(active, bool) else active)
            if dr.width(lanes) == 0:
                return wo, valid
            rows = _packed_rows(lanes, (si.wi, si.uv, sample2, [mi.Float(sample1)]))
            u = np.minimum(rows[:, 5:8], _BELOW_ONE)
            zero = np.zeros((len(rows), 2))
            # The package takes the texture position with a footprint: an empty one here.
            s = self.material.sample(rows[:, 0:3], u, rows[:, 3:5] * self.uv_scale, zero, zero)
            ok = (s["pdf"] > 0) & np.all(np.isfinite(s["wo"]), axis=1)
            w = np.where(ok[:, None], s["wo"], 0.0)
            dr.scatter(wo, mi.Vector3f(*(_float(w[:, k]) for k in range(3))), lanes)
            dr.scatter(valid, mi.Bool(ok), lanes)
            return wo, valid

        def sampler_pdf(self, si, wo, active):
            """The glint sampler's density on the ``active`` lanes (0 elsewhere), computed on
            those lanes alone (a light sample's MIS weight is asked for the few that carry
            light): Dr.Jit's cubature rules, the package's slope-space rule on the lanes that
            need it."""
            width = _width(si.wi, wo, active)
            pdf = dr.zeros(mi.Float, width)
            lanes = dr.compress(mi.Bool(active) if isinstance(active, bool) else active)
            if dr.width(lanes) == 0:
                return pdf
            if self.lobe_varies:
                rows = _packed_rows(lanes, (si.wi, wo, si.uv))
                q = self.material.pdf(rows[:, 0:3], rows[:, 3:6], rows[:, 6:8] * self.uv_scale)
                dr.scatter(pdf, _float(np.where(np.isfinite(q), q, 0.0)), lanes)
                return pdf
            dr.eval(si.wi, wo)
            wi64, wo64 = (mi.Vector3d(dr.gather(mi.Vector3f, v, lanes)) for v in (si.wi, wo))
            value, needs_package = self.lobe.pdf(wi64, wo64)
            value = mi.Float(value)
            index = dr.compress(needs_package)
            if dr.width(index):
                rows = _packed_rows(index, (wi64, wo64))
                q = self.material.pdf(rows[:, 0:3], rows[:, 3:6])
                dr.scatter(value, _float(np.where(np.isfinite(q), q, 0.0)), index)
            dr.scatter(pdf, value, lanes)
            return pdf

        def _on(self, ctx, si, wo, active):
            """The lanes answered: active, glossy reflection enabled, both directions above
            the horizon."""
            on = mi.Bool(active) & (si.wi.z > 0.0)
            if wo is not None:
                on &= wo.z > 0.0
            if not ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 0):
                on &= False
            return on

        # -- the mi.BSDF interface -------------------------------------------------------------

        def eval(self, ctx, si, wo, active=True):
            on = self._on(ctx, si, wo, active)
            f = self.brdf(si, wo, on) * (wo.z * dr.rsqrt(dr.squared_norm(wo)))
            return mi.Color3f(dr.select(on & _finite(f), f, 0.0))

        def pdf(self, ctx, si, wo, active=True):
            on = self._on(ctx, si, wo, active)
            return dr.select(on, self.sampler_pdf(si, wo, on), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            on = self._on(ctx, si, None, active)
            if self.lobe_varies:
                wo, valid = self.sample_at(si, sample1, sample2, on)
            else:
                wo64, valid = self.lobe.sample(mi.Vector3d(si.wi), mi.Float64(sample2.x),
                                               mi.Float64(sample2.y), mi.Float64(sample1))
                wo = mi.Vector3f(wo64)
                valid &= on
            pdf = self.sampler_pdf(si, wo, valid)
            valid &= (pdf > 0.0) & dr.isfinite(pdf)
            # f·cos θ_o / pdf: f̂ where the lane carries a footprint, else the smooth f.
            weight = self.brdf(si, wo, valid) * wo.z / pdf
            weight = dr.select(valid & _finite(weight), weight, 0.0)
            bs = dr.zeros(mi.BSDFSample3f, dr.width(weight))
            # Where nothing is sampled: wo 0 and pdf 0, as the scalar plugin.
            bs.wo = dr.select(valid, wo, mi.Vector3f(0.0))
            bs.pdf = dr.select(valid, pdf, 0.0)
            bs.eta = mi.Float(1.0)
            bs.sampled_component = mi.UInt32(0)
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            return bs, mi.Color3f(weight)

        def traverse(self, callback):
            pass

        def to_string(self):
            fields = ", ".join(f"{k}={v!r}" for k, v in self.params.items())
            maps = "".join(f", {k}={v}" for k, v in self.map_sources.items())
            return f"GlintBSDF[{fields}{maps}, uv_scale={self.uv_scale!r}] (vectorized)"

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
        value = bsdf.eval(ctx, si, wo, active)
        # The BSDF's pdf (the MIS weight) only where the sample carries light: f̂ is 0 on most
        # light samples of a sparse glint material.
        carries = active & dr.any(value != 0.0) & ~ds.delta
        bsdf_pdf = bsdf.pdf(ctx, si, wo, carries)
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
