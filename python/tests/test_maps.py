"""Density, roughness and tint maps from Python: the same answers as `cargo xtask eval` with
the maps as JSON rows (bit for bit), the layout (row 0 at the top of the texture), bad texels
named, and materials with maps that pickle."""

import json
import math
import pickle

import numpy as np
import pytest

import glint
from test_glint import _queries, _same, _xtask_eval

# 4 × 3 texels (H = 3 rows, W = 4 columns): a masked texel, seven roughness values over
# K = 4 levels, a tint.
DENSITY = np.array([[1.0, 0.5, 0.0, 0.25],
                    [0.75, 1.0, 0.6, 0.3],
                    [0.2, 0.9, 1.0, 0.4]])
ALPHA = np.array([[0.05, 0.1, 0.2, 0.3],
                  [0.4, 0.05, 0.1, 0.2],
                  [0.3, 0.4, 0.5, 0.05]])
TINT = np.stack([np.linspace(0.2, 1.0, 12).reshape(3, 4),
                 np.full((3, 4), 0.6),
                 np.linspace(1.0, 0.1, 12).reshape(3, 4)], axis=2)
KWARGS = dict(distribution="beckmann", alpha=0.1, particles=1e8, gamma_degrees=2.0, seed=5,
              roughness_levels=4)


def _material():
    return glint.Material(**KWARGS, density_map=DENSITY, alpha_map=ALPHA, tint_map=TINT)


@pytest.mark.parametrize("map_filter", [None, "bilinear"])
def test_maps_match_json_lines_bit_for_bit(map_filter):
    """The maps as NumPy arrays and as eval's JSON rows give the same answers, bit for bit,
    each texel constant (the default) or reconstructed bilinearly."""
    kwargs = dict(KWARGS) if map_filter is None else dict(KWARGS, map_filter=map_filter)
    m = glint.Material(**kwargs, density_map=DENSITY, alpha_map=ALPHA, tint_map=TINT)
    spec = dict(kwargs, density_map=DENSITY.tolist(), alpha_map=ALPHA.tolist(),
                tint_map=TINT.tolist())
    wi, wo, uv, dx, dy, u = _queries(60, seed=11)
    dx, dy = dx * 0.2, dy * 0.2
    lines = []
    for i in range(len(wi)):
        common = {"material": spec, "wi": wi[i].tolist()}
        lines.append(json.dumps({"op": "eval", **common, "wo": wo[i].tolist(),
                                 "uv": uv[i].tolist(), "duv_dx": dx[i].tolist(),
                                 "duv_dy": dy[i].tolist()}))
        lines.append(json.dumps({"op": "sample", **common, "u": u[i].tolist(),
                                 "uv": uv[i].tolist()}))
        lines.append(json.dumps({"op": "pdf", **common, "wo": wo[i].tolist(),
                                 "uv": uv[i].tolist()}))
    answers = _xtask_eval(lines)
    r = m.eval(wi, wo, uv, dx, dy)
    s = m.sample(wi, u, uv, dx, dy)
    p = m.pdf(wi, wo, uv)
    found = 0
    for i in range(len(wi)):
        e, a, ap = answers[3 * i: 3 * i + 3]
        assert "error" not in e, e
        for key in ("count", "expected_count", "d_hat", "f_hat", "f_smooth", "nodes_visited"):
            assert _same(r[key][i], e[key]), (i, key, r[key][i], e[key])
        if a["wo"] is None:
            assert s["pdf"][i] == 0
        else:
            assert _same(s["wo"][i], a["wo"]) and _same(s["pdf"][i], a["pdf"])
            assert _same(s["smooth_weight"][i], a["weight"])
        assert _same(p[i], ap["pdf"])
        found += r["count"][i] > 0
    assert found > 0


