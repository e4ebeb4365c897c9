"""glint.farm on a real Dask LocalCluster of two worker processes: frames merged from tiles
equal `cargo xtask render --frames`'s byte for byte, a worker killed in the middle of a run
changes nothing, a run interrupted and started again renders only what is missing, frames
whose outputs are damaged or another run's are rendered again, and a scene edited during a run
stops it without recording a frame mixed from two versions. (Checks without a cluster are in
test_farm_arguments.py and test_farm_outputs.py.)"""

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

import glint
from test_render import SCENE, _same_files, _scene, _xtask_render

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def cluster():
    """A local Dask cluster of two worker processes, shared by the farm tests."""
    from dask.distributed import Client, LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as local, Client(local) as client:
        yield client


def _reference(tmp_path, scene, frames, spp=None):
    out = tmp_path / "cli"
    args = ["--frames", f"{frames[0]}..{frames[-1]}"] + (["--spp", str(spp)] if spp else [])
    _xtask_render(scene, out, *args)
    return out


def _assert_frames_equal(farm_out, cli_out, stem, frames):
    for f in frames:
        for extension in (".exr", ".png"):
            name = f"{stem}_{f:04d}{extension}"
            assert _same_files(farm_out / name, cli_out / name), name
        summary = json.loads((farm_out / f"{stem}_{f:04d}.json").read_text())
        cli = json.loads((cli_out / f"{stem}_{f:04d}.json").read_text())
        assert summary["glint_queries"] == cli["glint_queries"]
        assert summary["rays"] == cli["rays"]


def test_farm_frames_are_the_command_lines(tmp_path, cluster):
    from glint.farm import render_frames
    scene = _scene(tmp_path)
    seen = []
    written = render_frames(scene, (0, 2), tmp_path / "farm", tile=24, client=cluster,
                            threads=1, progress=False, frames_in_flight=1,
                            on_tile=lambda f, b: seen.append((f, b)))
    assert len(written) == 9 and len(seen) == 12
    # One frame in flight: every tile of a frame arrives before any of the next.
    assert [f for f, _ in seen] == [0] * 4 + [1] * 4 + [2] * 4
    _assert_frames_equal(tmp_path / "farm", _reference(tmp_path, scene, [0, 1, 2]), "floor",
                         [0, 1, 2])
    # Everything done: a second run renders nothing; --overwrite renders again, identically.
    assert render_frames(scene, (0, 2), tmp_path / "farm", tile=24, client=cluster,
                         progress=False) == []
    # Through the scheduler's address, as `--scheduler` connects.
    again = render_frames(scene, (1, 1), tmp_path / "farm", tile=16,
                          scheduler=cluster.scheduler.address, overwrite=True, progress=False)
    assert len(again) == 3
    _assert_frames_equal(tmp_path / "farm", tmp_path / "cli", "floor", [1])
    # A changed scene file is not the recorded one: its frames render again.
    scene.write_text(SCENE.format(spp=4).replace("power = 20", "power = 30"))
    assert len(render_frames(scene, (0, 0), tmp_path / "farm", tile=24, client=cluster,
                             progress=False)) == 3


def test_a_killed_worker_changes_nothing(tmp_path, cluster):
    from glint.farm import render_frames
    scene = _scene(tmp_path, spp=64)
    before = set(cluster.run(os.getpid).values())
    killed = []

    def kill_one(frame, bounds):
        if not killed:
            pid = sorted(before)[0]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    render_frames(scene, (0, 2), tmp_path / "farm", tile=16, client=cluster, threads=1,
                  progress=False, on_tile=kill_one)
    assert killed
    # The nanny started a new worker process in place of the killed one.
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        after = set(cluster.run(os.getpid).values())
        if killed[0] not in after and len(after) == 2:
            break
        time.sleep(0.5)
    assert killed[0] not in after
    _assert_frames_equal(tmp_path / "farm", _reference(tmp_path, scene, [0, 1, 2]), "floor",
                         [0, 1, 2])


def test_an_interrupted_run_resumes_with_what_is_missing(tmp_path):
    scene = _scene(tmp_path, spp=256)
    out = tmp_path / "farm"
    command = [sys.executable, "-m", "glint.farm", str(scene), "--frames", "0..3", "--out",
               str(out), "--tile", "24", "--workers", "1", "--threads", "1"]
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "floor_0000.json").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert (out / "floor_0000.json").exists()
    first.send_signal(signal.SIGINT)
    _, errors = first.communicate(timeout=60)
    done = sorted(p.name for p in out.glob("floor_*.json"))
    assert first.returncode == 130, errors[-2000:]
    assert 1 <= len(done) < 4, done
    assert not list(out.glob("*.partial-*")), "no partial outputs are left"
    stamps = {name: (out / name).stat().st_mtime_ns for name in done}
    second = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert second.returncode == 0, second.stderr[-2000:]
    for name in done:
        assert (out / name).stat().st_mtime_ns == stamps[name], f"{name} was rendered again"
        assert f"frame {int(name[6:10])}: done already" in second.stderr
    _assert_frames_equal(out, _reference(tmp_path, scene, [0, 1, 2, 3]), "floor", [0, 1, 2, 3])


