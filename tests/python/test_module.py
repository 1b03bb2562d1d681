"""Tests of the spangle Python module (python/module.cpp): load, edit, render, arrays,
exceptions, stop from another thread, outputs. Run by ctest (python.module) with PYTHONPATH at
the build tree's python/ folder, or by hand:

    PYTHONPATH=build/python /usr/bin/python3 -m pytest -q tests/python
"""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import spangle

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
FLAKES = os.path.join(ROOT, "tests", "scenes", "flake_plane.toml")
SMALL = os.path.join(ROOT, "tests", "scenes", "small_lit.toml")
SUBDIV = os.path.join(ROOT, "tests", "scenes", "subdiv_near_far.toml")
BAD = os.path.join(ROOT, "tests", "scenes_bad", "camera_degenerate.toml")


@pytest.fixture()
def session():
    return spangle.Session(threads=2)


def assert_same_as_the_command_line(session, img, tmp_path, scene, args):
    """img (written through the module, 32-bit floats) has the pixels of `spangle render scene
    ARGS` (compared through oiiotool's per-channel statistics)."""
    cli = tmp_path / "cli.exr"
    spangle_bin = os.path.join(os.environ.get("SPANGLE_BUILD", os.path.join(ROOT, "build")), "spangle")
    subprocess.run([spangle_bin, "render", scene, *args, "--float", "--no-preview", "--threads",
                    "2", "-q", "-o", str(cli)], check=True)
    py = tmp_path / "py.exr"
    session.write(img, str(py), preview="", float=True)
    stats = [subprocess.run(["oiiotool", "--stats", str(p)], capture_output=True, text=True,
                            check=True).stdout for p in (cli, py)]
    lines = [[l for l in s.splitlines() if "Avg" in l or "Max" in l or "StdDev" in l] for s in stats]
    assert lines[0] and lines[0] == lines[1]


def test_renders_the_beauty_and_every_layer_as_float32_arrays(session):
    session.load(FLAKES)
    img = session.render(spp=4, size=(48, 32))
    assert img.beauty.shape == (32, 48, 3) and img.beauty.dtype == np.float32
    assert img.spp == 4 and not img.stopped and img.width == 48 and img.height == 32
    assert np.isfinite(img.beauty).all() and img.beauty.max() > 0.0
    for name, channels in {"A": 1, "albedo": 3, "N": 3, "Z": 1, "P": 3, "glints": 3}.items():
        assert img.layers[name].shape == (32, 48, channels), name
        assert img.layers[name].dtype == np.float32
    # The flake plane glitters: its glints are a part of the beauty, never more than it.
    assert img.glints is not None and img.glints.max() > 0.0
    assert (img.glints <= img.beauty + 1e-4).all()
    # Without layers: the beauty alone.
    plain = session.render(spp=4, size=(48, 32), layers=False)
    assert plain.layers == {} and plain.glints is None


@pytest.mark.parametrize("scene", [SMALL, SUBDIV])
def test_a_render_is_the_same_as_the_command_lines(session, tmp_path, scene):
    # The module renders through the same pipeline as `spangle render`: the same pixels (EXR as
    # 32-bit floats; compared through oiiotool's per-channel statistics and the module's own
    # write), also where the scene is built for the size asked for (subdivision levels chosen
    # from the camera's pixels).
    session.load(scene)
    img = session.render(spp=4, size=(40, 24), layers=False)
    again = session.render(spp=4, size=(40, 24), layers=False)
    assert np.array_equal(img.beauty, again.beauty)  # deterministic
    # Built for the size at load: the same scene, the same pixels.
    other = spangle.Session(threads=2)
    other.load(scene, size=(40, 24))
    assert np.array_equal(other.render(spp=4, layers=False).beauty, img.beauty)
    assert_same_as_the_command_line(session, img, tmp_path, scene,
                                    ["--spp", "4", "--size", "40x24"])


def test_material_edits_are_validated_and_change_the_image(session):
    session.load(FLAKES)
    before = session.render(spp=2, size=(32, 32), layers=False).beauty
    assert session.materials == ["glitter"]
    assert session.material("glitter")["params"]["density"] == 200000
    with pytest.raises(spangle.SceneError) as err:
        session.set_material("glitter", gamma=-1.0)
    assert "gamma" in str(err.value)
    with pytest.raises(spangle.SceneError) as err:
        session.set_material("glitter", densty=1e5)
    assert "density" in str(err.value)  # the valid names, with a suggestion
    with pytest.raises(spangle.SceneError) as err:
        session.set_material("nothing", density=1.0)
    assert "glitter" in str(err.value)
    with pytest.raises(TypeError):
        session.set_material("glitter", density=[1, 2])
    # A failed edit changes nothing.
    assert np.array_equal(session.render(spp=2, size=(32, 32), layers=False).beauty, before)
    session.set_material("glitter", flake_color=(1.0, 0.2, 0.1), seed=3)
    after = session.render(spp=2, size=(32, 32), layers=False).beauty
    assert session.material("glitter")["params"]["flake_color"] == pytest.approx((1.0, 0.2, 0.1))
    assert after[..., 1].sum() < 0.5 * before[..., 1].sum()
    # The host's cut-out keys are edited too: alpha 0 lets every ray through the sphere.
    session.set_material("glitter", alpha=0.0)
    cut = session.render(spp=2, size=(32, 32), layers=False).beauty
    assert not np.array_equal(cut, after)
    with pytest.raises(spangle.SceneError) as err:
        session.set_material("glitter", alpha=1.5)
    assert "alpha" in str(err.value)
    session.set_material("glitter", alpha=1.0)
    assert np.array_equal(session.render(spp=2, size=(32, 32), layers=False).beauty, after)


