"""glint: glittery surfaces with the discrete stochastic microfacet model (Jakob et al. 2014).

Scene files render with ``glint.render`` (as ``cargo xtask render`` does, bit for bit), and
``python -m glint.farm`` renders frames on a Dask cluster (``glint.farm``).

The material interface mirrors ``cargo xtask eval`` (``docs/eval.md`` in the repository): the same
material fields with the same defaults and meaning, the same answers bit for bit, the same
error messages, over NumPy arrays of n rows. Rows are answered in parallel with the GIL
released.

>>> import numpy as np, glint
>>> m = glint.Material(distribution="beckmann", alpha=0.1, particles=1e6, gamma_degrees=1.0)
>>> r = m.eval([0, 0, 1], [0.1, 0, 0.99], [0.3, 0.4], [1e-3, 0], [0, 1e-3])
>>> bool(r["count"] >= 0 and r["error"] == "")
True
"""

import json
import math
import warnings

import numpy as np

from ._glint import DISTRIBUTIONS, __version__
from ._glint import Material as _NativeMaterial
from ._render import read_map_image, render, write_exr, write_png
from .units import mesh_areas, particles_per_square

__all__ = ["DISTRIBUTIONS", "Material", "__version__", "mesh_areas", "particles_per_square",
           "read_map_image", "render", "write_exr", "write_png"]


def _rows(name, value, width):
    """A float64 array of shape (n, width) and whether the input was one row. Aligned views
    (columns of a wider array) are kept as they are: the native module reads strided arrays in
    place; unaligned ones (fields of a packed record) are copied."""
    array = np.require(value, dtype=np.float64, requirements=["A"])
    single = array.ndim == 1
    if single:
        array = array.reshape(1, -1)
    if array.ndim != 2 or (width is not None and array.shape[1] != width):
        wanted = f"(n, {width}) or ({width},)" if width is not None else "(n, k)"
        raise ValueError(f"{name} must have shape {wanted}, not {np.shape(value)}")
    return array, single


#: The whole-number fields and their ranges, for an integer too large to be a double.
_WHOLE_NUMBERS = {"seed": "[0, 2^64)", "particles": "[1, 2^53]", "pdf_points": "[1, 4096]"}


