"""The glint sampler (Sec. 3.4) and the smooth lobe of a uniform glint material, in Dr.Jit, for
the vectorized Mitsuba 3 plugin (``glint_vectorized.py``).

Only f̂ (Eq. 5) needs the particles, so only f̂ goes to the ``glint`` package. What the
plugin's ``sample`` and ``pdf`` compute, and the smooth f it shades where a path carries no
footprint, are closed forms of the material's roughness and cone radius: here they run inside
Dr.Jit's own kernels, on the renderer's wavefront, without a round trip through NumPy. They are
the package's formulas (``crates/brdf``: ``distribution.rs``, ``smooth.rs``, ``cone.rs``,
``glint_sampling.rs``) in double precision, and ``python/tests/test_mitsuba_vectorized.py``
checks them against the package on random queries:

- f = D(h)·G2(ω_i, ω_o)/(4 cos θ_i cos θ_o), F = 1 (Eq. 3, height-correlated Smith G).
- The sampler: a facet normal from D(m)(m·n) with the widened roughness α_s = 2α, ω′ its mirror
  direction, then ω_o uniform in the cone of radius γ around ω′. The sampler's three-number
  form u = (u0, u1, u2) splits u2's odd and even mantissa bits into the cone's two numbers, as
  the package's ``split_uniform``.
- The negligible-query test (``Material.negligible_test``): lanes whose bound λ̄ on the
  expected count is below τ are answered f̂ = 0 here, as the package would answer them,
  instead of being sent to it (three in four light samples of the sphere-lights example).
  Lanes just below τ (within the rounding differences of the two computations) go to the
  package, which decides.
- Its pdf, the cone average of the widened model's density, by the package's cubature rules:
  7 points while γ ≤ 0.35·α_s·cos θ_i, 32 points up to 2·α_s·cos θ_i. Wider cones and cones
  across the horizon take the package's slope-space rule: ``pdf`` reports those lanes
  (``needs_package``) and the plugin asks the package for them alone.
"""

import math

import drjit as dr
import mitsuba as mi

#: The package's bounds on α (``MIN_ALPHA``, 1) and its sampler's widening α_s/α.
MIN_ALPHA, MAX_ALPHA, SAMPLING_SCALE = 1e-4, 1.0, 2.0
#: The package's rule switches (``glint_sampling.rs``): the 7-point rule while
#: γ ≤ CUBATURE_MAX_CONE·α_s·cos θ_i, the 32-point rule while γ ≤ NARROW_CONE·α_s·cos θ_i.
CUBATURE_MAX_CONE, NARROW_CONE = 0.35, 2.0
#: The package's largest footprint edge component (``Footprint::MAX_EDGE``): a footprint
#: beyond it is refused, never skipped.
MAX_EDGE = 1e15
#: Lanes skip the package only where λ̄ < τ·(1 − margin): the package's own λ̄ differs from
#: this one by roundings. Those are ~1e-15 relative, except through the density bound B, whose
#: logarithm moves by up to 2/α² per unit of t = tan²θ (Beckmann and GGX), and t by ~1e-13
#: (a few ulps of a cosine, at grazing angles): margin = SKIP_MARGIN + 2e-13/α², α the smaller
#: roughness (2.5e-8 at α = 0.02, 2e-5 at 1e-4). Every lane skipped here is one the package
#: skips.
SKIP_MARGIN = 1e-9
_SQRT_PI = math.sqrt(math.pi)


def _seven_point_rule():
    """(r², angle in turns, weight) on the unit disk: the centre with 1/4 and a hexagon at
    r² = 2/3 with 1/8 each (exact to degree 5)."""
    return [(0.0, 0.0, 0.25)] + [(2.0 / 3.0, k / 6.0, 0.125) for k in range(6)]