def test_transforms_camera_and_lights_are_edited(session):
    session.load(SMALL)
    base = session.render(spp=2, size=(32, 24), layers=False).beauty
    name = session.objects[0]
    session.set_transform(name, translate=(0.0, 5.0, 0.0))
    assert session.transform(name)["translate"] == pytest.approx((0.0, 5.0, 0.0))
    moved = session.render(spp=2, size=(32, 24), layers=False).beauty
    assert not np.array_equal(moved, base)
    with pytest.raises(spangle.SceneError):
        session.set_transform("no such object", translate=(0, 0, 0))
    cam = session.camera
    session.set_camera(fov=cam["fov"] * 0.5)
    assert session.camera["fov"] == pytest.approx(cam["fov"] * 0.5)
    with pytest.raises(spangle.SceneError):
        session.set_camera(look_at=cam["position"])  # looks nowhere
    assert session.camera["fov"] == pytest.approx(cam["fov"] * 0.5)
    lights = session.lights
    assert lights and "kind" in lights[0]
    session.set_light(0, intensity=0.0)
    dark = session.render(spp=2, size=(32, 24), layers=False).beauty
    assert dark.sum() < moved.sum()
    with pytest.raises(spangle.SceneError):
        session.set_light(len(lights), intensity=1.0)
    with pytest.raises(spangle.SceneError, match="numbered from 0"):
        session.set_light(-1, intensity=1.0)


def test_errors_carry_file_line_and_column(session):
    with pytest.raises(spangle.SceneError) as err:
        session.load(BAD)
    assert err.value.file == BAD and err.value.line == 4 and err.value.column == 11
    assert isinstance(err.value, RuntimeError)
    with pytest.raises(spangle.SceneError):
        session.render()  # nothing loaded
    with pytest.raises(spangle.SceneError):
        session.load(os.path.join(ROOT, "no_such_scene.toml"))


def test_progress_passes_and_a_stop_from_another_thread(session):
    session.load(FLAKES)
    seen = []
    passes = []
    img = session.render(spp=8, size=(32, 32), progress=lambda d, t: seen.append((d, t)),
                         on_pass=lambda beauty, spp: passes.append((beauty.shape, spp)))
    assert seen and seen[-1][0] == seen[-1][1] and all(b[0] <= a[0] for b, a in zip(seen, seen[1:]))
    assert passes and passes[0][0] == (32, 32, 3) and img.spp == 8
    # A long render stopped from another thread ends early with what it has; the GIL is free
    # meanwhile (the other thread runs).
    ticks = []
    done = {}

    def run():
        done["img"] = session.render(spp=100000, size=(64, 64))

    t = threading.Thread(target=run)
    t.start()
    start = time.time()
    while time.time() - start < 1.0:
        ticks.append(1)
        time.sleep(0.01)
    session.stop()
    session.stop()  # twice is harmless
    t.join(timeout=60)
    assert not t.is_alive()
    assert len(ticks) > 20
    assert done["img"].stopped and 0 < done["img"].spp < 100000
    # A stop() is never lost, however early: one made before render() starts (a thread that
    # starts a render and stops it at once lost it 1 time in 5, and the render ran on) ends
    # that render after its first pass; the next render is whole.
    session.stop()
    early = session.render(spp=100000, size=(16, 16))
    assert early.stopped and early.spp == 1
    assert session.render(spp=4, size=(16, 16)).spp == 4
    # Ctrl-C during render() stops it and raises KeyboardInterrupt at once (it waited for the
    # whole render, then dropped it).
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    start = time.time()
    with pytest.raises(KeyboardInterrupt):
        session.render(spp=100000, size=(64, 64))
    timer.join()
    assert time.time() - start < 30.0
    assert session.render(spp=2, size=(16, 16)).spp == 2
    # A Python error in a callback stops the render and is raised.
    with pytest.raises(ZeroDivisionError):
        session.render(spp=64, size=(32, 32), progress=lambda d, t: 1 / 0)


def test_write_exr_and_png_whole(session, tmp_path):
    session.load(FLAKES)
    img = session.render(spp=2, size=(32, 32))
    out = tmp_path / "flakes.exr"
    session.write(img, str(out))
    assert out.stat().st_size > 0 and (tmp_path / "flakes.png").stat().st_size > 0
    info = subprocess.run(["oiiotool", "--info", "-v", str(out)], capture_output=True, text=True,
                          check=True).stdout
    assert "glints.R" in info and "32 x   32" in info
    # Said as such (it was "the EXR and the PNG preview are the same file").
    with pytest.raises(spangle.SceneError, match="must end in .exr"):
        session.write(img, str(tmp_path / "flakes.png"))
    with pytest.raises(spangle.SceneError):
        session.write(img, str(tmp_path / "x.exr"), compression="nope")
    assert not (tmp_path / "x.exr").exists()


