"""glint.farm's arguments and frame specifications, without a cluster: every bad argument is
refused with a ValueError or TypeError naming it before any folder, lock or cluster exists
(property tests with Hypothesis), every good one reaches the cluster, and the frames a run
renders are the ones specified, in order, each once."""

import itertools
import math
import os
import re
import socket

import numpy as np
import pytest

from test_render import SCENE

pytest.importorskip("distributed")
pytest.importorskip("hypothesis")  # the package's test extra
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import glint.farm as farm  # noqa: E402
from farm_stubs import ClusterStarted, no_cluster, scene  # noqa: E402,F401

#: Few examples each, the same in every run (CI never meets a new example by chance), no
#: example database written, no deadline (a run creates a folder and a lock).
FAST = settings(max_examples=60, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
#: The pure frame-list properties: more examples, as cheap.
MANY = settings(max_examples=200, deadline=None, derandomize=True, database=None)


#: Each integer argument: its valid range (None: no upper limit).
RANGES = {"tile": (1, None), "spp": (1, 65536), "workers": (1, 1024),
          "threads": (1, farm.MAX_THREADS),
          "retries": (0, None), "frames_in_flight": (1, None)}

#: Values that are not ints, for any argument.
NOT_INTS = st.one_of(st.booleans(), st.floats(allow_nan=True), st.text(max_size=3),
                     st.lists(st.integers(), max_size=2), st.just(b"1"), st.just(object()),
                     st.floats().map(np.float64), st.just(np.bool_(True)))


def _out_of_range(name):
    low, high = RANGES[name]
    below = st.integers(max_value=low - 1)
    return below if high is None else st.one_of(below, st.integers(min_value=high + 1))


@st.composite
def bad_arguments(draw):
    """(name, keyword arguments) with one argument wrong: out of range or not an int."""
    name = draw(st.sampled_from(sorted(RANGES)))
    value = draw(st.one_of(_out_of_range(name), NOT_INTS.filter(lambda v: v is not None)))
    return name, {name: value}


def _refused(scene, out, kwargs, names):
    with pytest.raises((TypeError, ValueError)) as error:
        farm.render_frames(scene, kwargs.pop("frames", (0, 0)), out, progress=False, **kwargs)
    assert not isinstance(error.value, ClusterStarted)
    assert any(n in str(error.value) for n in names), str(error.value)
    assert not os.path.exists(out), "nothing is created before the arguments are checked"


@FAST
@given(bad=bad_arguments())
def test_bad_arguments_are_refused_naming_them(scene, tmp_path, no_cluster, bad):
    name, kwargs = bad
    _refused(scene, tmp_path / "out", kwargs, [name])


@FAST
@given(bad=st.one_of(
    st.tuples(st.integers(), st.integers()).filter(lambda p: p[1] < p[0]),  # reversed pairs
    st.tuples(NOT_INTS, st.integers()), st.tuples(st.integers(), NOT_INTS),
    st.lists(NOT_INTS, min_size=1, max_size=3).map(lambda v: [0] + v),
    st.integers(), st.text(max_size=4), st.none(), st.floats(), st.just({0: 1}),
    st.integers(min_value=2**53 + 1).map(lambda f: [f]),
    st.integers(max_value=-2**53 - 1).map(lambda f: (f, 0)),
    st.integers(min_value=100_000, max_value=2**53).map(lambda n: (0, n)),
    st.just(itertools.count()), st.just(range(0, 10**12)),
))
def test_bad_frames_are_refused_naming_them(scene, tmp_path, no_cluster, bad):
    _refused(scene, tmp_path / "out", {"frames": bad}, ["frames"])


@FAST
@given(resolution=st.one_of(
    st.tuples(st.integers(max_value=0), st.integers(1, 64)),
    st.tuples(st.integers(1, 64), st.integers(min_value=16385)),
    st.tuples(NOT_INTS, st.integers(1, 64)), st.integers(), st.text(max_size=5),
    st.lists(st.integers(1, 64), min_size=3, max_size=4).map(tuple)))
def test_bad_resolutions_are_refused_naming_them(scene, tmp_path, no_cluster, resolution):
    _refused(scene, tmp_path / "out", {"resolution": resolution}, ["resolution"])


@FAST
@given(timeout=st.one_of(st.floats(max_value=0.0), st.just(float("inf")), st.just(float("nan")),
                         st.text(max_size=3), st.booleans()))
def test_bad_worker_timeouts_are_refused_naming_them(scene, tmp_path, no_cluster, timeout):
    _refused(scene, tmp_path / "out", {"worker_timeout": timeout}, ["worker_timeout"])


def test_other_bad_arguments_are_refused_naming_them(scene, tmp_path, no_cluster):
    out = tmp_path / "out"
    _refused(scene, out, {"workers": 2, "scheduler": "tcp://127.0.0.1:8786"},
             ["scheduler", "workers"])
    _refused(scene, out, {"client": object(), "workers": 1}, ["client"])
    _refused(scene, out, {"scheduler": 8786}, ["scheduler"])
    _refused(scene, out, {"on_tile": "print"}, ["on_tile"])
    _refused(7, out, {}, ["scene"])
    with pytest.raises(TypeError, match="out"):
        farm.render_frames(scene, (0, 0), 3.5, progress=False)
    with pytest.raises(ValueError, match=r"spp must be in 1\.\.=65536, not 0"):
        farm.render_frames(scene, (0, 0), out, spp=0)


#: Frame specifications that are not a pair: lists, tuples of other lengths, ranges,
#: generators, NumPy arrays, each of ints with repeats.
FRAME_LISTS = st.lists(st.integers(-2**53, 2**53) | st.integers(-3, 3), max_size=12)


@MANY
@given(values=FRAME_LISTS, kind=st.sampled_from(["list", "tuple", "generator", "numpy"]))
def test_frames_are_the_ones_given_each_once_in_order(values, kind):
    if kind == "tuple" and len(values) == 2:
        values = values + [values[0]]
    spec = {"list": lambda v: v, "tuple": tuple, "generator": lambda v: (f for f in v),
            "numpy": lambda v: np.array(v, dtype=np.int64)}[kind](values)
    expected = []
    for f in values:
        if f not in expected:
            expected.append(f)
    frames = farm._frame_list(spec)
    assert frames == expected and all(type(f) is int for f in frames)


@MANY
@given(first=st.integers(-2**53, 2**53), count=st.integers(1, 100_000))
def test_a_pair_is_first_to_last_inclusive(first, count):
    last = first + count - 1
    if last > 2**53:
        with pytest.raises(ValueError, match="frames"):
            farm._frame_list((first, last))
        return
    frames = farm._frame_list((first, last))
    assert len(frames) == count and frames[0] == first and frames[-1] == last
    assert farm._frame_list(range(first, min(last, first + 50) + 1)) == frames[:51]


@pytest.fixture
def fake_probe(monkeypatch, scene):
    """glint.farm's one-pixel probe render replaced by its result for ``scene``'s settings:
    what the property test of good arguments checks is the checking, not the tracer."""
    def probe(path, **kwargs):
        resolution = kwargs.get("resolution") or (48, 32)
        return {"stats": {"resolution": list(resolution), "spp": kwargs.get("spp") or 4,
                          "sources": [str(path)]}}

    monkeypatch.setattr(farm, "render", probe)


@FAST
@given(kwargs=st.fixed_dictionaries({}, optional={
    "tile": st.integers(1, 10**6), "spp": st.sampled_from([1, 2, 65536]),
    "threads": st.integers(1, farm.MAX_THREADS), "retries": st.integers(0, 10**6),
    "frames_in_flight": st.integers(1, 10**6), "worker_timeout": st.floats(1e-3, 1e6) | st.none(),
    "resolution": st.tuples(st.integers(1, 16384), st.integers(1, 16384)),
    "workers": st.integers(1, 1024)}),
    frames=st.one_of(st.tuples(st.integers(0, 9), st.integers(9, 20)),
                     st.lists(st.integers(0, 20), min_size=1, max_size=5),
                     st.lists(st.integers(0, 20), min_size=1).map(iter)))
def test_good_arguments_reach_the_cluster(scene, tmp_path, no_cluster, fake_probe, kwargs,
                                          frames):
    with pytest.raises(ClusterStarted):
        farm.render_frames(scene, frames, tmp_path / "out", progress=False, **kwargs)
    assert not (tmp_path / "out" / farm.LOCK_NAME).exists(), "the lock is released"


def test_no_frames_is_nothing_to_do(scene, tmp_path, no_cluster):
    assert farm.render_frames(scene, [], tmp_path / "out") == []
    assert farm.render_frames(scene, iter(()), tmp_path / "out") == []


def test_the_command_line_refuses_bad_counts_before_a_cluster(scene, tmp_path, no_cluster,
                                                              capsys):
    for args, name in [(["--workers", "0"], "workers"), (["--workers", "-1", "--threads", "1"],
                                                         "workers"),
                       (["--workers", "0", "--threads", "1"], "workers"),
                       (["--threads", "0"], "threads"), (["--tile", "0"], "tile"),
                       (["--retries", "-1"], "retries"), (["--spp", "0"], "65536"),
                       (["--spp", "65537"], "spp"), (["--worker-timeout", "0"], "worker_timeout"),
                       (["--frames", "0..100000"], "frames")]:
        assert farm.main([str(scene), "--out", str(tmp_path / "out"), *args]) == 2
        error = capsys.readouterr().err
        assert error.startswith("error:") and name in error, (args, error)
        assert "4294967295" not in error and "Traceback" not in error


def test_a_scheduler_address_that_is_not_one_is_named(scene, tmp_path, capsys):
    for address in ["inproc://x", "nonsense"]:
        assert farm.main([str(scene), "--out", str(tmp_path / "out"), "--scheduler",
                          address]) == 2
        error = capsys.readouterr().err
        assert error.startswith(f"error: scheduler {address!r} is not a Dask scheduler address")
    # Many in a row: a Client that failed must not be collected inside the next one's start,
    # where distributed deadlocks (this hung about one run in five before the farm collected
    # it at once).
    for _ in range(25):
        for address in ["inproc://x", "nonsense"]:
            with pytest.raises(ValueError, match="scheduler"):
                farm.render_frames(scene, (0, 0), tmp_path / "out", scheduler=address,
                                   progress=False)


def test_a_scheduler_without_workers_is_an_error_not_a_wait(scene, tmp_path, capsys):
    from dask.distributed import LocalCluster
    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as empty:
        code = farm.main([str(scene), "--out", str(tmp_path / "out"), "--scheduler",
                          empty.scheduler_address, "--worker-timeout", "0.5", "--quiet"])
    error = capsys.readouterr().err
    assert code == 2 and "no Dask worker" in error and "worker_timeout" in error, error
    assert empty.scheduler_address in error


def test_a_scene_with_pixel_bounds_is_refused(tmp_path, no_cluster):
    scene = tmp_path / "crop.toml"
    scene.write_text(SCENE.format(spp=4).replace("spp = 4", "spp = 4\npixel_bounds = [0, 8, 0, 8]"))
    if farm.tomllib is None:
        pytest.skip("no TOML reader (Python < 3.11 without tomli): the farm cannot see the setting")
    with pytest.raises(ValueError, match=re.escape("pixel_bounds = [0, 8, 0, 8]") + ".*whole"):
        farm.render_frames(scene, (0, 0), tmp_path / "out", progress=False)


def test_lock_holder_is_read_back(tmp_path):
    lock = farm._FolderLock(str(tmp_path))
    with lock:
        assert lock._holder() == (os.getpid(), socket.gethostname())
    assert not (tmp_path / farm.LOCK_NAME).exists()


#: A camera path that is degenerate at frame 2 alone: the eye passes over the look-at point
#: looking straight down, along the up vector.
DEGENERATE_AT_2 = SCENE.replace('''[[camera.keyframes]]
frame = 10
position = [0.5, 1, 3]''', '''[[camera.keyframes]]
frame = 4
position = [0, 1, -3]''')


def test_a_degenerate_frame_is_refused_before_any_frame_renders(tmp_path, no_cluster, capsys):
    """Frames 0, 1 and 3 are valid and 2 is not: the run is refused before anything is created
    or rendered (no cluster, no folder), as cargo xtask render --frames refuses, with the
    tracer's message and no traceback."""
    path = tmp_path / "through.toml"
    path.write_text(DEGENERATE_AT_2.format(spp=1))
    out = tmp_path / "out"
    assert farm.main([str(path), "--frames", "0..3", "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("error:") and "camera at frame 2" in error, error
    assert "Traceback" not in error
    assert not out.exists()
    with pytest.raises(ValueError, match="camera at frame 2"):
        farm.render_frames(path, [3, 2], out, progress=False)


def test_a_tile_glint_refuses_is_returned_not_raised(tmp_path):
    """On a worker, glint's refusal of a tile is a value (never retried by Dask, no worker
    traceback), which the client raises with glint's message."""
    path = tmp_path / "through.toml"
    path.write_text(DEGENERATE_AT_2.format(spp=1))
    result = farm.render_tile(str(path), 2, (0, 1, 0, 1), None, 1, 1)
    assert isinstance(result, farm.TileError) and "camera at frame 2" in result.message
    bounds, image, stats, before, after = farm.render_tile(str(path), 3, (0, 1, 0, 1), None, 1, 1)
    assert bounds == (0, 1, 0, 1) and image.shape == (1, 1, 3)


def test_out_naming_a_file_says_so(scene, tmp_path, no_cluster, capsys):
    out = tmp_path / "frames.exr"
    out.write_bytes(b"not a folder")
    assert farm.main([str(scene), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert f"error: out {str(out)!r} is a file, not a folder" in error, error
    assert "Errno" not in error and "Traceback" not in error
    with pytest.raises(NotADirectoryError, match="is a file, not a folder"):
        farm.render_frames(scene, (0, 0), out, progress=False)


@pytest.mark.parametrize("args", [["--frames", "0..1", "--frames", "2..3"],
                                  ["--frames=0..1", "--frames", "0..1"],
                                  ["--spp", "4", "--spp", "8"], ["--quiet", "--quiet"],
                                  ["--scheduler", "tcp://a:1", "--scheduler", "tcp://b:1"]])
def test_an_option_given_twice_is_refused(scene, tmp_path, no_cluster, capsys, args):
    with pytest.raises(SystemExit) as exit:
        farm.main([str(scene), "--out", str(tmp_path / "out"), *args])
    assert exit.value.code == 2
    error = capsys.readouterr().err
    assert f"{args[-2].split('=')[0]} is given twice" in error, error
    assert not (tmp_path / "out").exists()


def test_an_unreachable_scheduler_fails_after_the_connect_timeout(scene, tmp_path, capsys):
    """Nothing listens at the address: the run fails after --connect-timeout (1 s here), with a
    message naming the address and the option, not after Dask's 30 s."""
    import time
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    start = time.monotonic()
    code = farm.main([str(scene), "--out", str(tmp_path / "out"), "--scheduler", address,
                      "--connect-timeout", "1", "--quiet"])
    elapsed = time.monotonic() - start
    error = capsys.readouterr().err
    assert code == 2, error
    assert error.startswith(f"error: cannot reach the Dask scheduler at {address!r} within 1 s "
                            "(--connect-timeout)"), error
    assert elapsed < 20, elapsed
    for bad in (0, -1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="connect_timeout"):
            farm.render_frames(scene, (0, 0), tmp_path / "out", scheduler=address,
                               connect_timeout=bad, progress=False)
