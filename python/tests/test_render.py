"""glint.render against `cargo xtask render`: the same pixels, the same bytes; crops are the
full frame's pixels; errors name the problem."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import glint

REPO = pathlib.Path(__file__).resolve().parents[2]

#: A glittery floor under a sphere light, with a camera that moves over frames 0..10.
SCENE = """
[render]
resolution = [48, 32]
spp = {spp}
[camera]
position = [0, 1, 3]
look_at = [0, 0, 0]
[[camera.keyframes]]
frame = 0
[[camera.keyframes]]
frame = 10
position = [0.5, 1, 3]
[materials.glitter]
type = "glint"
alpha = 0.1
particles = 1e7
gamma = 1
[[shapes]]
type = "rectangle"
center = [0, 0, 0]
u = [4, 0, 0]
v = [0, 0, -4]
material = "glitter"
[[lights]]
type = "sphere"
center = [0, 1, -2]
radius = 0.1
power = 20
"""


def _scene(folder, spp=4, name="floor"):
    path = folder / f"{name}.toml"
    path.write_text(SCENE.format(spp=spp))
    return path


def _xtask_render(scene, out, *args):
    """`cargo xtask render SCENE --out OUT ARGS` (the binary in GLINT_XTASK if set)."""
    command = os.environ.get("GLINT_XTASK")
    command = [command, "render"] if command else [
        "cargo", "run", "--release", "--quiet", "-p", "xtask", "--", "render"]
    done = subprocess.run(command + [str(scene), "--out", str(out), "--quiet", *args],
                          capture_output=True, text=True, cwd=REPO, check=False)
    assert done.returncode == 0, done.stderr[-2000:]


def _same_files(a, b):
    return pathlib.Path(a).read_bytes() == pathlib.Path(b).read_bytes()


def test_render_is_the_command_lines_frame(tmp_path):
    scene = _scene(tmp_path)
    _xtask_render(scene, tmp_path / "cli", "--frames", "2..2")
    result = glint.render(scene, frame=2)
    image, stats = result["image"], result["stats"]
    assert image.shape == (32, 48, 3) and image.dtype == np.float32
    assert stats["frame"] == 2 and stats["pixel_bounds"] == [0, 48, 0, 32]
    assert stats["glint_queries"] > 0
    cli = json.loads((tmp_path / "cli" / "floor_0002.json").read_text())
    assert cli["glint_queries"] == stats["glint_queries"]
    assert cli["expected_footprint_areas"] == stats["expected_footprint_areas"]
    glint.write_exr(tmp_path / "py.exr", image)
    glint.write_png(tmp_path / "py.png", image, stats["exposure"], stats["bloom"])
    assert _same_files(tmp_path / "py.exr", tmp_path / "cli" / "floor_0002.exr")
    assert _same_files(tmp_path / "py.png", tmp_path / "cli" / "floor_0002.png")


def test_crops_are_the_full_frames_pixels(tmp_path):
    scene = _scene(tmp_path)
    full = glint.render(scene, frame=1, threads=1)["image"]
    for x0, x1, y0, y1 in [(5, 30, 3, 20), (47, 48, 31, 32), (0, 48, 16, 32)]:
        crop = glint.render(scene, frame=1, pixel_bounds=(x0, x1, y0, y1), threads=2)
        assert crop["stats"]["pixel_bounds"] == [x0, x1, y0, y1]
        assert np.array_equal(crop["image"], full[y0:y1, x0:x1])
    smaller = glint.render(scene, resolution=(24, 16), spp=1)
    assert smaller["image"].shape == (16, 24, 3) and smaller["stats"]["spp"] == 1


def test_a_changed_scene_or_asset_is_loaded_again(tmp_path):
    """A process keeps the last scene it loaded for the next render of the same file; a change
    to the file or to an asset it reads is seen by the next render."""
    scene = _scene(tmp_path)
    first = glint.render(scene, spp=1)
    assert glint.render(scene, spp=1)["stats"]["glint_queries"] == first["stats"][
        "glint_queries"]
    assert first["stats"]["sources"] == [str(scene)]
    scene.write_text(SCENE.format(spp=4).replace("power = 20", "power = 80"))
    brighter = glint.render(scene, spp=1)["image"]
    assert np.allclose(brighter, 4 * first["image"], rtol=1e-5, atol=0)
    assert brighter.max() > 0
    texture = tmp_path / "tint.png"
    glint.write_png(texture, np.full((2, 2, 3), 0.25, dtype=np.float32))
    scene.write_text(SCENE.format(spp=4).replace(
        'material = "glitter"', 'material = "floor"') + """