def test_a_session_is_not_edited_or_reloaded_while_it_renders(session):
    # Found by a user: set_material or load from another thread (or from on_pass) while render()
    # ran freed what the render read (SIGSEGV in the flake plugin). They are refused now.
    session.load(FLAKES)
    done = {}

    def run():
        done["img"] = session.render(spp=100000, size=(64, 64))

    t = threading.Thread(target=run)
    t.start()
    time.sleep(0.5)
    try:
        with pytest.raises(spangle.SceneError, match="rendering"):
            session.set_material("glitter", density=100000)
        with pytest.raises(spangle.SceneError, match="rendering"):
            session.load(SMALL)
    finally:
        session.stop()
        t.join(timeout=60)
    assert not t.is_alive() and done["img"].stopped
    with pytest.raises(spangle.SceneError, match="rendering"):
        session.render(spp=4, size=(16, 16),
                       on_pass=lambda beauty, spp: session.set_material("glitter", density=1e5))
    # The session renders as before afterwards.
    assert session.render(spp=2, size=(16, 16)).spp == 2


def test_times_sizes_threads_and_edits_are_checked(session):
    with pytest.raises(spangle.SceneError, match="time"):
        session.load(os.path.join(ROOT, "tests", "scenes", "moving_camera.toml"), time=float("nan"))
    with pytest.raises(spangle.SceneError, match="threads"):
        spangle.Session(threads=70000)
    session.load(FLAKES, size=(32, 32))
    before = session.render(spp=2).beauty
    for edit in (lambda: session.set_light(0, radius=-1.0),
                 lambda: session.set_light(0, intensity=-100.0),
                 lambda: session.set_light(0, color=(float("nan"), 1, 1)),
                 lambda: session.set_camera(fov=float("nan")),
                 lambda: session.set_camera(fov=-10),
                 lambda: session.set_camera(aperture=-1),
                 lambda: session.set_transform("[[object]] #1", scale=(0, 0, 0)),
                 lambda: session.set_transform("[[object]] #1", translate=(float("nan"), 0, 0))):
        with pytest.raises(spangle.SceneError):
            edit()
    assert np.array_equal(session.render(spp=2).beauty, before), "refused edits change nothing"
    with pytest.raises(spangle.SceneError, match="spp"):
        session.render(spp=0)
    # A size refused leaves the session at the size it had.
    with pytest.raises(spangle.SceneError):
        session.render(spp=1, size=(0, 4))
    assert session.render(spp=2).beauty.shape == (32, 32, 3)


def test_layers_match_the_command_line_with_layers(session, tmp_path):
    # With layers (the default) the module renders as `spangle render --layers`: the environment
    # seen directly is a layer of its own and the beauty is premultiplied by A (it was not).
    session.load(SMALL)
    img = session.render(spp=4, size=(40, 24))
    assert "background" in img.layers
    a = img.layers["A"][..., 0]
    assert (a == 0).any() and np.abs(img.beauty[a == 0]).max() == 0.0


def test_background_apart_false_keeps_the_sky_in_the_beauty(session):
    session.load(SMALL)
    apart = session.render(spp=2, size=(40, 24))
    kept = session.render(spp=2, size=(40, 24), background_apart=False)
    assert "background" not in kept.layers
    a = apart.layers["A"][..., 0]
    # The sky is in the beauty again, and it is what the background layer held.
    assert np.allclose(kept.beauty[a == 0], apart.layers["background"][a == 0], atol=1e-6)


def test_numpy_scalars_and_path_objects_are_taken(session):
    import pathlib
    session.load(pathlib.Path(FLAKES), size=(16, 16))
    session.set_material("glitter", gamma=np.float32(4.0), density=np.int64(200000))
    assert session.material("glitter")["params"]["gamma"] == pytest.approx(4.0)
    with pytest.raises(spangle.SceneError, match="out of range"):
        session.set_material("glitter", seed=2**70)


