"""The benchmark's importer (tests/bench/spangle_to_blender.py) draws a Spangle scene in Cycles
as Spangle draws it: a diffuse floor and ball lit by each light type in turn, then a lat-long map, each
rendered by `spangle render` from the file and by Cycles from the Blender scene the importer
builds. Diffuse materials are the same BRDF in both renderers, so a wrong light power, a
misplaced camera or light, or a turned map shows as a different mean or a different layout.
Run as test_blender_addon.py is (tests/blender/run.sh)."""

import os
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "tests", "bench"))
bpy = pytest.importorskip("bpy")
import spangle_to_blender  # noqa: E402
from test_blender_addon import read_exr  # noqa: E402  (the add-on tests' EXR reader)

BUILD = os.environ.get("SPANGLE_BUILD", os.path.join(ROOT, "build"))
SPANGLE = os.path.join(BUILD, "spangle")
W, H, SPP = 64, 36, 64
MESHES = os.path.join(ROOT, "assets", "meshes")

# A floor and a ball, seen from above and in front (Spangle's y up), in the file's sRGB colours.
ROOM = f"""
[render]
width = {W}
height = {H}
spp = {SPP}
max_depth = 4
filter = "gaussian"
working_space = "lin_rec709"
color_space = "srgb_texture"

[camera]
position = [0.5, 2.5, 6.0]
look_at = [0.0, 0.6, 0.0]
fov = 35

[[material]]
name = "floor"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.5 }}

[[material]]
name = "ball"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = [0.8, 0.45, 0.3] }}

[[object]]
mesh = "{MESHES}/plane.ply"
material = "floor"
scale = 8

[[object]]
mesh = "{MESHES}/sphere.obj"
material = "ball"
translate = [-0.8, 0.7, 0.5]
scale = 0.7
"""

LIGHTS = {
    "sphere": '[[light]]\ntype = "sphere"\ncenter = [2.0, 3.0, 1.5]\nradius = 0.4\nintensity = 8\n',
    "quad": '[[light]]\ntype = "quad"\ncorner = [-1.5, 3.5, -1.0]\nedge1 = [2.0, 0.0, 0.0]\n'
            'edge2 = [0.0, 0.0, 1.5]\nintensity = 1.5\n',
    "point": '[[light]]\ntype = "point"\nposition = [1.5, 3.0, 2.0]\nintensity = 6\n',
    "distant": '[[light]]\ntype = "distant"\ndirection = [-1.0, 2.0, 1.2]\nintensity = 2.5\n'
               'angular_radius = 2\n',
    "map": f'[environment]\nmap = "{ROOT}/assets/env/studio_hdri.exr"\ncolor_space = "lin_rec709"\n'
           'rotation = 70\n',
}


def blocks(a, n=4):
    return a.reshape(H // n, n, W // n, n, 3).mean(axis=(1, 3)).ravel()


@pytest.mark.parametrize("light", sorted(LIGHTS))
def test_the_importer_lights_and_frames_a_scene_as_spangle_does(tmp_path, light):
    scene_file = tmp_path / f"{light}.toml"
    scene_file.write_text(ROOM + "\n" + LIGHTS[light])
    subprocess.run([SPANGLE, "render", str(scene_file), "--float", "--no-preview", "--threads", "2",
                    "-q", "-o", str(tmp_path / "spangle.exr")], check=True)
    ours = read_exr(str(tmp_path / "spangle.exr"))
    scene = spangle_to_blender.build(str(scene_file), W, H)
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising, c.seed = "CPU", SPP, False, False, 1
    scene.render.threads_mode, scene.render.threads = "FIXED", 2
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(tmp_path / "cycles.exr")
    bpy.ops.render.render(write_still=True)
    theirs = read_exr(str(tmp_path / "cycles.exr"))
    assert ours.shape == theirs.shape == (H, W, 3)
    # The same light in both: the image's mean (the ball, the floor, and for the map the
    # backdrop seen behind them) to 1.5%, and its layout: 4 x 4 pixel blocks' means
    # proportional. Measured: means within 0.1%, correlations above 0.996 (the map's); a light
    # 2% dim, or the map turned 30 degrees, fails.
    assert ours.mean() > 0.01
    assert theirs.mean() == pytest.approx(ours.mean(), rel=0.015)
    b_ours, b_theirs = blocks(ours), blocks(theirs)
    assert np.corrcoef(b_ours, b_theirs)[0, 1] > 0.99