def _polar_gauss_rule():
    """(r², angle in turns, weight): 4 Gauss–Legendre nodes in r² times 8 angles, alternate
    rings turned by half a step."""
    inner = math.sqrt(3.0 / 7.0 - 2.0 / 7.0 * math.sqrt(6.0 / 5.0))
    outer = math.sqrt(3.0 / 7.0 + 2.0 / 7.0 * math.sqrt(6.0 / 5.0))
    w_inner, w_outer = (18.0 + math.sqrt(30.0)) / 72.0, (18.0 - math.sqrt(30.0)) / 72.0
    rings = [(0.5 - 0.5 * outer, w_outer), (0.5 - 0.5 * inner, w_inner),
             (0.5 + 0.5 * inner, w_inner), (0.5 + 0.5 * outer, w_outer)]
    return [(u, (j + 0.5 * (k % 2)) / 8.0, weight / 8.0)
            for k, (u, weight) in enumerate(rings) for j in range(8)]


def _on_cone(versine, rule):
    """A disk rule mapped onto the cone around +z by the equal-area map (``uniform_in_cap``
    around +z, whose basis is x, y): ((x, y, z), weight) in the cone's frame."""
    points = []
    for u, turns, weight in rule:
        one_minus_cos = u * versine
        sin_theta = math.sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0))
        phi = 2.0 * math.pi * turns
        p = (sin_theta * math.cos(phi), sin_theta * math.sin(phi), 1.0 - one_minus_cos)
        length = math.sqrt(sum(c * c for c in p))
        points.append((tuple(c / length for c in p), weight))
    return points


def _orthonormal_basis(axis):
    """Two unit vectors completing unit ``axis`` to a frame (Duff et al. 2017, as the
    package's ``orthonormal_basis``)."""
    sign = dr.select(axis.z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + axis.z)
    b = axis.x * axis.y * a
    t = mi.Vector3d(1.0 + sign * axis.x * axis.x * a, sign * b, -sign * axis.x)
    s = mi.Vector3d(b, sign + axis.y * axis.y * a, -axis.y)
    return t, s


def _compact_even_bits(x):
    """The even bits of a 64-bit integer moved together (bit 2k to bit k)."""
    x = x & 0x5555555555555555
    x = (x | (x >> 1)) & 0x3333333333333333
    x = (x | (x >> 2)) & 0x0F0F0F0F0F0F0F0F
    x = (x | (x >> 4)) & 0x00FF00FF00FF00FF
    x = (x | (x >> 8)) & 0x0000FFFF0000FFFF
    return (x | (x >> 16)) & 0x00000000FFFFFFFF


def split_uniform(u):
    """Two uniforms from one (``mi.Float64`` in [0, 1)): the odd and the even bits of its
    52-bit mantissa fraction, as the package's ``split_uniform``."""
    bits = mi.UInt64(dr.clip(u, 0.0, 1.0 - 2.0 ** -52) * float(1 << 52))
    scale = 2.0 ** -26
    return (mi.Float64(_compact_even_bits(bits >> 1)) * scale,
            mi.Float64(_compact_even_bits(bits)) * scale)


def _scaled_slope2(m, alpha):
    """(x²/α_x² + y²/α_y²)/z² for m = (x, y, z): the squared scaled slope of radial kinds."""
    ax, ay = alpha
    return (dr.square(m.x) / (ax * ax) + dr.square(m.y) / (ay * ay)) / dr.square(m.z)


def _normal_from_scaled_slope(radius, u1, alpha):
    """normalize(−s_x, −s_y, 1) for the slopes (α_x ρ cos φ, α_y ρ sin φ), φ = 2πu1."""
    sin_phi, cos_phi = dr.sincos(2.0 * math.pi * u1)
    ax, ay = alpha
    return dr.normalize(mi.Vector3d(-ax * radius * cos_phi, -ay * radius * sin_phi, 1.0))


class _Port:
    """A distribution's port; those that read Λ from the package's table take it here
    (``Material.smith_table``)."""

    def __init__(self, smith_table=None):
        self.smith_table = smith_table