def test_adaptive_sampling_is_the_command_lines(session, tmp_path):
    # render(noise_threshold=, min_spp=, max_spp=) is `spangle render --noise-threshold --min-spp
    # --max-spp`: the same pixels, fewer samples where the image is flat; the next render without
    # them is the scene's again. Bad values raise and leave the session usable.
    session.load(SMALL)
    img = session.render(spp=64, size=(40, 24), layers=False, noise_threshold=0.2, min_spp=8,
                         max_spp=64)
    assert 8 <= img.spp_mean < 64, img.spp_mean
    assert_same_as_the_command_line(session, img, tmp_path, SMALL,
                                    ["--spp", "64", "--size", "40x24", "--noise-threshold", "0.2",
                                     "--min-spp", "8", "--max-spp", "64"])
    fixed = session.render(spp=64, size=(40, 24), layers=False)
    assert fixed.spp_mean == 64 and not np.array_equal(fixed.beauty, img.beauty)
    for bad in (dict(noise_threshold=-0.1), dict(noise_threshold=1e-9), dict(min_spp=0),
                dict(min_spp=-3), dict(max_spp=2**40),
                dict(noise_threshold=0.1, min_spp=128, max_spp=64)):
        with pytest.raises(spangle.SceneError):
            session.render(spp=8, size=(40, 24), layers=False, **bad)
    with pytest.raises(spangle.SceneError):  # was pybind's TypeError
        session.render(spp=-1, size=(40, 24), layers=False)
    assert session.render(spp=4, size=(40, 24), layers=False).spp == 4


def test_denoise_is_the_command_lines(session, tmp_path):
    # render(denoise=True) is `spangle render --denoise`: the same pixels (the denoised beauty and
    # every layer, the noisy beauty among them); the noisy layer is the render without the
    # denoiser, and the denoised beauty is closer to a converged render. Glints pass through
    # unfiltered by default. Denoising without layers, or with an unknown glint mode, raises.
    session.load(FLAKES)
    img = session.render(spp=4, size=(48, 32), denoise=True)
    assert img.denoised and "noisy" in img.layers
    assert_same_as_the_command_line(session, img, tmp_path, FLAKES,
                                    ["--spp", "4", "--size", "48x32", "--denoise"])
    noisy = session.render(spp=4, size=(48, 32))
    assert not noisy.denoised and "noisy" not in noisy.layers
    np.testing.assert_array_equal(img.layers["noisy"], noisy.beauty)
    # Glints kept: where the glints layer is lit, the denoised beauty keeps the whole glint.
    lit = img.glints.max(axis=2) > 0.0
    assert lit.sum() > 20 and (img.beauty[lit] >= img.glints[lit] - 1e-5).all()
    # A scene without glitter: the denoised beauty is at least 5 times nearer a converged render
    # in relMSE (as unit/test_denoise.cpp holds the engine's; 6.4x when written).
    session.load(SMALL)
    img = session.render(spp=8, size=(96, 64), denoise=True)
    noisy = img.layers["noisy"]
    reference = session.render(spp=1024, size=(96, 64)).beauty
    err = lambda x: float(np.mean((x - reference) ** 2 / (reference ** 2 + 0.01)))
    assert err(img.beauty) < 0.2 * err(noisy), (err(img.beauty), err(noisy))
    with pytest.raises(spangle.SceneError, match="needs the layers"):
        session.render(spp=2, size=(48, 32), layers=False, denoise=True)
    with pytest.raises(spangle.SceneError, match="denoise_glints"):
        session.render(spp=2, size=(48, 32), denoise=True, denoise_glints="blur")
    with pytest.raises(spangle.SceneError, match="needs denoise=True"):
        session.render(spp=2, size=(48, 32), denoise_glints="apart")
    assert session.render(spp=2, size=(48, 32), denoise=True, denoise_glints="apart").denoised


def test_the_camera_turns_orthographic_and_back(session):
    # set_camera(ortho_height=H) makes the camera orthographic (the view H units tall), 0 makes
    # it the perspective camera it was, pixel for pixel; a fov for an orthographic camera raises.
    session.load(SMALL)
    persp = session.render(spp=2, size=(40, 24), layers=False)
    assert session.camera["ortho_height"] is None
    session.set_camera(ortho_height=3.0)
    assert session.camera["ortho_height"] == 3.0
    assert session.camera["projection"] == "orthographic"
    ortho = session.render(spp=2, size=(40, 24), layers=False)
    assert not np.array_equal(ortho.beauty, persp.beauty) and np.isfinite(ortho.beauty).all()
    with pytest.raises(spangle.SceneError):
        session.set_camera(fov=30)
    with pytest.raises(spangle.SceneError):
        session.set_camera(ortho_height=-1.0)
    session.set_camera(ortho_height=0.0)
    assert session.camera["ortho_height"] is None and session.camera["projection"] == "perspective"
    assert np.array_equal(session.render(spp=2, size=(40, 24), layers=False).beauty, persp.beauty)


