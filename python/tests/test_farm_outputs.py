"""glint.farm's output folder, without a cluster: one run at a time holds its lock (a dead
run's lock is taken over), a run removes the temporary files of dead runs, and a frame JSON
that is not the farm's record of complete outputs marks nothing as done."""

import json
import os
import socket
import subprocess
import sys

import pytest

pytest.importorskip("distributed")
import glint.farm as farm  # noqa: E402
from farm_stubs import ClusterStarted, no_cluster, scene  # noqa: E402,F401

#: Holds the lock of the folder argv[1] until its standard input closes.
_HOLDER = """
import sys, glint.farm
with glint.farm._FolderLock(sys.argv[1]):
    print("locked", flush=True)
    sys.stdin.read()
"""


@pytest.fixture
def holder(tmp_path):
    """A child process holding the lock of tmp_path / "out"; yields its pid."""
    out = tmp_path / "out"
    out.mkdir()
    child = subprocess.Popen([sys.executable, "-c", _HOLDER, str(out)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "locked"
        yield child.pid
    finally:
        child.stdin.close()
        child.wait(timeout=30)


def _dead_pid():
    """The pid of a process that has exited."""
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    return int(done.stdout)


def test_a_second_run_on_a_folder_is_refused_naming_the_lock_and_its_holder(
        scene, tmp_path, holder, no_cluster):
    lock = tmp_path / "out" / farm.LOCK_NAME
    with pytest.raises(farm.FolderInUseError) as error:
        farm.render_frames(scene, (0, 1), tmp_path / "out", progress=False)
    assert str(lock) in str(error.value) and f"pid {holder}" in str(error.value)
    assert lock.exists(), "the holder's lock is left alone"
    code = farm.main([str(scene), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == 2


def test_a_dead_runs_lock_is_taken_over(scene, tmp_path, no_cluster):
    out = tmp_path / "out"
    out.mkdir()
    (out / farm.LOCK_NAME).write_text(f"{_dead_pid()} {socket.gethostname()}\n")
    with pytest.raises(ClusterStarted):
        farm.render_frames(scene, (0, 0), out, progress=False)
    assert not (out / farm.LOCK_NAME).exists(), "released at the end"


def test_without_posix_locks_a_live_holder_refuses_and_a_dead_one_is_taken_over(
        scene, tmp_path, monkeypatch, no_cluster):
    monkeypatch.setattr(farm, "fcntl", None)
    out = tmp_path / "out"
    out.mkdir()
    lock = out / farm.LOCK_NAME
    lock.write_text(f"{os.getppid()} {socket.gethostname()}\n")
    with pytest.raises(farm.FolderInUseError, match=f"pid {os.getppid()} on"):
        farm.render_frames(scene, (0, 0), out, progress=False)
    lock.write_text(f"{_dead_pid()} {socket.gethostname()}\n")
    with pytest.raises(ClusterStarted):
        farm.render_frames(scene, (0, 0), out, progress=False)
    assert not lock.exists()


def test_temporary_files_of_dead_runs_are_removed(scene, tmp_path, no_cluster):
    out = tmp_path / "out"
    out.mkdir()
    dead = [out / f"floor_0000.partial-{_dead_pid()}{e}" for e in (".exr", ".png", ".json")]
    alive = out / f"floor_0001.partial-{os.getppid()}.exr"
    other = out / "notes.partial-x.exr"
    for path in dead + [alive, other]:
        path.write_bytes(b"partial")
    with pytest.raises(ClusterStarted):
        farm.render_frames(scene, (0, 0), out, progress=False)
    assert not any(p.exists() for p in dead)
    assert alive.exists() and other.exists()


@pytest.mark.parametrize("text", ["[]", '{"farm": null}', '{"farm": []}', "null", '"done"', "3",
                                  '{"farm": {"identity": [], "outputs": 1}}', "[" * 100_000,
                                  "{", ""])
def test_a_frame_json_that_is_not_the_farms_record_marks_nothing_done(scene, tmp_path,
                                                                      no_cluster, text):
    out = tmp_path / "out"
    out.mkdir()
    for extension in (".exr", ".png"):
        (out / f"floor_0000{extension}").write_bytes(b"\0" * 100)
    (out / "floor_0000.json").write_text(text)
    with pytest.raises(ClusterStarted):
        farm.render_frames(scene, (0, 0), out, progress=False)


def test_outputs_are_done_only_as_recorded(scene, tmp_path):
    paths = [str(tmp_path / f"f.{e}") for e in ("exr", "png", "json")]
    identity = {"sources_sha256": "x", "resolution": [2, 2], "spp": 1, "glint": "0"}
    outputs = {}
    for key, path in zip(("exr", "png"), paths):
        outputs[key] = farm._atomic(path, lambda p, k=key: open(p, "wb").write(k.encode() * 9))
    farm._atomic(paths[2], lambda p: open(p, "w").write(
        json.dumps({"farm": {"identity": identity, "outputs": outputs}})))
    assert farm._is_done(paths, identity)
    assert not farm._is_done(paths, {**identity, "spp": 2})
    with open(paths[0], "r+b") as exr:  # same size, other bytes
        exr.write(b"p")
    assert not farm._is_done(paths, identity)
    with open(paths[0], "wb") as exr:  # truncated
        exr.write(b"exr")
    assert not farm._is_done(paths, identity)
    os.remove(paths[1])
    assert not farm._is_done(paths, identity)