class BeckmannPort(_Port):
    """Beckmann (``crates/brdf/src/distribution/beckmann.rs``)."""

    @staticmethod
    def d(m, alpha):
        """D(m) for unit m with m.z > 0."""
        ax, ay = alpha
        z2 = dr.square(m.z)
        slope2 = _scaled_slope2(m, alpha)
        return dr.exp(-slope2) / (math.pi * ax * ay * z2 * z2)

    @staticmethod
    def lambda_(w, alpha):
        """Smith's Λ(ω) for unit ω above the horizon (0 along the normal)."""
        ax, ay = alpha
        projected2 = dr.square(ax * w.x) + dr.square(ay * w.y)
        a = w.z * dr.rsqrt(projected2)
        value = 0.5 * (dr.erf(a) - 1.0) + dr.exp(-a * a) / (2.0 * a * _SQRT_PI)
        # erf(a) = 1 and exp(−a²) < 3e-16 beyond a = 6: Λ is 0 to double precision.
        return dr.select((projected2 == 0.0) | (dr.square(w.z) > 36.0 * projected2),
                         0.0, value)

    @staticmethod
    def density_bound(t_near, t_far, alpha):
        """The bound on D(m)(m·n) over tan²θ in [t_near, t_far]: unimodal in t, peaking at
        t* = 3α²/2 − 1, α the larger roughness."""
        ax, ay = alpha
        alpha2 = max(ax, ay) ** 2
        t = dr.minimum(dr.maximum(1.5 * alpha2 - 1.0, t_near), t_far)
        rise = (1.0 + t) * dr.sqrt(1.0 + t)
        return rise * dr.exp(-t / alpha2) / (math.pi * ax * ay)

    @staticmethod
    def sample_normal(u0, u1, alpha):
        """A normal from D(m)(m·n): Gaussian slopes."""
        u0 = dr.minimum(u0, 1.0 - 2.0 ** -52)
        radius = dr.sqrt(-dr.log(1.0 - u0))
        return _normal_from_scaled_slope(radius, u1, alpha)


class GgxPort(_Port):
    """GGX (``crates/brdf/src/distribution/ggx.rs``)."""

    @staticmethod
    def d(m, alpha):
        """D(m) for unit m with m.z > 0."""
        ax, ay = alpha
        z2 = dr.square(m.z)
        slope2 = _scaled_slope2(m, alpha)
        return dr.rcp(math.pi * ax * ay * z2 * z2 * dr.square(1.0 + slope2))

    @staticmethod
    def lambda_(w, alpha):
        """Smith's Λ(ω) for unit ω above the horizon (0 along the normal)."""
        ax, ay = alpha
        projected2 = dr.square(ax * w.x) + dr.square(ay * w.y)
        return dr.select(projected2 == 0.0, 0.0,
                         0.5 * (dr.sqrt(1.0 + projected2 / dr.square(w.z)) - 1.0))

    @staticmethod
    def density_bound(t_near, t_far, alpha):
        """The bound on D(m)(m·n) over tan²θ in [t_near, t_far]: unimodal in t, peaking at
        t* = 3α² − 4, α the larger roughness."""
        ax, ay = alpha
        alpha2 = max(ax, ay) ** 2
        t = dr.minimum(dr.maximum(3.0 * alpha2 - 4.0, t_near), t_far)
        rise = (1.0 + t) * dr.sqrt(1.0 + t)
        return rise / (dr.square(1.0 + t / alpha2) * (math.pi * ax * ay))

    @staticmethod
    def sample_normal(u0, u1, alpha):
        """A normal from D(m)(m·n): the bivariate Student-like P22 slopes."""
        u0 = dr.minimum(u0, 1.0 - 2.0 ** -52)
        radius = dr.sqrt(u0 / (1.0 - u0))
        return _normal_from_scaled_slope(radius, u1, alpha)