def test_the_camera_turns_equirectangular_and_back(session, tmp_path):
    # set_camera(projection="equirectangular") is [camera] projection = "equirectangular": the
    # same pixels as that scene file loaded; "perspective" gives back the camera it was, pixel for
    # pixel; "orthographic" takes an ortho_height. A lens, a fov or an unknown name raise.
    session.load(SMALL)
    persp = session.render(spp=2, size=(64, 32), layers=False)
    session.set_camera(projection="equirectangular")
    assert session.camera["projection"] == "equirectangular" and session.camera["fov"] is None
    pano = session.render(spp=2, size=(64, 32), layers=False)
    text = open(SMALL).read().replace('"../../', '"' + ROOT + '/').replace(
        "fov = 32", 'projection = "equirectangular"')
    scene = tmp_path / "pano.toml"
    scene.write_text(text)
    other = spangle.Session(threads=2)
    other.load(str(scene))
    assert np.array_equal(other.render(spp=2, size=(64, 32), layers=False).beauty, pano.beauty)
    for bad in (dict(fov=30), dict(aperture=0.1), dict(ortho_height=2.0)):
        with pytest.raises(spangle.SceneError):
            session.set_camera(**bad)
    session.set_camera(projection="perspective")
    assert session.camera["projection"] == "perspective" and session.camera["fov"] == 32
    assert np.array_equal(session.render(spp=2, size=(64, 32), layers=False).beauty, persp.beauty)
    with pytest.raises(spangle.SceneError, match="needs ortho_height"):
        session.set_camera(projection="orthographic")
    session.set_camera(projection="orthographic", ortho_height=3.0)
    assert session.camera["projection"] == "orthographic"
    with pytest.raises(spangle.SceneError, match="projection must be"):
        session.set_camera(projection="fisheye")
    session.set_camera(projection="perspective", aperture=0.2)
    with pytest.raises(spangle.SceneError, match="aperture=0"):
        session.set_camera(projection="equirectangular")
    session.set_camera(projection="equirectangular", aperture=0.0)
    assert session.camera["projection"] == "equirectangular"


def test_a_panoramas_depth_is_the_distance(session, tmp_path):
    # An equirectangular camera looks every way: its Z layer is each point's distance from the
    # camera (along the view it ran from -d to d, negative behind), and the camera reports no fov.
    text = open(SMALL).read().replace('"../../', '"' + ROOT + '/').replace(
        "fov = 32", 'projection = "equirectangular"')
    scene = tmp_path / "pano.toml"
    scene.write_text(text)
    session.load(str(scene))
    assert session.camera["projection"] == "equirectangular" and session.camera["fov"] is None
    img = session.render(spp=2, size=(64, 32))
    z, p, a = img.layers["Z"][..., 0], img.layers["P"], img.layers["A"][..., 0]
    hit = a > 0.999
    assert hit.sum() > 100
    eye = np.array(session.camera["position"], dtype=np.float64)
    dist = np.linalg.norm(p[hit].astype(np.float64) - eye, axis=1)
    assert (z[hit] > 0).all()
    # Z and P are each a pixel's mean over its samples, so they agree to the spread of a pixel
    # (5.6 degrees here): within 1%. Depth along the view would be d cos(azimuth): -d behind.
    assert np.allclose(z[hit], dist, rtol=1e-2), np.abs(z[hit] / dist - 1).max()


def test_reads_while_another_thread_edits_do_not_crash(session):
    # The properties copy the description under the lock an edit replaces it under: reading
    # s.materials / s.camera while another thread ran set_camera read freed memory (a segfault in
    # 4 of 11 ten-second runs, stray MemoryError and SystemError otherwise).
    session.load(SMALL)
    done = threading.Event()
    errors = []

    def edit():
        fov = 30.0
        while not done.is_set():
            fov = 60.0 - fov
            session.set_camera(fov=fov)

    t = threading.Thread(target=edit)
    t.start()
    try:
        end = time.time() + 1.5
        while time.time() < end:
            try:
                assert session.materials == ["red", "floor"]
                assert session.camera["fov"] in (30.0, 60.0, 32.0)
                assert len(session.lights) == 1 and len(session.objects) == 3
                session.material("red")
            except spangle.SceneError as e:  # never: every read sees a whole description
                errors.append(e)
    finally:
        done.set()
        t.join()
    assert not errors


def test_write_labels_an_image_with_the_scene_it_was_rendered_from(session, tmp_path):
    # An image written after a later edit or load carries its own camera and colour space (it
    # took the session's state at write time: fov 40's matrices on a fov 20 render).
    session.load(SMALL)
    session.set_camera(fov=20)
    narrow = session.render(spp=1, size=(32, 18), layers=False)
    session.write(narrow, str(tmp_path / "before.exr"), preview="", float=True)
    session.set_camera(fov=40)
    session.load(FLAKES)  # another scene, in lin_rec709
    session.write(narrow, tmp_path / "after.exr", preview="", float=True)  # a pathlib.Path too
    info = [subprocess.run(["iinfo", "-v", str(tmp_path / f)], capture_output=True, text=True,
                           check=True).stdout for f in ("before.exr", "after.exr")]
    keep = lambda s: [l for l in s.splitlines() if "worldTo" in l or "colorSpace" in l or "hromatic" in l]
    assert keep(info[0]) and keep(info[0]) == keep(info[1])
    # Paths checked as the command line checks them.
    with pytest.raises(spangle.SceneError, match="must end in .png"):
        session.write(narrow, str(tmp_path / "x.exr"), preview=str(tmp_path / "x.jpg"))
    with pytest.raises(spangle.SceneError, match="NUL"):
        session.write(narrow, str(tmp_path / "c\x00junk.exr"))