def test_frames_listed_twice_and_damaged_outputs(tmp_path, cluster):
    from glint.farm import render_frames
    scene = _scene(tmp_path)
    out = tmp_path / "farm"
    written = render_frames(scene, [1, 0, 1], out, tile=24, client=cluster, threads=1,
                            progress=False)
    assert sorted(os.path.basename(p) for p in written) == [
        f"floor_000{f}.{e}" for f in (0, 1) for e in ("exr", "json", "png")]
    cli = _reference(tmp_path, scene, [0, 1])
    _assert_frames_equal(out, cli, "floor", [0, 1])
    # The tiles' statistics merged per material: the whole frame's (node counts are exact).
    for f in (0, 1):
        farm = json.loads((out / f"floor_{f:04d}.json").read_text())
        whole = json.loads((cli / f"floor_{f:04d}.json").read_text())
        assert [m["name"] for m in farm["materials"]] == [m["name"] for m in whole["materials"]]
        for mine, theirs in zip(farm["materials"] + [farm], whole["materials"] + [whole]):
            for key in ("glint_queries", "negligible_queries", "nodes_per_query",
                        "overlapping_nodes_per_query", "particles_histogram",
                        "particles_per_query_p99"):
                assert mine[key] == theirs[key], key
            for key in ("particles_per_query", "negligible_bound"):
                assert mine[key] == pytest.approx(theirs[key], rel=1e-9, abs=1e-300), key
    # A truncated EXR, and another run's EXR (1 spp) beside this run's PNG and JSON: neither
    # frame is done, both render again.
    (out / "floor_0000.exr").write_bytes((out / "floor_0000.exr").read_bytes()[:100])
    glint.write_exr(out / "floor_0001.exr", glint.render(scene, frame=1, spp=1)["image"])
    again = render_frames(scene, (0, 1), out, tile=24, client=cluster, threads=1,
                          progress=False)
    assert len(again) == 6
    _assert_frames_equal(out, cli, "floor", [0, 1])


def test_a_scene_edited_during_a_run_records_no_mixed_frame(tmp_path, cluster):
    from glint.farm import SceneChangedError, render_frames
    scene = _scene(tmp_path)
    out = tmp_path / "farm"
    original = scene.read_text()

    def edit(frame, bounds):
        scene.write_text(original.replace("power = 20", "power = 30"))

    # One frame in flight: frame 1's tiles are all submitted after the edit.
    with pytest.raises(SceneChangedError, match="the scene changed during the run"):
        render_frames(scene, (0, 2), out, tile=24, client=cluster, threads=1,
                      frames_in_flight=1, progress=False, on_tile=edit)
    assert not (out / "floor_0001.json").exists() and not (out / "floor_0002.json").exists()
    # The edit reverted: any frame recorded done is the scene's, and the rest render now.
    scene.write_text(original)
    render_frames(scene, (0, 2), out, tile=24, client=cluster, threads=1, progress=False)
    _assert_frames_equal(out, _reference(tmp_path, scene, [0, 1, 2]), "floor", [0, 1, 2])


def test_a_tile_glint_refuses_is_not_retried(tmp_path, cluster, monkeypatch, capfd):
    """A tile the tracer refuses on a worker (here the camera at frame 2, with the client's
    check of every frame switched off) stops the run with glint's message: no Dask retry, no
    worker traceback."""
    from test_farm_arguments import DEGENERATE_AT_2
    import glint.farm as farm
    scene = tmp_path / "through.toml"
    scene.write_text(DEGENERATE_AT_2.format(spp=1))
    monkeypatch.setattr(farm._glint, "check_camera_frames", lambda *args: None)
    capfd.readouterr()
    with pytest.raises(ValueError) as error:
        # Frame 3 first: the client's one-pixel probe renders the first frame.
        farm.render_frames(scene, [3, 2], tmp_path / "farm", client=cluster, tile=1000,
                           frames_in_flight=1, progress=False)
    assert str(error.value).startswith("frame 2: camera at frame 2"), str(error.value)
    time.sleep(0.5)  # what the workers would log reaches the captured stderr
    captured = capfd.readouterr()
    assert "Traceback" not in captured.err and "Compute Failed" not in captured.err, \
        captured.err[-2000:]


def test_ctrl_c_stops_the_run_quietly(tmp_path):
    """Ctrl-C at a terminal reaches the whole process group (the farm and its workers): the
    run ends with status 130 and its message, no worker's KeyboardInterrupt traceback."""
    scene = _scene(tmp_path, spp=256)
    out = tmp_path / "farm"
    command = [sys.executable, "-m", "glint.farm", str(scene), "--frames", "0..3", "--out",
               str(out), "--tile", "24", "--workers", "1", "--threads", "1"]
    run = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (out / "floor_0000.json").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (out / "floor_0000.json").exists()
        os.killpg(run.pid, signal.SIGINT)
        _, errors = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait()
    assert run.returncode == 130, errors[-2000:]
    assert "interrupted: frames written so far are kept" in errors
    assert "Traceback" not in errors and "KeyboardInterrupt" not in errors, errors[-2000:]
