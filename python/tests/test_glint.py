"""The Python package against its contract: the same answers as `cargo xtask eval`, bit for
bit, for the same inputs; errors per row and per parameter; shapes; determinism under
parallelism."""

import json
import math
import os
import pathlib
import subprocess
import threading

import numpy as np
import pytest

import glint

REPO = pathlib.Path(__file__).resolve().parents[2]

MATERIALS = [
    dict(distribution="beckmann", alpha=0.1, particles=1e9, gamma_degrees=1.0, seed=7,
         dense_node_scale=2.0),
    dict(distribution="ggx", alpha=0.05, alpha_y=0.3, particles=2e7, gamma_degrees=3.0,
         epsilon=0.0, seed=3, multinomial="normal"),
    dict(distribution="beckmann", alpha=0.2, particles=1e6, gamma_degrees=2.0,
         fresnel={"conductor": {"eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.2]}}),
    dict(distribution="beckmann", alpha=0.1, particles=1e12, gamma_degrees=0.5,
         negligible_count=1e-12, fresnel={"dielectric": {"eta": 1.5}}),
    dict(distribution="beckmann", alpha=0.1, particles=1e12, gamma_degrees=1.0, seed=5,
         dense="sampled"),
]


def _json_material(kwargs):
    """The same material as a docs/eval.md JSON object."""
    spec = dict(kwargs)
    return spec


def _queries(n, seed):
    """n random queries near and away from the highlight, with a few awkward rows."""
    rng = np.random.default_rng(seed)
    theta = rng.uniform(0, 1.4, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    wi = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    wo = mirror + rng.normal(0, 0.08, (n, 3))
    wo[::5, 2] = -0.2  # some below the horizon
    uv = rng.uniform(-2, 3, (n, 2))
    side = 10 ** rng.uniform(-4, -1.5, n)
    dx = np.stack([side, rng.normal(0, 0.2, n) * side], 1)
    dy = np.stack([rng.normal(0, 0.2, n) * side, side], 1)
    u = rng.uniform(0, 1, (n, 4))
    return wi, wo, uv, dx, dy, u


def _xtask_eval(lines):
    """Answers from `cargo xtask eval`, one dict per line."""
    command = os.environ.get("GLINT_XTASK")
    command = [command, "eval"] if command else [
        "cargo", "run", "--release", "--quiet", "-p", "xtask", "--", "eval"]
    done = subprocess.run(command, input="\n".join(lines) + "\n", capture_output=True,
                          text=True, cwd=REPO, check=False)
    answers = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(answers) == len(lines), done.stderr[-2000:]
    return answers


def _same(a, b):
    """Bit-identical floats (NaN equal to NaN)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))


@pytest.mark.parametrize("index", range(len(MATERIALS)))
def test_eval_sample_pdf_match_json_lines_bit_for_bit(index):
    kwargs = MATERIALS[index]
    m = glint.Material(**kwargs)
    wi, wo, uv, dx, dy, u = _queries(120, seed=index)
    material = _json_material(kwargs)
    lines = []
    for i in range(len(wi)):
        common = {"material": material, "wi": wi[i].tolist()}
        lines.append(json.dumps({"op": "eval", **common, "wo": wo[i].tolist(),
                                 "uv": uv[i].tolist(), "duv_dx": dx[i].tolist(),
                                 "duv_dy": dy[i].tolist()}))
        lines.append(json.dumps({"op": "sample", **common, "u": u[i].tolist()}))
        lines.append(json.dumps({"op": "sample", **common, "u": u[i, :3].tolist()}))
        lines.append(json.dumps({"op": "pdf", **common, "wo": wo[i].tolist()}))
    answers = _xtask_eval(lines)
    r = m.eval(wi, wo, uv, dx, dy)
    s4 = m.sample(wi, u)
    s3 = m.sample(wi, u[:, :3])
    p = m.pdf(wi, wo)
    found = 0
    for i in range(len(wi)):
        e, a4, a3, ap = answers[4 * i: 4 * i + 4]
        assert "error" not in e, e
        assert r["error"][i] == ""
        for key in ("count", "expected_count", "d_hat", "f_hat", "f_smooth", "nodes_visited"):
            assert _same(r[key][i], e[key]), (i, key, r[key][i], e[key])
        bound = e.get("negligible_bound", math.nan)
        assert _same(r["negligible_bound"][i], bound)
        found += r["count"][i] > 0
        for sample, answer in ((s4, a4), (s3, a3)):
            if answer["wo"] is None:
                assert np.all(np.isnan(sample["wo"][i])) and sample["pdf"][i] == 0
            else:
                assert _same(sample["wo"][i], answer["wo"])
                assert _same(sample["pdf"][i], answer["pdf"])
                assert _same(sample["weight"][i], answer["weight"])
        assert _same(p[i], ap["pdf"])
    assert found > 0, "the comparison must include queries that find particles"


def test_the_first_materials_node_scale_changes_its_answers():
    """The first material's ``dense_node_scale=2.0`` reaches the queries the lattice leaves to
    its tree, so the bit-for-bit comparison above covers the field: at scale 1 some of the
    same 120 queries count differently."""
    rows = _queries(120, seed=0)[:5]
    scaled = glint.Material(**MATERIALS[0]).eval(*rows)["count"]
    unscaled = glint.Material(**{**MATERIALS[0], "dense_node_scale": 1.0}).eval(*rows)["count"]
    assert np.sum(scaled != unscaled) > 0


@pytest.mark.parametrize("index", range(len(MATERIALS)))
def test_f_hat_and_lean_eval_columns_are_evals_bit_for_bit(index):
    """``f_hat`` (a renderer's call) and ``eval`` without the expected count or the smooth BRDF
    give eval's f̂ bit for bit, in strided columns too; the skipped columns are NaN and bad rows
    NaN in ``f_hat``."""
    m = glint.Material(**MATERIALS[index])
    wi, wo, uv, dx, dy, _ = _queries(400, seed=30 + index)
    wo[5] = [0.0, 0.0, 0.0]  # refused: zero length
    dx[9] = [math.inf, 0.0]  # refused: a non-finite footprint
    full = m.eval(wi, wo, uv, dx, dy)
    lean = m.eval(wi, wo, uv, dx, dy, expected_count=False, f_smooth=False)
    for key in ("count", "d_hat", "f_hat", "nodes_visited", "negligible_bound", "error"):
        assert np.array_equal(lean[key], full[key]) or _same(lean[key], full[key]), key
    ok = full["error"] == ""
    assert np.all(np.isnan(lean["expected_count"])) and np.all(np.isnan(lean["f_smooth"]))
    assert ok.sum() == len(ok) - 2
    # Strided columns of one (n, 12) array, as a renderer packs its rows.
    packed = np.concatenate([wi, wo, uv, dx, dy], axis=1)
    f = m.f_hat(packed[:, 0:3], packed[:, 3:6], packed[:, 6:8], packed[:, 8:10],
                packed[:, 10:12])
    assert f.shape == full["f_hat"].shape
    assert _same(f[ok], full["f_hat"][ok]) and np.all(np.isnan(f[~ok]))
    assert np.any(f[ok] > 0), "the comparison must include queries that find particles"
    assert _same(m.f_hat(wi[3], wo[3], uv[3], dx[3], dy[3]), full["f_hat"][3])


def test_sample_weights_are_named_and_the_footprint_one_is_f_hats():
    """`smooth_weight` (and its deprecated name `weight`) is eval's sample weight; with a
    footprint, `footprint_weight` is f̂ at the sampled direction times cos θ_o / pdf, f̂ as
    eval's `eval` gives it there, bit for bit (what Rust's GlintBxdf::sample computes)."""
    m = glint.Material(**MATERIALS[0])
    wi, _, uv, dx, dy, u = _queries(200, seed=11)
    plain = m.sample(wi, u)
    s = m.sample(wi, u, uv, dx, dy)
    assert "footprint_weight" not in plain
    for key in ("wo", "pdf", "smooth_weight"):
        assert _same(s[key], plain[key])
    assert _same(s["weight"], s["smooth_weight"])
    sampled = s["pdf"] > 0
    assert sampled.sum() > 100 and (~sampled).sum() >= 0
    at = np.where(sampled[:, None], s["wo"], [0.0, 0.0, 1.0])
    f_hat = m.eval(wi, at, uv, dx, dy)["f_hat"]
    for i in range(len(wi)):
        if sampled[i]:
            assert _same(s["f_hat"][i], f_hat[i])
            assert _same(s["footprint_weight"][i], f_hat[i] * (s["wo"][i, 2] / s["pdf"][i]))
        else:
            assert s["footprint_weight"][i] == 0 and s["f_hat"][i] == 0
    assert (s["footprint_weight"] > 0).sum() > 0, "some sampled directions meet flakes"
    one = m.sample(wi[0], u[0], uv[0], dx[0], dy[0])
    assert _same(one["footprint_weight"], s["footprint_weight"][0])
    with pytest.raises(ValueError, match="uv, duv_dx and duv_dy"):
        m.sample(wi, u, uv)


def test_gamma_deg_is_the_deprecated_name_of_gamma_degrees():
    wi, wo, uv, dx, dy, _ = _queries(50, seed=3)
    new = glint.Material(particles=1e8, gamma_degrees=2.5).eval(wi, wo, uv, dx, dy)
    with pytest.warns(DeprecationWarning, match="gamma_degrees"):
        old = glint.Material(particles=1e8, gamma_deg=2.5)
    assert _same(old.eval(wi, wo, uv, dx, dy)["f_hat"], new["f_hat"])
    with pytest.warns(DeprecationWarning):
        positional = glint.Material("beckmann", 0.1, None, 1e8, 2.5)
    assert _same(positional.eval(wi, wo, uv, dx, dy)["f_hat"], new["f_hat"])
    with pytest.raises(ValueError, match="not both"):
        glint.Material(gamma_deg=2.5, gamma_degrees=2.5)


def test_the_readmes_python_snippet_runs():
    """The README's Python snippet (under "From Python"), as it stands there, runs and finds
    what it says: a convention change cannot leave it stale."""
    readme = (REPO / "README.md").read_text()
    section = readme[readme.index("## From Python"):]
    start = section.index("```python\n") + len("```python\n")
    code = section[start:section.index("```", start)]
    names = {}
    exec(compile(code, "README.md", "exec"), names)  # noqa: S102 (the project's own README)
    assert names["r"]["error"][0] == "" and names["r"]["f_hat"][0] >= 0
    assert names["s"]["pdf"][0] > 0 and names["s"]["smooth_weight"][0] > 0


def test_single_query_gives_scalars():
    m = glint.Material(particles=1e9, seed=7)
    r = m.eval([0, 0, 1], [0.1, 0, 0.99], [0.3, 0.4], [1e-3, 0], [0, 1e-3])
    assert np.ndim(r["count"]) == 0 and r["error"] == ""
    batch = m.eval([[0, 0, 1]], [[0.1, 0, 0.99]], [[0.3, 0.4]], [[1e-3, 0]], [[0, 1e-3]])
    assert r["count"] == batch["count"][0] and r["f_hat"] == batch["f_hat"][0]
    s = m.sample([0, 0, 1], [0.3, 0.6, 0.2, 0.9])
    assert s["wo"].shape == (3,)
    assert np.ndim(m.pdf([0, 0, 1], [0.1, 0, 0.99])) == 0


def test_coloured_fresnel_gives_rgb_columns():
    m = glint.Material(**MATERIALS[2])
    wi, wo, uv, dx, dy, u = _queries(10, seed=9)
    r = m.eval(wi, wo, uv, dx, dy)
    assert r["f_hat"].shape == (10, 3) and r["f_smooth"].shape == (10, 3)
    assert m.sample(wi, u)["weight"].shape == (10, 3)
    grey = glint.Material()
    assert grey.eval(wi, wo, uv, dx, dy)["f_hat"].shape == (10,)


@pytest.mark.parametrize("kwargs, name", [
    (dict(alpha=2.0), "alpha"),
    (dict(alpha=math.nan), "material.alpha"),
    (dict(alpha_y=-1.0), "alpha"),
    (dict(particles=1.5), "material.particles"),
    (dict(particles=0), "material.particles"),
    (dict(gamma_degrees=90), "gamma"),
    (dict(distribution="beckman"), "material.distribution"),
    (dict(multinomial="approximate"), "material.multinomial"),
    (dict(pdf_quadrature="gauss"), "material.pdf_quadrature"),
    (dict(seed=-1), "material.seed"),
    (dict(epsilon=-0.5), "epsilon"),
    (dict(negligible_count=-1.0), "negligible count"),
    (dict(fresnel={"conductor": {"eta": [1, 1], "k": [0, 0, 0]}}), "material.fresnel.conductor.eta"),
    (dict(fresnel={"metal": 1}), "material.fresnel"),
    (dict(fresnel={"dielectric": {"eta": math.inf}}), "material.fresnel"),
    (dict(pdf_points=0), "material.pdf_points"),
    (dict(pdf_points=2.5), "material.pdf_points"),
    (dict(gamma_degrees=1e-300), "material.gamma_degrees"),
    (dict(epsilon=1e300), "epsilon"),
    (dict(expected_footprint_area=0.0), "expected footprint area"),
])
def test_bad_parameters_raise_value_error_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name.replace(".", r"\.")):
        glint.Material(**kwargs)


def test_bad_rows_do_not_abort_the_batch_and_give_evals_message():
    m = glint.Material(particles=1e9, seed=7)
    good = ([0, 0, 1], [0.1, 0, 0.99], [0.3, 0.4], [1e-3, 0], [0, 1e-3])
    rows = [list(good) for _ in range(5)]
    rows[1][0] = [0, 0, 0]            # a zero vector
    rows[2][1] = [math.nan, 0, 1]     # NaN
    rows[3][3] = [math.inf, 0]        # a non-finite footprint
    rows[4][2] = [0.3, 0.4]
    columns = [np.array([row[k] for row in rows], dtype=float) for k in range(5)]
    r = m.eval(*columns)
    assert list(r["error"][[0, 4]]) == ["", ""]
    assert r["error"][1] == "wi has zero length"
    assert r["error"][2].startswith("wo must hold finite numbers")
    assert r["error"][3].startswith("duv_dx must hold finite numbers")
    for key in ("count", "f_hat", "expected_count", "nodes_visited"):
        assert np.all(np.isnan(r[key][1:4])) and not np.isnan(r[key][0])
    assert r["count"][0] == r["count"][4]
    # The zero-vector message is eval's own.
    line = json.dumps({"op": "eval", "material": MATERIALS[0], "wi": [0, 0, 0],
                       "wo": [0.1, 0, 0.99], "uv": [0.3, 0.4], "duv_dx": [1e-3, 0],
                       "duv_dy": [0, 1e-3]})
    assert _xtask_eval([line])[0]["error"] == "line 1: wi has zero length"
    s = m.sample([[0, 0, 1], [0, 0, 1]], [[0.1, 0.2, 0.3, 1.0], [0.1, 0.2, 0.3, 0.4]])
    assert "[0, 1)" in s["error"][0] and s["error"][1] == ""
    assert np.all(np.isnan(s["wo"][0]))
    assert np.isnan(m.pdf([[0, 0, 0]], [[0, 0, 1]])[0])


def test_shape_mismatches_raise():
    m = glint.Material()
    with pytest.raises(ValueError, match="wo"):
        m.eval(np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((3, 2)), np.zeros((3, 2)),
               np.zeros((3, 2)))
    with pytest.raises(ValueError, match="uv"):
        m.eval(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 2)),
               np.zeros((3, 2)))
    with pytest.raises(ValueError, match="u must have shape"):
        m.sample(np.zeros((3, 3)), np.zeros((3, 5)))


def test_batches_are_deterministic_in_any_split_and_thread():
    m = glint.Material(particles=1e8, seed=1)
    wi, wo, uv, dx, dy, _ = _queries(3000, seed=11)
    whole = m.eval(wi, wo, uv, dx, dy)
    parts = [m.eval(wi[k:k + 7], wo[k:k + 7], uv[k:k + 7], dx[k:k + 7], dy[k:k + 7])
             for k in range(0, 3000, 7)]
    for key in ("count", "f_hat", "nodes_visited"):
        assert _same(whole[key], np.concatenate([p[key] for p in parts]))
    results = [None, None]

    def run(slot):
        results[slot] = m.eval(wi, wo, uv, dx, dy)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(_same(r["f_hat"], whole["f_hat"]) for r in results)


def _fork_child(material, rows, connection):
    """In a forked child: the material's answers to ``rows``, and a material built there."""
    try:
        r = material.eval(*rows)
        fresh = glint.Material(**MATERIALS[0]).eval(*rows)
        connection.send((r["count"], r["f_hat"], r["error"].tolist(), fresh["count"]))
    finally:
        connection.close()


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # Python 3.12 warns of fork
def test_a_forked_child_answers_large_batches():
    """A process that used the package and then forks (multiprocessing's default on Linux)
    answers batches of more than 256 rows (several parallel tasks) in the child, as the
    parent does. The parent's worker threads do not survive the fork; the child builds its
    own."""
    import multiprocessing

    m = glint.Material(**MATERIALS[0])
    wi, wo, uv, dx, dy, _ = _queries(5000, seed=21)
    rows = (wi, wo, uv, dx, dy)
    parent = m.eval(*rows)  # the parent's pool exists and has worked
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    child = context.Process(target=_fork_child, args=(m, rows, sender))
    child.start()
    sender.close()
    try:
        assert receiver.poll(120), "the forked child did not answer within 120 s (deadlock?)"
        count, f_hat, errors, fresh_count = receiver.recv()
    finally:
        child.join(10)
        if child.is_alive():
            child.kill()
            child.join()
    assert child.exitcode == 0
    assert _same(count, parent["count"]) and _same(f_hat, parent["f_hat"])
    assert errors == parent["error"].tolist()
    assert _same(fresh_count, parent["count"])
    # The parent still answers after its child is gone.
    assert _same(m.eval(*rows)["count"], parent["count"])


_INTERRUPTED_BATCH = """
import sys, numpy as np, glint
m = glint.Material(distribution="beckmann", alpha=0.1, particles=1e12, gamma_degrees=1.0,
                   epsilon=0.0, seed=1)
n = 1_000_000
rng = np.random.default_rng(5)
wi = np.tile([0.0, 0.0, 1.0], (n, 1))
wo = np.tile([0.0, 0.0, 1.0], (n, 1)) + rng.normal(0, 0.01, (n, 3))
uv = rng.uniform(0, 1, (n, 2))
dx = np.tile([3e-3, 0.0], (n, 1))
dy = np.tile([0.0, 3e-3], (n, 1))
m.eval(wi[:10], wo[:10], uv[:10], dx[:10], dy[:10])
print("started", flush=True)
try:
    m.eval(wi, wo, uv, dx, dy)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted", flush=True)
"""


def test_ctrl_c_interrupts_a_large_batch():
    """Ctrl-C (SIGINT) stops a batch that runs for a long time with KeyboardInterrupt: the
    package takes the GIL back between blocks of rows to run Python's signal handlers. The
    batch (10^6 dense queries) takes far longer than the second it is given."""
    from interrupt import interrupted_output
    assert interrupted_output(_INTERRUPTED_BATCH) == "interrupted"


@pytest.mark.parametrize("kwargs, message", [
    (dict(distribution=b"beckmann"), "material.distribution"),
    (dict(distribution=object()), "material.distribution"),
    (dict(multinomial=object()), "material.multinomial"),
    (dict(pdf_quadrature={1, 2}), "material.pdf_quadrature"),
    (dict(distribution=3), "material.distribution"),
    (dict(seed=10**400), r"material\.seed = an integer of 401 digits must be a whole number "
                         r"in \[0, 2\^64\)"),
    (dict(seed=2**64), r"material\.seed = 1\.8446744073709552e19 must be a whole number in "
                       r"\[0, 2\^64\)"),
    (dict(seed=1.7), r"material\.seed = 1\.7 must be a whole number"),
    (dict(particles=2**53 + 1), r"material\.particles = 9007199254740993 must be a whole"),
    (dict(alpha=10**400), r"material\.alpha = an integer of 401 digits must be a finite"),
    (dict(fresnel={"conductor": {"eta": [1e300, 1, 1], "k": [0, 0, 0]}}),
     r"material\.fresnel\.conductor\.eta: Fresnel eta = 1e300 is invalid: eta must be in "
     r"\[1e-3, 1e3\] and k in \[0, 1e3\]"),
    (dict(fresnel={"conductor": {"eta": [1, 1, 1], "k": [0, 0, 0], "kk": 1}}),
     r"unknown material\.fresnel\.conductor field `kk`"),
    (dict(fresnel={"dielectric": {"eta": np.float32("nan")}}),
     r"material\.fresnel\.dielectric\.eta must be a finite number"),
    (dict(fresnel=5), r"material\.fresnel 5 is not valid"),
])
def test_bad_parameters_name_the_right_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        glint.Material(**kwargs)


def test_integers_are_exact_as_in_eval():
    """Seeds are taken exactly (2^53 + 1 is not 2^53) and agree with `cargo xtask eval` given
    the same integer literal; NumPy integers are integers."""
    wi, wo, uv, dx, dy, _ = _queries(200, seed=5)
    counts = {}
    for seed in (2**53, 2**53 + 1, 2**64 - 1, np.uint64(2**64 - 1)):
        m = glint.Material(particles=1e9, seed=seed)
        counts[int(seed)] = m.eval(wi, wo, uv, dx, dy)["count"]
    assert not _same(counts[2**53], counts[2**53 + 1])
    line = json.dumps({"op": "eval", "material": dict(particles=1e9, seed=2**53 + 1),
                       "wi": wi[0].tolist(), "wo": wo[0].tolist(), "uv": uv[0].tolist(),
                       "duv_dx": dx[0].tolist(), "duv_dy": dy[0].tolist()})
    line = line.replace('"particles"', '"distribution": "beckmann", "alpha": 0.1, '
                        '"gamma_deg": 1.0, "particles"')
    assert _same(_xtask_eval([line])[0]["count"], counts[2**53 + 1][0])


def test_numpy_numbers_inside_fresnel():
    plain = glint.Material(**MATERIALS[2])
    fresnel = {"conductor": {"eta": np.array([0.2, 0.9, 1.1]),
                             "k": [np.float32(3.9).item(), np.float64(2.4), np.float16(2.2)]}}
    numpy = glint.Material(**{**MATERIALS[2], "fresnel": fresnel})
    wi, wo, uv, dx, dy, _ = _queries(50, seed=3)
    a, b = plain.eval(wi, wo, uv, dx, dy), numpy.eval(wi, wo, uv, dx, dy)
    assert np.allclose(a["f_hat"], b["f_hat"], rtol=1e-3) and _same(a["count"], b["count"])
    exact = glint.Material(**{**MATERIALS[2], "fresnel": {"conductor": {
        "eta": np.array([0.2, 0.9, 1.1]), "k": np.array([3.9, 2.4, 2.2])}}})
    assert _same(exact.eval(wi, wo, uv, dx, dy)["f_hat"], a["f_hat"])
    glint.Material(fresnel={"dielectric": {"eta": np.float64(1.5)}})


@pytest.mark.parametrize("index", range(len(MATERIALS)))
def test_materials_pickle_and_copy(index):
    """pickle, copy and deepcopy rebuild a material from its parameters: the same answers,
    bit for bit."""
    import copy
    import pickle

    m = glint.Material(**MATERIALS[index], pdf_points=32)
    wi, wo, uv, dx, dy, u = _queries(300, seed=index)
    expected = m.eval(wi, wo, uv, dx, dy)
    for other in (pickle.loads(pickle.dumps(m)), copy.copy(m), copy.deepcopy(m)):
        assert isinstance(other, glint.Material) and other.gray == m.gray
        r = other.eval(wi, wo, uv, dx, dy)
        for key in ("count", "f_hat", "f_smooth", "nodes_visited"):
            assert _same(r[key], expected[key]), key
        assert _same(other.sample(wi, u)["wo"], m.sample(wi, u)["wo"])
        assert _same(other.pdf(wi, wo), m.pdf(wi, wo))
    assert "glint.Material(" in repr(m)


def test_extreme_inputs_give_finite_answers_or_named_errors():
    """The ends of the accepted ranges answer with finite, non-negative numbers; just beyond
    them, an error naming the field, as `cargo xtask eval` gives it."""
    for eta, k in ((1e-3, 0.0), (1e3, 1e3), (1.0, 0.0), (1e-3, 1e3)):
        m = glint.Material(alpha=0.3, particles=1e9,
                           fresnel={"conductor": {"eta": [eta] * 3, "k": [k] * 3}})
        wi, wo, uv, dx, dy, _ = _queries(200, seed=8)
        wi[:20] = [1.0, 0.0, 1e-6]  # grazing
        r = m.eval(wi, wo, uv, dx, dy)
        for key in ("f_hat", "f_smooth", "count"):
            assert np.all(np.isfinite(r[key]) & (r[key] >= 0)), (eta, k, key)
    m = glint.Material()
    edge = 1e15
    r = m.eval([[0, 0, 1]] * 3, [[0.1, 0, 0.99]] * 3, [[0.3, 0.4]] * 3,
               [[edge, 0], [1e300, 0], [1e154, 0]], [[0, edge], [0, 1e300], [0, 1e154]])
    assert r["error"][0] == "" and np.isfinite(r["count"][0]) and r["count"][0] > 0
    assert r["error"][1] == "duv_dx must hold numbers within ±1e15, not [1e300, 0.0]"
    assert r["error"][2].startswith("duv_dx must hold numbers within ±1e15")


def test_directions_near_the_horizon_give_finite_answers():
    """ω_i = (0.6, −0.8, 1e-200), ω_o = (−0.6, 0.3, 1e-200) gave f_smooth NaN for every
    distribution, and the GGX pdf at γ = 60° with ω_i 1e-300 above the horizon NaN (issue 64)."""
    for distribution in glint.DISTRIBUTIONS:
        m = glint.Material(distribution=distribution, alpha=0.2, particles=1e9,
                           gamma_degrees=60.0)
        for z in (1e-100, 1e-200, 1e-300):
            r = m.eval([0.6, -0.8, z], [-0.6, 0.3, z], [0.3, 0.4], [1e-3, 0], [0, 1e-3])
            assert r["error"] == "", r["error"]
            for key in ("f_hat", "f_smooth", "count", "expected_count"):
                assert np.isfinite(r[key]) and r[key] >= 0, (distribution, z, key, r[key])
            pdf = m.pdf([0.6, -0.8, z], [-0.6, 0.3, 0.5])
            assert np.isfinite(pdf) and pdf >= 0, (distribution, z, pdf)