def test_edits_keep_the_scene_files_ranges(session, tmp_path):
    # A scale beyond the scene file's 1e-8..1e8 (the render aborted in Embree), a perspective
    # camera given an ortho_height, and an edit of a keyframed camera (reported, then ignored by
    # the render) raise; a relative load survives a change of folder; vec3 parameters say so.
    session.load(SMALL)
    for bad in ((1e-20, 1, 1), (1e9, 1, 1)):
        with pytest.raises(spangle.SceneError, match="1e-8 and 1e8"):
            session.set_transform("[[object]] #1", scale=bad)
    with pytest.raises(spangle.SceneError, match="takes no ortho_height"):
        session.set_camera(projection="perspective", ortho_height=3.0)
    session.load(os.path.join(ROOT, "tests", "scenes", "moving_camera.toml"))
    with pytest.raises(spangle.SceneError, match="keyframed"):
        session.set_camera(position=(0, 3, 8))
    here = os.getcwd()
    try:
        os.chdir(ROOT)
        session.load("tests/scenes/small_lit.toml")
        os.chdir(str(tmp_path))
        session.set_light(0, intensity=4.0)  # reloads the scene: found from anywhere
    finally:
        os.chdir(here)
    eta = [p for p in session.parameters("smooth", "conductor") if p["name"] == "eta"][0]
    assert eta["type"] == "vec3" and eta["default"] == (-1.0, -1.0, -1.0)


def test_the_type_stubs_name_every_keyword_the_module_takes():
    # spangle/__init__.pyi names each method's keywords as the binding does (it lacked render's
    # denoise, set_camera's projection and Image.denoised).
    import ast
    import re
    stub = ast.parse(open(os.path.join(ROOT, "python", "spangle", "__init__.pyi")).read())
    cls = {n.name: n for n in stub.body if isinstance(n, ast.ClassDef)}
    for name in ("render", "set_camera", "set_transform", "set_light", "write", "load"):
        fn = [f for f in cls["Session"].body if isinstance(f, ast.FunctionDef) and f.name == name][0]
        stubbed = {a.arg for a in fn.args.args + fn.args.kwonlyargs} - {"self"}
        first = getattr(spangle.Session, name).__doc__.splitlines()[0]
        bound = set(re.findall(r"(\w+): ", first[first.index("(") + 1:])) - {"self"}
        assert stubbed == bound, (name, stubbed ^ bound)
    props = {f.name for f in cls["Image"].body if isinstance(f, ast.FunctionDef)}
    bound = {n for n in dir(spangle.Image) if not n.startswith("_")}
    assert props == bound, props ^ bound


def test_the_interpreter_exits_cleanly_while_a_daemon_thread_renders():
    # Python ends a daemon thread that wants the GIL after finalisation began by unwinding it;
    # the render's progress callback, on a TBB thread, had that unwinding caught ("FATAL:
    # exception not rethrown", every run) and the waiting thread's std::thread was destroyed
    # joinable ("terminate called", about one run in four). An atexit hook now stops renders.
    script = f"""
import threading, time, spangle
s = spangle.Session(threads=1)
s.load({FLAKES!r})
started = threading.Event()
def progress(done, total):
    if done > 0:
        started.set()
threading.Thread(target=lambda: s.render(spp=100000, size=(320, 180), progress=progress),
                 daemon=True).start()
started.wait(60)
time.sleep(1.0)  # callbacks come often by then
"""
    env = dict(os.environ)
    for _ in range(3):
        run = subprocess.run([os.sys.executable, "-c", script], capture_output=True, text=True,
                             timeout=120, env=env)
        assert run.returncode == 0, run.stderr
        assert "terminate" not in run.stderr and "FATAL" not in run.stderr, run.stderr


def test_write_refuses_the_scenes_files_and_lossy_layers(session, tmp_path):
    # Found by a user: write() overwrote a map the scene reads (the command line refuses), and
    # took dwaa for an image with layers (its normals came back 1.009 long).
    import shutil
    shutil.copy(os.path.join(ROOT, "assets", "env", "studio.exr"), tmp_path / "map.exr")
    text = open(SMALL).read().replace('"../../assets/', '"' + os.path.join(ROOT, "assets") + "/")
    text = text.replace("color = [0.5, 0.6, 0.8]", 'map = "map.exr"')
    (tmp_path / "scene.toml").write_text(text)
    session.load(str(tmp_path / "scene.toml"), size=(16, 12))
    img = session.render(spp=1)
    before = (tmp_path / "map.exr").read_bytes()
    with pytest.raises(spangle.SceneError, match="a file the scene reads"):
        session.write(img, str(tmp_path / "map.exr"), preview="")
    assert (tmp_path / "map.exr").read_bytes() == before, "the map is left as it was"
    with pytest.raises(spangle.SceneError, match="lossy"):
        session.write(img, str(tmp_path / "lossy.exr"), compression="dwaa", preview="")
    assert not (tmp_path / "lossy.exr").exists()
    # Without layers, dwaa is the user's choice.
    session.write(session.render(spp=1, layers=False), str(tmp_path / "plain.exr"),
                  compression="dwaa", preview="")
    assert (tmp_path / "plain.exr").exists()