def test_map_filter_nearest_is_the_default_and_bilinear_interpolates_between_centres():
    """``map_filter="nearest"`` answers as the material without it, bit for bit (f̂, counts,
    samples, pdfs, the smooth limit); ``"bilinear"`` answers otherwise, and its smooth limit
    on a density map alone is d(uv) times the unmapped one, d interpolated between the texel
    centres ((i + ½)/W, 1 − (r + ½)/H), wrapping."""
    wi, wo, uv, dx, dy, u = _queries(80, seed=17)
    dx, dy = dx * 0.2, dy * 0.2
    default, nearest, bilinear = (
        glint.Material(**KWARGS, density_map=DENSITY, alpha_map=ALPHA, tint_map=TINT, **extra)
        for extra in ({}, {"map_filter": "nearest"}, {"map_filter": "bilinear"}))

    def answers(m):
        r = m.eval(wi, wo, uv, dx, dy)
        s = m.sample(wi, u, uv, dx, dy)
        return [r["count"], r["f_hat"], r["f_smooth"], s["wo"], s["pdf"], m.pdf(wi, wo, uv)]

    reference = answers(default)
    assert all(_same(a, b) for a, b in zip(answers(nearest), reference))
    assert not _same(answers(bilinear)[0], reference[0])
    assert not _same(answers(bilinear)[2], reference[2])

    # The smooth limit under a density map alone: d(uv)·f, d bilinear between the centres.
    plain = dict(distribution="beckmann", alpha=0.1, particles=1e6, gamma_degrees=2.0)
    flat = glint.Material(**plain)
    mapped = glint.Material(**plain, density_map=DENSITY, map_filter="bilinear")
    height, width = DENSITY.shape
    from_bottom = DENSITY[::-1]
    points = np.array([[0.125, 5 / 6], [0.5, 0.5], [0.0, 0.0], [0.99, 0.01], [-0.3, 1.7]])
    zero = np.zeros_like(points)
    up = np.array([[0.0, 0.0, 1.0]] * len(points))
    out = np.array([[0.05, 0.0, 1.0]] * len(points))
    f = flat.eval(up, out, points, zero, zero)["f_smooth"]
    g = mapped.eval(up, out, points, zero, zero)["f_smooth"]
    for (x, y), fk, gk in zip(points % 1.0, f, g):
        s, t = x * width - 0.5, y * height - 0.5
        i, j = math.floor(s), math.floor(t)
        fs, ft = s - i, t - j
        q = from_bottom[[j % height, (j + 1) % height]][:, [i % width, (i + 1) % width]]
        d = ((1 - ft) * ((1 - fs) * q[0, 0] + fs * q[0, 1])
             + ft * ((1 - fs) * q[1, 0] + fs * q[1, 1]))
        # (d is stored to 2⁻³², so to 1e-9 here.)
        assert gk == pytest.approx(d * fk, rel=1e-9, abs=1e-300), (x, y, d)
    # At a texel's centre the value is the texel's: texel (column 0, row 0) at (1/8, 5/6).
    assert g[0] == pytest.approx(DENSITY[0, 0] * f[0], rel=1e-12)


def test_row_zero_is_the_top_of_the_texture():
    """A density map whose top row alone is 1: footprints in the top third of the square
    find flakes, those in the bottom two thirds none, even with a wide cone."""
    density = np.zeros((3, 2))
    density[0] = 1.0
    m = glint.Material(alpha=0.5, particles=1e7, gamma_degrees=40.0, epsilon=0.0,
                       density_map=density)
    wi = np.array([[0.0, 0.0, 1.0]] * 2)
    wo = np.array([[0.1, 0.0, 1.0]] * 2)
    uv = np.array([[0.3, 0.9], [0.3, 0.4]])
    edge = np.array([[0.05, 0.0]] * 2), np.array([[0.0, 0.05]] * 2)
    r = m.eval(wi, wo, uv, *edge)
    assert r["count"][0] > 0 and r["count"][1] == 0, r["count"]