[materials.floor]
type = "diffuse"
texture = "tint.png"
""")
    dark = glint.render(scene, spp=1)
    assert dark["stats"]["sources"] == [str(scene), str(tmp_path / "tint.png")]
    glint.write_png(texture, np.full((2, 2, 3), 1.0, dtype=np.float32))
    light = glint.render(scene, spp=1)
    floor = np.s_[-4:]  # the bottom rows: floor only, no light
    assert light["image"][floor].mean() > 3 * dark["image"][floor].mean() > 0


def test_render_errors_name_the_problem(tmp_path):
    scene = _scene(tmp_path)
    with pytest.raises(ValueError, match="pixel_bounds"):
        glint.render(scene, pixel_bounds=(0, 49, 0, 1))
    with pytest.raises(ValueError, match="pixel_bounds"):
        glint.render(scene, pixel_bounds=(3, 3, 0, 1))
    with pytest.raises(ValueError, match="pixel_bounds"):
        glint.render(scene, pixel_bounds=(0, 1, 0))
    with pytest.raises(ValueError, match="spp"):
        glint.render(scene, spp=0)
    with pytest.raises(ValueError, match="threads"):
        glint.render(scene, threads=0)
    # glint's limit for every pool (xtask --threads and C too), refused before any thread starts.
    assert glint._glint.MAX_THREADS == 1024
    with pytest.raises(ValueError, match=r"threads = 4096 is outside \[1, 1024\]"):
        glint.render(scene, threads=4096)
    with pytest.raises(ValueError, match=r"threads = 1025: the number of threads must be in "
                                         r"\[1, 1024\]"):
        glint._glint.render_scene(str(scene), 0, None, None, None, 1025, False)
    with pytest.raises(FileNotFoundError):
        glint.render(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.format(spp=4).replace("alpha = 0.1", "alpha = -1"))
    with pytest.raises(ValueError, match=r"bad\.toml.*alpha"):
        glint.render(bad)
    image = np.zeros((4, 4, 3), dtype=np.float32)
    image[1, 2, 0] = np.inf
    with pytest.raises(ValueError, match="row 1, column 2"):
        glint.write_exr(tmp_path / "inf.exr", image)
    with pytest.raises(ValueError, match="shape"):
        glint.write_png(tmp_path / "flat.png", np.zeros((4, 4)))
    with pytest.raises(OSError):
        glint.write_exr(tmp_path / "no" / "such" / "folder.exr", np.zeros((2, 2, 3)))


def test_farm_arguments_are_checked_before_any_work(tmp_path):
    from glint.farm import render_frames
    scene = _scene(tmp_path)
    with pytest.raises(ValueError, match="more than the limit"):
        render_frames(scene, (0, 10**9), tmp_path / "out")
    with pytest.raises(FileNotFoundError):
        render_frames(tmp_path / "missing.toml", (0, 1), tmp_path / "out")


def test_tiles_cover_the_image_once():
    from glint.farm import tiles
    covered = np.zeros((33, 50), dtype=int)
    for x0, x1, y0, y1 in tiles(50, 33, 16):
        covered[y0:y1, x0:x1] += 1
    assert (covered == 1).all()
    assert len(tiles(48, 32, 24)) == 4
    with pytest.raises(ValueError):
        tiles(4, 4, 0)


_INTERRUPTED_RENDER = """
import sys, time, glint
print("started", flush=True)
start = time.monotonic()
try:
    glint.render(sys.argv[1], spp=65536, resolution=(256, 256))
    print("finished", flush=True)
except KeyboardInterrupt:
    print(f"interrupted {time.monotonic() - start:.1f}", flush=True)
"""


def test_ctrl_c_stops_a_render(tmp_path):
    """Ctrl-C (SIGINT) stops a long render with KeyboardInterrupt (the render runs with the GIL
    released; the calling thread runs Python's signal handlers while it waits). The render
    asked for (256 x 256 at 65536 spp) takes far longer than the second it is given."""
    from interrupt import interrupted_output
    out = interrupted_output(_INTERRUPTED_RENDER, _scene(tmp_path))
    assert out.startswith("interrupted"), out