def test_a_keyframed_objects_keyed_parts_are_not_edited(session):
    # set_transform on what an object's keys decide was reported by transform() and ignored by
    # the render; a part its keys leave alone is still edited.
    session.load(os.path.join(ROOT, "tests", "scenes", "moving_camera.toml"), time=1.0,
                 size=(16, 12))
    name = session.objects[1]
    with pytest.raises(spangle.SceneError, match="keyframed"):
        session.set_transform(name, translate=(0, 3, 0))
    with pytest.raises(spangle.SceneError, match="keyframed"):
        session.set_transform(name, rotate=(0, 10, 0))
    session.set_transform(name, scale=(0.25, 0.25, 0.25))
    assert session.transform(name)["scale"] == pytest.approx((0.25, 0.25, 0.25))


def test_a_renders_size_does_not_stick_to_the_next(session):
    # render(size=...) then render(): the second was at the first's size (spp did not stick).
    session.load(SMALL, size=(24, 16))
    assert session.render(spp=1, size=(12, 8), layers=False).beauty.shape == (8, 12, 3)
    assert session.render(spp=1, layers=False).beauty.shape == (16, 24, 3)


def test_every_refused_edit_names_itself_as_the_file(session):
    # Some edits' errors had file=None (a NaN gamma, a negative fov, a negative light colour),
    # and a plugin's refusal of an edited value blamed the scene file's line.
    session.load(FLAKES, size=(16, 12))
    for edit, where in ((lambda: session.set_material("glitter", gamma=float("nan")),
                         "python: set_material('glitter', gamma=...)"),
                        (lambda: session.set_material("glitter", min_flakes=1e9),
                         "python: set_material('glitter', min_flakes=...)"),
                        (lambda: session.set_camera(fov=-1), "python: set_camera()"),
                        (lambda: session.set_light(0, color=(-1, 0, 0)), "python: set_light(0)"),
                        (lambda: session.set_transform("[[object]] #1", scale=(0, 0, 0)),
                         "python: set_transform('[[object]] #1')"),
                        (lambda: session.set_transform("[[object]] #1",
                                                       translate=(float("inf"), 0, 0)),
                         "python: set_transform('[[object]] #1')"),
                        (lambda: session.set_transform("[[object]] #1", scale="big"),
                         "python: set_transform('[[object]] #1')"),
                        (lambda: session.set_transform("nope", scale=2),
                         "python: set_transform('nope')"),
                        (lambda: session.set_material("zzz", roughness=0.1),
                         "python: set_material('zzz')"),
                        (lambda: session.set_light(99, intensity=1), "python: set_light(99)"),
                        (lambda: session.set_light(0, intensity=-1), "python: set_light(0)")):
        with pytest.raises(spangle.SceneError) as e:
            edit()
        assert e.value.file == where, str(e.value)


def test_a_matrix_in_every_shape_the_scene_file_takes(session):
    # 4 x 4 (numpy's eye), flat 12 and a single scale number were TypeErrors from the binding.
    session.load(SMALL, size=(16, 12))
    name = session.objects[1]
    session.set_transform(name, matrix=np.eye(4))
    assert session.transform(name)["matrix"][0] == pytest.approx((1.0, 0.0, 0.0, 0.0))
    session.set_transform(name, matrix=[1, 0, 0, 1, 0, 1, 0, 2, 0, 0, 1, 3])
    assert session.transform(name)["matrix"][2] == pytest.approx((0.0, 0.0, 1.0, 3.0))
    session.set_transform(name, translate=(0, 1, 0), rotate=(0, 0, 0), scale=2)
    assert session.transform(name)["scale"] == pytest.approx((2.0, 2.0, 2.0))
    with pytest.raises(spangle.SceneError, match="12 numbers"):
        session.set_transform(name, matrix=[1, 2, 3])
    with pytest.raises(spangle.SceneError, match="last row"):
        session.set_transform(name, matrix=np.ones((4, 4)))


def test_plugin_path_takes_one_folder_or_a_list_and_refuses_what_is_not_one(tmp_path):
    # Found by a user: Session(plugin_path="/dir") was pybind's "incompatible constructor
    # arguments", and a folder that does not exist was searched silently.
    assert spangle.Session(plugin_path=str(tmp_path), threads=1) is not None
    assert spangle.Session(plugin_path=tmp_path, threads=1) is not None
    assert spangle.Session(plugin_path=[tmp_path, str(tmp_path)], threads=1) is not None
    with pytest.raises(spangle.SceneError, match="is not a folder"):
        spangle.Session(plugin_path=[str(tmp_path / "missing")], threads=1)
    with pytest.raises(spangle.SceneError, match="is not a folder"):
        spangle.Session(plugin_path=str(tmp_path / "missing"), threads=1)