@pytest.mark.parametrize("kwargs, message", [
    (dict(density_map=np.array([[1.0, 1.5]])), "density_map: texel (column 1, row 0) is 1.5"),
    (dict(density_map=np.array([[1.0, np.nan]])), "density_map: texel (column 1, row 0)"),
    (dict(alpha_map=np.array([[0.1], [0.0]])), "alpha_map: texel (column 0, row 1)"),
    (dict(tint_map=np.full((1, 2, 3), 2.0)), "tint_map: texel (column 0, row 0)"),
    (dict(tint_map=np.ones((2, 2))), "tint_map must have shape (H, W, 3)"),
    (dict(density_map=np.ones(3)), "density_map must have shape (H, W)"),
    (dict(density_map=[["a"]]), "density_map must be an array of numbers"),
    (dict(density_map=np.zeros((2, 2))), "density_map: every texel is 0"),
    (dict(density_map=np.ones((2, 2)), alpha_map=np.full((2, 3), 0.1)), "the same size"),
    (dict(roughness_levels=0), "roughness_levels"),
    (dict(density_map=np.ones((2, 2)), map_filter="cubic"),
     'map_filter "cubic" is unknown: use "nearest" or "bilinear"'),
    (dict(map_filter=None), "map_filter"),
])
def test_bad_maps_raise_value_error_naming_the_map_and_texel(kwargs, message):
    with pytest.raises(ValueError, match=None) as error:
        glint.Material(**kwargs)
    assert message in str(error.value), str(error.value)


def test_materials_with_maps_pickle():
    m = _material()
    copy = pickle.loads(pickle.dumps(m))
    wi, wo, uv, dx, dy, _ = _queries(30, seed=2)
    a, b = m.eval(wi, wo, uv, dx, dy), copy.eval(wi, wo, uv, dx, dy)
    assert _same(a["f_hat"], b["f_hat"]) and _same(a["count"], b["count"])
    assert "density_map=<array (3, 4)>" in repr(m)


def test_a_coloured_tint_answers_colours_without_fresnel():
    """A cyan tint and no Fresnel term: f_hat is (n, 3) with red 0 (it was one number, the
    red channel's 0); a grey tint keeps one number per row."""
    wi, wo, uv, dx, dy, _ = _queries(20, seed=3)
    plain = dict(distribution="beckmann", alpha=0.1, particles=1e9, gamma_degrees=5.0)
    cyan = glint.Material(**plain, tint_map=np.tile([0.0, 1.0, 1.0], (2, 2, 1)))
    assert not cyan.gray
    f = cyan.eval(wi, wo, uv, dx, dy)["f_hat"]
    assert f.shape == (20, 3) and np.all(f[:, 0] == 0) and np.all(f[:, 1] == f[:, 2])
    assert np.any(f[:, 1] > 0)
    grey = glint.Material(**plain, tint_map=np.full((2, 2, 3), 0.5))
    assert grey.gray and grey.eval(wi, wo, uv, dx, dy)["f_hat"].shape == (20,)


def test_one_roughness_level_for_a_map_of_several_is_a_value_error():
    """It panicked (pyo3's PanicException); now a ValueError naming roughness_levels."""
    with pytest.raises(ValueError, match="roughness_levels"):
        glint.Material(distribution="beckmann", particles=1e6, gamma_degrees=1.0,
                       alpha_map=np.array([[0.1, 0.3]]), roughness_levels=1)


def test_roughness_levels_share_their_texels_instead_of_multiplying_the_memory():
    """A 512 × 768 roughness map of 97 values changing at every texel, at 64 levels: as maps
    of their own its levels would hold 12.7 bytes a texel each (about 0.3 GB, and a
    2048 × 3072 one about 4.5 GB, over the 4.29 GB bound: it was refused); filtered nearest or
    bilinear they share one family of texels, 9 bytes a texel and 0.36 a level, 15 MB (Rust's
    budget tests check the count and the refusal over the bound)."""
    alpha = 0.02 + 0.3 * (np.arange(512 * 768) % 97).reshape(768, 512) / 96.0
    texels = alpha.size
    for map_filter in ["nearest", "bilinear"]:
        m = glint.Material(particles=1e6, alpha_map=alpha, roughness_levels=64,
                           map_filter=map_filter)
        # The α map itself (8 bytes a texel), the family, and 56 levels' blocked tables.
        assert 17 * texels < m.map_bytes < (17 + 64 * 0.36) * texels, m.map_bytes
        wi, wo, uv, dx, dy, _ = _queries(50, seed=5)
        assert np.all(np.isfinite(m.eval(wi, wo, uv, dx, dy)["f_hat"]))