def _log1p_over(x):
    """ln(1 + x)/x, accurate for small x (Goldberg: ln(y)/(y − 1) with y = 1 + x rounded)."""
    y = 1.0 + x
    return dr.select(y == 1.0, 1.0, dr.log(y) / (y - 1.0))


def _expm1(z):
    """e^z − 1, accurate for small z (Kahan: (e^z − 1)·z/ln(e^z))."""
    y = dr.exp(z)
    return dr.select(y == 1.0, z, (y - 1.0) * z / dr.log(y))


def _catmull_rom(p0, p1, p2, p3, f):
    """The Catmull–Rom cubic through p1 (f = 0) and p2 (f = 1), as the package's."""
    return p1 + 0.5 * f * (p2 - p0 + f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
                                          + f * (3.0 * (p1 - p2) + p3 - p0)))


class AshikhminShirleyPort(_Port):
    """Ashikhmin–Shirley (``crates/brdf/src/distribution/ashikhmin_shirley.rs``): exponents
    e = 2/α² − 2, D = cos^{e(φ)}θ/(π α_x α_y); Λ interpolated in the package's table
    (``Material.smith_table``, ``ashikhmin_shirley/smith.rs``) exactly as the package does."""

    def __init__(self, smith_table=None):
        super().__init__(smith_table)
        if smith_table is None:
            raise ValueError("the Dr.Jit lobe of ashikhmin_shirley needs the material's "
                             "smith_table")
        self.values = mi.Float64(smith_table["values"])
        self.u_nodes = int(smith_table["u_nodes"])
        self.rows = int(smith_table["azimuth_nodes"])

    @staticmethod
    def _exponents(alpha):
        ax, ay = alpha
        return 2.0 / (ax * ax) - 2.0, 2.0 / (ay * ay) - 2.0, 1.0 / (math.pi * ax * ay)

    def d(self, m, alpha):
        """D(m) for unit m with m.z > 0."""
        e_x, e_y, c = self._exponents(alpha)
        x2, y2 = dr.square(m.x / m.z), dr.square(m.y / m.z)
        return c * dr.exp(-0.5 * (e_x * x2 + e_y * y2) * _log1p_over(x2 + y2))

    def lambda_(self, w, alpha):
        """Smith's Λ(ω) from the package's table (0 along the normal)."""
        ax, ay = alpha
        if (ax, ay) != tuple(self.smith_table["alpha"]):
            raise ValueError("the smith_table is for another roughness")
        projected = dr.sqrt(dr.square(ax * w.x) + dr.square(ay * w.y))
        a = w.z / projected
        u = 1.0 / (1.0 + a)
        row_length = self.u_nodes + 1
        x = u * (self.u_nodes - 1)
        # Clamped below too: lanes below the horizon (u < 0) read the first nodes, then are
        # discarded (as the package, whose index saturates at 0).
        i = dr.clip(dr.floor(x), 0, self.u_nodes - 2)
        f = x - i
        i = mi.UInt32(i)

        def along_u(r):
            start = r * row_length
            below = dr.select(i == 0, 1, i - 1)
            p = [dr.gather(mi.Float64, self.values, start + k) for k in (below, i, i + 1, i + 2)]
            return _catmull_rom(*p, f)

        if self.rows == 1:
            g = along_u(mi.UInt32(0))
        else:
            azimuth = dr.atan2(dr.abs(ay * w.y), dr.abs(ax * w.x))
            y = azimuth / (0.5 * math.pi) * (self.rows - 1)
            j = dr.clip(dr.floor(y), 0, self.rows - 2)
            fy = y - j
            j = mi.Int32(j)
            last = self.rows - 1

            def reflected(r):
                return mi.UInt32(dr.select(r < 0, -r, dr.select(r > last, 2 * last - r, r)))

            g = _catmull_rom(*[along_u(reflected(j + k)) for k in (-1, 0, 1, 2)], fy)
        value = dr.maximum(g / (1.0 - u), 0.0)
        return dr.select(projected == 0.0, 0.0, dr.select(u >= 1.0, math.inf, value))

    def density_bound(self, t_near, t_far, alpha):
        """C cos^{e_m+1}θ at t_near: p ≤ C cos^{e(φ)+1}θ, decreasing in θ."""
        e_x, e_y, c = self._exponents(alpha)
        return c * dr.exp(-0.5 * (min(e_x, e_y) + 1.0) * t_near * _log1p_over(t_near))

    def sample_normal(self, u0, u1, alpha):
        """A normal from D(m)(m·n): the azimuth from its marginal by quadrant, then
        cos θ = u^{1/(e(φ)+2)}."""
        e_x, e_y, _ = self._exponents(alpha)
        quadrant = dr.clip(dr.floor(4.0 * u1), 0.0, 3.0)
        v = 4.0 * u1 - quadrant
        first = math.sqrt((e_x + 2.0) / (e_y + 2.0)) * dr.tan(0.5 * math.pi * v)
        sin, cos = dr.sincos(dr.atan(first))
        cos = dr.select((quadrant == 1.0) | (quadrant == 2.0), -cos, cos)
        sin = dr.select(quadrant >= 2.0, -sin, sin)
        e = e_x * cos * cos + e_y * sin * sin
        rest = dr.maximum(1.0 - u0, 2.2250738585072014e-308)
        tan = dr.sqrt(_expm1(-2.0 * dr.log(rest) / (e + 2.0)))
        return dr.normalize(mi.Vector3d(tan * cos, tan * sin, 1.0))