def test_two_threads_reading_their_first_images_at_once_do_not_hang(tmp_path):
    # Found by a user: before numpy was imported, two threads making their first arrays at once
    # (two images read, or two sessions' on_pass) waited for each other for ever inside
    # pybind11's numpy set-up. A fresh interpreter, numpy not imported before.
    script = tmp_path / "first_arrays.py"
    script.write_text(
        "import sys, threading\n"
        "import spangle\n"
        "s = spangle.Session(threads=1)\n"
        f"s.load({SMALL!r}, size=(16, 9))\n"
        "img = s.render(spp=1)\n"
        "b = threading.Barrier(2)\n"
        "def read():\n"
        "    b.wait()\n"
        "    img.beauty\n"
        "ts = [threading.Thread(target=read) for _ in range(2)]\n"
        "[t.start() for t in ts]\n"
        "[t.join() for t in ts]\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120,
                         env=os.environ.copy())
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_edits_from_two_threads_wait_for_each_other(session):
    # Found by a user: 345 of 400 edits from two threads were refused as "this session is
    # rendering" while nothing rendered.
    session.load(SMALL, size=(16, 12))
    errors = []

    def edit(k):
        for i in range(40):
            try:
                if k:
                    session.set_camera(fov=20 + i % 10)
                else:
                    session.set_light(0, intensity=1 + i)
            except spangle.SceneError as e:
                errors.append(str(e))

    ts = [threading.Thread(target=edit, args=(k,)) for k in (0, 1)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert errors == []
    # Each thread's last edit stands (an edit made on a copy read before the other's reload
    # dropped it).
    assert session.camera["fov"] == pytest.approx(20 + 39 % 10)
    assert session.lights[0]["intensity"] == pytest.approx(40)


def test_scale_and_matrix_arrays_are_read_by_their_shape(session):
    # Found by a user: scale=np.array([...]) of three was a bare pybind11 cast error; a 4 x 3
    # matrix (transposed) or complex numbers were read as twelve numbers without a word.
    session.load(SMALL, size=(16, 12))
    name = session.objects[1]
    session.set_transform(name, translate=(0, 1, 0), rotate=(0, 0, 0),
                          scale=np.array([0.5, 2.0, 3.0], dtype=np.float32))
    assert session.transform(name)["scale"] == pytest.approx((0.5, 2.0, 3.0))
    session.set_transform(name, translate=(0, 1, 0), rotate=(0, 0, 0), scale=np.array(0.25))
    assert session.transform(name)["scale"] == pytest.approx((0.25, 0.25, 0.25))
    with pytest.raises(spangle.SceneError, match="shape \\(4, 3\\)"):
        session.set_transform(name, matrix=np.zeros((4, 3)))
    with pytest.raises(spangle.SceneError, match="real numbers"):
        session.set_transform(name, matrix=np.eye(4, dtype=complex)[:3])
    with pytest.raises(spangle.SceneError, match="three numbers or one"):
        session.set_transform(name, scale=np.ones(2))
    from fractions import Fraction
    session.set_transform(name, translate=(0, 1, 0), rotate=(0, 0, 0), scale=Fraction(1, 2))
    assert session.transform(name)["scale"] == pytest.approx((0.5, 0.5, 0.5))


def test_material_shows_alpha_and_an_empty_path_is_a_scene_error(session):
    session.load(SMALL, size=(16, 12))
    name = session.materials[0]
    session.set_material(name, alpha=0.3, alpha_cutoff=0.2)
    m = session.material(name)
    assert m["alpha"] == pytest.approx(0.3)
    assert m["alpha_cutoff"] == pytest.approx(0.2)
    with pytest.raises(spangle.SceneError, match="path is empty"):
        session.load("")


def test_a_plugin_that_crashes_is_named_before_python_dies(tmp_path):
    """A material plugin that crashes (SIGSEGV in eval()) took the interpreter with it without a
    word; the command line names it. Now the last line names the kernel, the plugin and the
    material, and the process still dies of the signal (nothing can be caught)."""
    plugins = os.environ.get(
        "SPANGLE_TEST_PLUGIN_DIR",
        os.path.join(os.environ.get("SPANGLE_BUILD", os.path.join(ROOT, "build")), "test_plugins"))
    assert os.path.exists(os.path.join(plugins, "libspangle_kernels.so")), plugins
    scene = tmp_path / "crash.toml"
    scene.write_text(
        "[render]\nwidth = 8\nheight = 8\nspp = 1\n"
        "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\n"
        "[[light]]\ntype = \"distant\"\ndirection = [0, 0, -1]\nintensity = 1\n"
        "[[material]]\nname = \"crasher\"\nplugin = \"kernels\"\nparams = { x = 0.9 }\n"
        "[[object]]\nmesh = \"%s\"\nmaterial = \"crasher\"\n"
        % os.path.join(ROOT, "assets", "meshes", "sphere.obj"))
    code = ("import spangle\n"
            "s = spangle.Session(plugin_path=%r, threads=1)\n"
            "s.load(%r)\n"
            "s.render(spp=1)\n" % (plugins, str(scene)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == -signal.SIGSEGV, (out.returncode, out.stderr)
    assert ("spangle: fatal: SIGSEGV (invalid memory access) in eval() of plugin 'kernels'"
            in out.stderr), out.stderr
    assert "material 'crasher'" in out.stderr, out.stderr