def _maps_strategy():
    """Random maps of one size (1–6 × 1–6): densities, roughness and tints in range with their
    edges, now and then a value out of range or not finite, and roughness levels 0–65."""
    from hypothesis import strategies as st

    bad = st.sampled_from([-1e-300, 1.0 + 2**-52, math.nan, math.inf, 7.0])

    def texels(values, shape):
        """A map of ``values``, one in five with one texel replaced by a bad value."""
        size = int(np.prod(shape))

        def build(drawn):
            values, corrupt = drawn
            array = np.array(values, dtype=float)
            if corrupt is not None:
                array[corrupt[0] % size] = corrupt[1]
            return array.reshape(shape)

        corrupt = st.one_of(*[st.none()] * 4, st.tuples(st.integers(0, size - 1), bad))
        return st.tuples(st.lists(values, min_size=size, max_size=size), corrupt).map(build)

    unit = st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1.0, 1e-10, 2.0**-33]))
    rough = st.one_of(st.sampled_from([0.05, 0.2, 1e-4, 1.0]), st.floats(1e-4, 1.0))
    return st.tuples(st.integers(1, 6), st.integers(1, 6)).flatmap(lambda hw: st.fixed_dictionaries({
        "density_map": st.none() | texels(unit, hw),
        "alpha_map": st.none() | texels(rough, hw),
        "tint_map": st.none() | texels(unit, (*hw, 3)),
        "roughness_levels": st.one_of(st.integers(1, 9), st.sampled_from([0, 64, 65])),
    }))


def test_random_maps_build_or_raise_value_errors_and_answer_finite():
    """Over random map shapes, values, roughness levels and tint channels (Hypothesis, fixed
    seed): a material builds or raises ValueError naming a map or roughness_levels (never a
    panic), and a built one answers finite, non-negative f_hat, in colour exactly when its
    tint is coloured."""
    from hypothesis import given, settings

    wi, wo, uv, dx, dy, _ = _queries(8, seed=21)

    @settings(max_examples=60, deadline=None, derandomize=True, database=None)
    @given(_maps_strategy())
    def check(maps):
        try:
            m = glint.Material(particles=1e7, gamma_degrees=3.0, **maps)
        except ValueError as error:
            assert any(name in str(error) for name in (
                "density_map", "alpha_map", "tint_map", "roughness_levels",
                "roughness levels")), str(error)
            return
        f = m.eval(wi, wo, uv, dx * 50, dy * 50)["f_hat"]
        assert np.all(np.isfinite(f)) and np.all(f >= 0)
        tint = maps["tint_map"]
        coloured = tint is not None and not (np.all(tint[..., 0] == tint[..., 1])
                                             and np.all(tint[..., 1] == tint[..., 2]))
        assert m.gray == (not coloured) and f.ndim == (2 if coloured else 1)

    check()


def test_read_map_image_reads_as_the_tracer(tmp_path):
    """glint.read_map_image: an 8-bit grey PNG as k/255 for data and sRGB-decoded for a colour,
    three equal channels, rows from the top; a file beyond the tracer's limits refused from its
    header with the tracer's message; an unknown kind refused naming the argument."""
    import struct
    import zlib

    def png(path, width, height, rows):
        def chunk(kind, data):
            body = kind + data
            return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))
        header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
        data = zlib.compress(b"".join(b"\x00" + bytes(r) for r in rows))
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data)
                         + chunk(b"IEND", b""))
        return path

    small = png(tmp_path / "small.png", 2, 2, [[0, 255], [128, 64]])
    data = glint.read_map_image(small)
    assert data.shape == (2, 2, 3) and data.dtype == np.float64
    assert np.array_equal(data[:, :, 0], np.array([[0, 255], [128, 64]]) / 255.0)
    assert np.array_equal(data[:, :, 0], data[:, :, 2])
    colour = glint.read_map_image(small, "colour")
    c = 128 / 255.0
    assert colour[1, 0, 1] == ((c + 0.055) / 1.055) ** 2.4
    liar = png(tmp_path / "liar.png", 60000, 60000, [])
    with pytest.raises(ValueError, match="60000 × 60000 pixels: wider or higher than the limit "
                                         "of 16384"):
        glint.read_map_image(liar)
    with pytest.raises(ValueError, match='kind must be "data" or "colour", not \'color\''):
        glint.read_map_image(small, "color")