def _finite(name, value):
    """A material number as JSON will carry it: an integer exactly (so that a seed above 2^53
    is not rounded, and eval refuses a particle count above 2^53 as written), anything else as
    a float. NumPy scalars are numbers too."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (int, float, np.integer, np.floating)):
        raise ValueError(f"material.{name} must be a finite number, not {value!r}")
    if isinstance(value, (int, np.integer)):
        value = int(value)
        if -2**64 < value < 2**64:
            return value
        try:
            # Out of every whole-number range; as a double, eval names the range.
            return float(value)
        except OverflowError:
            digits = int(value.bit_length() * math.log10(2)) + 1
            wanted = (f"a whole number in {_WHOLE_NUMBERS[name]}" if name in _WHOLE_NUMBERS
                      else "a finite number")
            raise ValueError(f"material.{name} = an integer of {digits} digits must be "
                             f"{wanted}") from None
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"material.{name} must be a finite number, not {value}")
    return value


def _name(name, value):
    """A material field that names something ("beckmann", "exact", …): a string, or any
    other JSON value, which eval refuses naming the field."""
    if isinstance(value, (str, np.str_)):
        return str(value)
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        raise ValueError(f"material.{name} {value!r} is unknown: it must be a string") from None
    return value


def _fresnel(value):
    """The ``fresnel`` argument as JSON: NumPy scalars and arrays become numbers and lists
    (each number checked as the material's own are, named by its path)."""
    if value is None or isinstance(value, (str, np.str_)):
        return None if value is None else str(value)
    if not isinstance(value, dict):
        raise ValueError(f"material.fresnel {value!r} is not valid: use None, \"none\", "
                         "{\"conductor\": {\"eta\": [r, g, b], \"k\": [r, g, b]}} or "
                         "{\"dielectric\": {\"eta\": x}}")

    def convert(path, item):
        if isinstance(item, dict):
            return {str(k): convert(f"{path}.{k}", v) for k, v in item.items()}
        if isinstance(item, np.ndarray):
            item = item.tolist()
        if isinstance(item, (list, tuple)):
            return [convert(path, v) for v in item]
        if isinstance(item, (str, np.str_)) or item is None:
            return item if item is None else str(item)
        return _finite(path, item)

    return {str(k): convert(f"fresnel.{k}", v) for k, v in value.items()}


class Material:
    """A glint material, built once (a few ms) and reused for any number of queries.

    Parameters have the names, defaults, meaning and ranges of ``docs/eval.md``'s material
    fields: ``distribution`` (a name in ``glint.DISTRIBUTIONS``: "beckmann", "ggx", "ashikhmin_shirley"), roughness ``alpha`` and ``alpha_y`` in
    [1e-4, 1] (None: the same as ``alpha``), ``particles`` N per unit texture square (a whole
    number in [1, 2^53]), ``gamma_degrees`` the cone radius γ in degrees ([5.73e-5, 60], 1 by
    default; ``gamma_deg``, its older name, still works, deprecated),
    ``epsilon`` of Eq. 10 in [0, 1] (0 = off; 0.1, the paper's, by default: it acts only on
    nodes the dense regime does not sample), ``seed`` the particle set (a whole
    number in [0, 2^64), taken exactly), ``fresnel`` (None, ``{"conductor": {"eta": [r, g, b],
    "k": [r, g, b]}}`` or ``{"dielectric": {"eta": x}}``, η in [1e-3, 1e3] and k in [0, 1e3];
    NumPy scalars and arrays are accepted), ``multinomial`` ("exact" or "normal"),
    ``negligible_count`` (skip queries whose expected count is provably below it: 1e-12 by
    default, glint-tracer's τ; 0 = never, every query traversed),
    and, keyword only, ``expected_footprint_area`` (Eq. 11), ``pdf_quadrature`` (the
    sampler pdf's rule over the cone: "cubature", the default, or "qmc", the paper's),
    ``pdf_points`` (its QMC points, in [1, 4096]), ``dense`` ("lattice", the default: queries
    expecting 8 or more particles answered from a Poisson process drawn at their own scale,
    with the exact counts' mean, dispersion and correlations at a cost that stops growing with
    N, blended with the tree from 4 to 8, others as "sampled"; or "sampled": partly covered
    nodes at the query's scale that hold many particles answer from a rescaled sample; or
    "exact": every particle resolved) and ``dense_node_scale`` (the largest node sampled, in
    widths of the query, in (0, 16]; 1 by default: larger is faster and lumpier).

    Maps vary the material over its texture square (keyword only; NumPy arrays, row 0 at the
    top of the texture, v from 1 − 1/H to 1, column 0 starting at u = 0, the map tiling with
    the square): ``density_map`` (H, W), d in [0, 1], N·d flakes per
    unit area (0 masks: no flake at all); ``alpha_map`` (H, W), the flakes' isotropic α in
    [1e-4, 1], replacing ``alpha``/``alpha_y`` (the same size as ``density_map`` when both are
    given); ``tint_map`` (H, W, 3), a colour in [0, 1] scaling the flakes' reflectance (its
    mean over each footprint); ``roughness_levels`` (K, 8 by default): an ``alpha_map`` with
    at most K distinct values is exact, one with more is K levels interpolated in log α;
    ``map_filter`` ("nearest", the default, or "bilinear"): how ``density_map`` and
    ``alpha_map`` are reconstructed between texels, each texel constant over its square or
    interpolated bilinearly between the texels' centres (wrapping as the map tiles), so a
    mask's edge ramps over one texel; ``tint_map`` stays nearest.
    A bad texel raises ``ValueError`` naming the map and the texel (column, row).

    Invalid parameters raise ``ValueError`` naming the parameter. A material pickles and
    copies (it is rebuilt from its parameters, with the same particle set).
    """

    def __init__(self, distribution="beckmann", alpha=0.1, alpha_y=None, particles=1e6,
                 gamma_deg=None, epsilon=0.1, seed=0, fresnel=None, multinomial="exact",
                 negligible_count=1e-12, *, expected_footprint_area=1e-6, pdf_quadrature="cubature",
                 pdf_points=64, gamma_degrees=None, density_map=None, alpha_map=None,
                 tint_map=None, roughness_levels=8, dense="lattice", dense_node_scale=1.0,
                 map_filter="nearest"):
        if gamma_deg is not None:
            if gamma_degrees is not None:
                raise ValueError("give gamma_degrees or gamma_deg (its older name), not both")
            warnings.warn("glint.Material(gamma_deg=...) is deprecated: use gamma_degrees=...",
                          DeprecationWarning, stacklevel=2)
            gamma_degrees = gamma_deg
        if gamma_degrees is None:
            gamma_degrees = 1.0
        spec = {
            "distribution": _name("distribution", distribution),
            "alpha": _finite("alpha", alpha),
            "particles": _finite("particles", particles),
            "gamma_degrees": _finite("gamma_degrees", gamma_degrees),
            "epsilon": _finite("epsilon", epsilon),
            "seed": _finite("seed", seed),
            "multinomial": _name("multinomial", multinomial),
            "negligible_count": _finite("negligible_count", negligible_count),
            "expected_footprint_area": _finite("expected_footprint_area",
                                               expected_footprint_area),
            "pdf_quadrature": _name("pdf_quadrature", pdf_quadrature),
            "pdf_points": _finite("pdf_points", pdf_points),
            "dense": _name("dense", dense),
            "dense_node_scale": _finite("dense_node_scale", dense_node_scale),
        }
        if alpha_y is not None:
            spec["alpha_y"] = _finite("alpha_y", alpha_y)
        if fresnel is not None:
            spec["fresnel"] = _fresnel(fresnel)
        spec["roughness_levels"] = _finite("roughness_levels", roughness_levels)
        spec["map_filter"] = _name("map_filter", map_filter)
        maps = {
            "density_map": _map("density_map", density_map, 2),
            "alpha_map": _map("alpha_map", alpha_map, 2),
            "tint_map": _map("tint_map", tint_map, 3),
        }
        self._native = _NativeMaterial(json.dumps(spec, allow_nan=False), **maps)
        self._spec = spec
        self._maps = maps
        self.gray = self._native.gray

    def __reduce__(self):
        # pickle, copy and deepcopy rebuild the material from its parameters (the native
        # material is not picklable; building it again gives the same particle set).
        return (_material_from_spec, (dict(self._spec), dict(self._maps)))

    def __repr__(self):
        fields = [f"{k}={v!r}" for k, v in self._spec.items()]
        fields += [f"{k}=<array {v.shape}>" for k, v in self._maps.items() if v is not None]
        return f"glint.Material({', '.join(fields)})"

    def _colour(self, columns, prefix):
        if self.gray:
            return columns[f"{prefix}_r"]
        return np.stack([columns[f"{prefix}_{c}"] for c in "rgb"], axis=1)

    @staticmethod
    def _finish(result, single):
        result["error"] = np.array(result["error"], dtype=str)
        if single:
            result = {key: value[0] for key, value in result.items()}
        return result

    def eval(self, wi, wo, uv, duv_dx, duv_dy, *, expected_count=True, f_smooth=True):
        """f̂ and its statistics for n queries.

        ``wi``, ``wo``: (n, 3) directions in the local frame (z = normal), ``wi`` toward the
        viewer and ``wo`` toward the light (pbrt-v4's names are the reverse), normalized on
        input;
        ``uv``, ``duv_dx``, ``duv_dy``: (n, 2), the footprint
        {uv + s·duv_dx + t·duv_dy : s, t ∈ [−½, ½]}, each edge component within ±1e15. Returns a dict of arrays: ``count``,
        ``expected_count``, ``d_hat``, ``f_hat``, ``f_smooth`` ((n,) when F is grey, else
        (n, 3)), ``nodes_visited``, ``negligible_bound`` (NaN where the query was traversed)
        and ``error`` (empty where the row is valid, else the message ``eval`` gives; the
        row's numbers are then NaN). 1-D inputs give one query's values.

        ``expected_count=False`` skips the expected count (a tree traversal of its own, as
        costly as the count's; the column is then NaN), and ``f_smooth=False`` the smooth BRDF
        (Smith's Λ of both directions, about a fifth of a row's cost; NaN): a renderer that
        shades f̂ wherever it has a footprint needs neither.
        Rows are answered in parallel in an order that keeps neighbouring footprints on one
        thread, and returned in input order, bit for bit whatever the batch or thread count.
        """
        wi, single = _rows("wi", wi, 3)
        wo, _ = _rows("wo", wo, 3)
        uv, _ = _rows("uv", uv, 2)
        dx, _ = _rows("duv_dx", duv_dx, 2)
        dy, _ = _rows("duv_dy", duv_dy, 2)
        c = _with_errors(self._native.eval(wi, wo, uv, dx, dy, bool(expected_count),
                                           bool(f_smooth)))
        result = {
            "count": c["count"],
            "expected_count": c["expected_count"],
            "d_hat": c["d_hat"],
            "f_hat": self._colour(c, "f_hat"),
            "f_smooth": self._colour(c, "f_smooth"),
            "nodes_visited": c["nodes_visited"],
            "negligible_bound": c["negligible_bound"],
            "error": c["error"],
        }
        return self._finish(result, single)

    @property
    def smith_table(self):
        """The table Smith's Λ is read from, for a distribution that tabulates it
        ("ashikhmin_shirley"): a dict of ``alpha``, ``u_nodes``, ``azimuth_nodes`` and
        ``values`` (``crates/brdf/src/distribution/ashikhmin_shirley/smith.rs`` says how it
        is laid out and interpolated); None for the others."""
        return self._native.smith_table

    @property
    def map_bytes(self):
        """The heap memory the material's maps hold, in bytes: the maps given and those built
        from them (its roughness levels', the density-weighted tint's), as counted against the
        4.29 GB bound a material's maps may hold before any is built. 0 without maps."""
        return self._native.map_bytes

    @property
    def negligible_test(self):
        """The negligible-query test's constants, for a renderer that runs the test in its own
        kernels before asking for f̂ (the Mitsuba plugin does, in Dr.Jit): a dict of
        ``particles`` N, ``threshold`` τ (``negligible_count``), ``law_excess_ratio`` W,
        ``unbounded_mass`` M and ``widening_arc`` (radians). A query over a footprint of area
        a(A) is skipped, f̂ = 0, when
        λ̄ = N·a(A)·(W·B[θ_a − δ, θ_a + δ]·σ_cap + M) < τ, with the conic's bounding cap
        around h = (ω_i + ω_o)/|ω_i + ω_o| (cos θ_max = √(a² − sin²(γ/2))/a, sin θ_max =
        sin(γ/2)/a, a = |ω_i + ω_o|/2; never skipped when a ≤ sin(γ/2)),
        σ_cap = 2π sin²θ_max/(1 + cos θ_max), δ = θ_max + ``widening_arc``, θ_a the angle of h
        from the normal and B the distribution's bound on D(m)(m·n) between two polar angles
        (glint-brdf's ``Microfacet::particle_density_bound``). None for a material with maps or
        with ``negligible_count = 0``."""
        return self._native.negligible_test

    def f_hat(self, wi, wo, uv, duv_dx, duv_dy):
        """f̂ alone for n queries, as ``eval`` computes it: (n,) when F is grey, else (n, 3);
        NaN on the rows ``eval`` refuses (its ``error`` column names why). What a renderer
        shading pixel footprints asks for, at the lowest cost per row: no statistics, no
        smooth BRDF, no error strings. Arguments as for ``eval``."""
        wi, single = _rows("wi", wi, 3)
        wo, _ = _rows("wo", wo, 3)
        uv, _ = _rows("uv", uv, 2)
        dx, _ = _rows("duv_dx", duv_dx, 2)
        dy, _ = _rows("duv_dy", duv_dy, 2)
        f = self._native.f_hat(wi, wo, uv, dx, dy)
        return f[0] if single else f

    def sample(self, wi, u, uv=None, duv_dx=None, duv_dy=None):
        """Directions from the glint sampler (Sec. 3.4) for n rows, and their two weights.

        ``wi``: (n, 3) directions toward the viewer (normalized on input); ``u``: (n, 4)
        uniform numbers in [0, 1) (two for the widened lobe, two for the cone) or (n, 3) in
        ``docs/eval.md``'s original form. Returns ``wo`` (n, 3), toward the light, rows of NaN
        where no direction is sampled; ``pdf`` (n,); ``smooth_weight`` (n,) or (n, 3),
        f_smooth·cos θ_o/pdf, for paths that carry no footprint; and ``error``.

        With the footprint ``uv``, ``duv_dx``, ``duv_dy`` ((n, 2) each, as in ``eval``) it
        also returns ``f_hat`` at the sampled direction and ``footprint_weight``,
        f̂·cos θ_o/pdf, the weight Rust's ``GlintBxdf::sample`` and C's ``glint_sample`` with a
        footprint give (bit for bit). Rows without a sample have 0 weights.

        ``weight`` is ``smooth_weight`` under its older name (deprecated: it will be removed
        in the next version).
        """
        wi, single = _rows("wi", wi, 3)
        u, _ = _rows("u", u, None)
        # A material with maps samples at the footprint's centre.
        at_uv = _rows("uv", uv, 2)[0] if uv is not None and self._has_maps() else None
        c = _with_errors(self._native.sample(wi, u, at_uv))
        wo = np.stack([c["wo_x"], c["wo_y"], c["wo_z"]], axis=1)
        smooth_weight = self._colour(c, "weight")
        result = {
            "wo": wo,
            "pdf": c["pdf"],
            "smooth_weight": smooth_weight,
            "weight": smooth_weight,
            "error": c["error"],
        }
        footprint = (uv, duv_dx, duv_dy)
        if any(x is not None for x in footprint):
            if any(x is None for x in footprint):
                raise ValueError("a footprint needs all of uv, duv_dx and duv_dy")
            sampled = c["pdf"] > 0
            # Rows without a sample are evaluated at a harmless direction and zeroed after.
            at = np.where(sampled[:, None], wo, np.array([0.0, 0.0, 1.0]))
            uv, _ = _rows("uv", uv, 2)
            dx, _ = _rows("duv_dx", duv_dx, 2)
            dy, _ = _rows("duv_dy", duv_dy, 2)
            e = _with_errors(self._native.eval(wi, at, uv, dx, dy, False, False))
            f_hat = self._colour(e, "f_hat")
            mask = sampled if f_hat.ndim == 1 else sampled[:, None]
            f_hat = np.where(mask, f_hat, 0.0)
            cos_over_pdf = np.where(sampled, wo[:, 2] / np.where(sampled, c["pdf"], 1.0), 0.0)
            result["f_hat"] = f_hat
            result["footprint_weight"] = f_hat * (cos_over_pdf if f_hat.ndim == 1
                                                   else cos_over_pdf[:, None])
            bad = np.array(e["error"], dtype=str)
            result["error"] = np.where(np.array(c["error"], dtype=str) != "",
                                       np.array(c["error"], dtype=str), bad)
        return self._finish(result, single)

    def pdf(self, wi, wo, uv=None):
        """The glint sampler's density of ``wo`` for n rows: (n,), NaN on invalid rows. A
        material with maps samples at texture positions ``uv`` ((n, 2)) when they are given
        (as ``sample`` with a footprint does), else by its roughness levels' shares."""
        wi, single = _rows("wi", wi, 3)
        wo, _ = _rows("wo", wo, 3)
        at_uv = _rows("uv", uv, 2)[0] if uv is not None and self._has_maps() else None
        p = self._native.pdf(wi, wo, at_uv)["pdf"]
        return p[0] if single else p

    def _has_maps(self):
        return any(m is not None for m in self._maps.values())


def _with_errors(columns):
    """The native columns with their ``error`` column: "" where a row succeeded, else its
    message (the native module lists only the failed rows)."""
    rows, messages = columns.pop("error_rows"), columns.pop("error_messages")
    n = len(next(iter(columns.values())))
    width = max((len(m) for m in messages), default=1)
    error = np.zeros(n, dtype=f"<U{width}")
    error[rows] = messages
    columns["error"] = error
    return columns


def _material_from_spec(spec, maps=None):
    """The material of ``Material.__reduce__``: ``spec`` is its JSON object, ``maps`` its
    arrays."""
    spec = dict(spec)
    return Material(**spec, **(maps or {}))


def _map(name, value, dimensions):
    """A map argument as a C-ordered float64 array of ``dimensions`` dimensions ((H, W), or
    (H, W, 3) for a tint), or None; its values are checked by the native material, which names
    the texel."""
    if value is None:
        return None
    try:
        array = np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"material.{name} must be an array of numbers") from None
    shape = "(H, W)" if dimensions == 2 else "(H, W, 3)"
    if array.ndim != dimensions or array.size == 0 or (dimensions == 3 and array.shape[2] != 3):
        raise ValueError(f"material.{name} must have shape {shape}, not {array.shape}")
    return array