#: The Dr.Jit port of each of the package's distributions, by name. A test checks that every
#: name in ``glint.DISTRIBUTIONS`` has one, and each against the package.
PORTS = {"beckmann": BeckmannPort, "ggx": GgxPort, "ashikhmin_shirley": AshikhminShirleyPort}


class Lobe:
    """The smooth lobe and the glint sampler of a uniform glint material (no maps, F = 1,
    cubature pdf), built from ``glint.Material``'s specification (``Material._spec``).

    Directions are ``mi.Vector3d`` in the local frame (z the normal), ``wi`` toward the viewer;
    results are ``mi.Float64``."""

    def __init__(self, spec, negligible_test=None, smith_table=None):
        if spec.get("pdf_quadrature", "cubature") != "cubature":
            raise ValueError("the Dr.Jit sampler implements the cubature pdf only, not "
                             f"pdf_quadrature = {spec['pdf_quadrature']!r}")
        if spec.get("fresnel", "none") not in ("none", None):
            raise ValueError("the Dr.Jit lobe implements F = 1 only")
        name = spec["distribution"]
        if name not in PORTS:
            raise ValueError(f"the Dr.Jit lobe has no port of distribution {name!r}: it has "
                             f"{', '.join(PORTS)}")
        self.kind = PORTS[name](smith_table)
        alpha = float(spec["alpha"])
        alpha_y = float(spec.get("alpha_y") or alpha)
        self.alpha = (alpha, alpha_y)
        self.widened = tuple(min(max(a * SAMPLING_SCALE, MIN_ALPHA), MAX_ALPHA)
                             for a in self.alpha)
        gamma = math.radians(float(spec["gamma_degrees"]))
        self.versine = 2.0 * math.sin(0.5 * gamma) ** 2
        self.sin_gamma = math.sin(gamma)
        self.gamma_over_alpha = gamma / min(self.widened)
        self.sin_half = math.sin(0.5 * gamma)
        self.negligible = negligible_test
        self.skip_margin = SKIP_MARGIN + 2e-13 / min(self.alpha) ** 2
        self.seven = _on_cone(self.versine, _seven_point_rule())
        self.polar = _on_cone(self.versine, _polar_gauss_rule())

    # -- the distribution ------------------------------------------------------------------

    def _d(self, m, alpha):
        """D(m) for unit m (0 below the horizon)."""
        return dr.select(m.z > 0.0, self.kind.d(m, alpha), 0.0)

    def _lambda(self, w):
        """Smith's Λ(ω) of the material's roughness for unit ω above the horizon."""
        return self.kind.lambda_(w, self.alpha)

    def _reflected_density(self, wi, w, alpha):
        """The density of the mirror direction ω′ = w when the facet normal is drawn from
        D(m)(m·n) of roughness ``alpha``: D(h)(h·n)/(4 ω_i·h), h = (ω_i + ω′)/|·|."""
        h = dr.normalize(wi + w)
        cos = dr.dot(wi, h)
        value = self._d(h, alpha) * h.z / (4.0 * cos)
        return dr.select((h.z > 0.0) & (cos > 0.0), value, 0.0)

    def _particle_density_bound(self, cos_near, cos_far):
        """The bound on D(m)(m·n) between the polar angles of cosines ``cos_near`` ≥
        ``cos_far`` (the package's ``Microfacet::particle_density_bound``): each density is
        each kind bounds it on the interval of t = tan²θ."""
        def tan2(c):
            return dr.select(c <= 0.0, math.inf, dr.maximum(1.0 - c * c, 0.0) / (c * c))

        t_near, t_far = tan2(dr.minimum(cos_near, 1.0)), tan2(cos_far)
        value = self.kind.density_bound(t_near, dr.maximum(t_far, t_near), self.alpha)
        return dr.select(dr.isfinite(t_near), value, 0.0)

    def negligible_bound(self, wi, wo, duv_dx, duv_dy):
        """λ̄ of the package's negligible-query test (``Material.negligible_test``) for
        footprint edges ``duv_dx``, ``duv_dy`` (``mi.Vector2d``, in the particles' texture
        units); infinite where the conic is hyperbolic."""
        c = self.negligible
        wi, wo = dr.normalize(wi), dr.normalize(wo)
        total = wi + wo
        a = 0.5 * dr.norm(total)
        k1 = a * a - self.sin_half * self.sin_half
        cap_cos, cap_sin = dr.sqrt(dr.maximum(k1, 0.0)) / a, self.sin_half / a
        axis_cos = total.z / dr.norm(total)
        axis_sin = dr.sqrt(dr.maximum(1.0 - axis_cos * axis_cos, 0.0))
        arc_sin, arc_cos = math.sin(c["widening_arc"]), math.cos(c["widening_arc"])
        delta_cos = cap_cos * arc_cos - cap_sin * arc_sin
        delta_sin = cap_sin * arc_cos + cap_cos * arc_sin
        cos_near = dr.select(axis_cos >= delta_cos, 1.0,
                             axis_cos * delta_cos + axis_sin * delta_sin)
        cos_far = axis_cos * delta_cos - axis_sin * delta_sin
        cap = 2.0 * math.pi * cap_sin * cap_sin / (1.0 + cap_cos)
        area = dr.abs(duv_dx.x * duv_dy.y - duv_dx.y * duv_dy.x)
        bound = c["particles"] * area * (
            c["law_excess_ratio"] * self._particle_density_bound(cos_near, cos_far) * cap
            + c["unbounded_mass"])
        return dr.select((k1 > 0.0) & ~dr.isnan(bound), bound, math.inf)

    def skips(self, wi, wo, uv, duv_dx, duv_dy):
        """The lanes the package would answer f̂ = 0 by its negligible-query test (with the
        skip margin): directions above the horizon, a footprint it accepts (finite, edges
        within ``MAX_EDGE``), λ̄ < τ. None when the material has no test (``negligible_test``
        None)."""
        if self.negligible is None:
            return None
        accepted = (dr.all(dr.isfinite(uv)) & dr.all(dr.isfinite(duv_dx))
                    & dr.all(dr.isfinite(duv_dy))
                    & (dr.max(dr.abs(duv_dx)) <= MAX_EDGE) & (dr.max(dr.abs(duv_dy)) <= MAX_EDGE))
        bound = self.negligible_bound(wi, wo, duv_dx, duv_dy)
        return (accepted & (wi.z > 0.0) & (wo.z > 0.0)
                & (bound < self.negligible["threshold"] * (1.0 - self.skip_margin)))

    # -- the smooth BRDF ---------------------------------------------------------------------

    def f_smooth(self, wi, wo):
        """f = D(h)·G2/(4 cos θ_i cos θ_o) (F = 1); 0 unless both are above the horizon."""
        wi, wo = dr.normalize(wi), dr.normalize(wo)
        h = dr.normalize(wi + wo)
        g = dr.rcp(1.0 + self._lambda(wi) + self._lambda(wo))
        value = self._d(h, self.alpha) * g / (4.0 * wi.z * wo.z)
        valid = ((wi.z > 0.0) & (wo.z > 0.0) & (dr.dot(wi, h) > 0.0) & (dr.dot(wo, h) > 0.0)
                 & dr.isfinite(value))
        return dr.select(valid, value, 0.0)

    # -- the sampler ------------------------------------------------------------------------

    def sample(self, wi, u0, u1, u2):
        """The sampler's direction for three uniforms (``mi.Float64``): (ω_o, valid)."""
        wi = dr.normalize(wi)
        c0, c1 = split_uniform(u2)
        # A normal from D(m)(m·n), widened.
        m = self.kind.sample_normal(u0, u1, self.widened)
        cos_m = dr.dot(wi, m)
        centre = 2.0 * cos_m * m - wi
        # ω_o uniform in the cap of 1 − cos θ ≤ versine around ω′.
        one_minus_cos = c0 * self.versine
        sin_theta = dr.sqrt(dr.maximum(one_minus_cos * (2.0 - one_minus_cos), 0.0))
        sin_psi, cos_psi = dr.sincos(2.0 * math.pi * c1)
        t, s = _orthonormal_basis(centre)
        wo = dr.normalize((1.0 - one_minus_cos) * centre
                          + sin_theta * (cos_psi * t + sin_psi * s))
        valid = (wi.z > 0.0) & (centre.z > 0.0) & (cos_m > 0.0) & (wo.z > 0.0)
        return wo, valid

    def pdf(self, wi, wo):
        """The sampler's density of ω_o: (pdf, needs_package). Lanes where the package's
        slope-space rule applies (wide cones, cones across the horizon) have pdf 0 here and
        ``needs_package`` set."""
        wi, wo = dr.normalize(wi), dr.normalize(wo)
        above = (wi.z > 0.0) & (wo.z > 0.0)
        needs_package = above & ((self.gamma_over_alpha > NARROW_CONE * wi.z)
                                 | (wo.z < self.sin_gamma))
        polar = above & ~needs_package & (self.gamma_over_alpha > CUBATURE_MAX_CONE * wi.z)
        value = dr.select(above & ~needs_package & ~polar, self._cone_rule(self.seven, wi, wo),
                          0.0)
        # One kernel for the 7-point rule and both masks; then the 32-point rule only on the
        # lanes that need it (few: grazing incidence).
        dr.eval(value, polar, needs_package)
        lanes = dr.compress(polar)
        if dr.width(lanes):
            at = [dr.gather(mi.Vector3d, w, lanes) for w in (wi, wo)]
            dr.scatter(value, self._cone_rule(self.polar, *at), lanes)
        return value, needs_package

    def _cone_rule(self, points, wi, wo):
        """The cone average of the widened model's density by the rule ``points`` (unit wi,
        wo)."""
        t, b = _orthonormal_basis(wo)
        total = mi.Float64(0.0)
        for (x, y, z), weight in points:
            w = x * t + y * b + z * wo
            density = self._reflected_density(wi, w, self.widened)
            total += weight * dr.select(w.z > 0.0, density, 0.0)
        return total
