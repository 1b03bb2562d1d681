"""Blender's compositor reads Spangle's Cryptomatte: `spangle render --layers` writes an EXR of two
named squares, one over the other's corner, on a transparent background; Blender's Cryptomatte
node (source: that image) keys each square by its name, and the two mattes add up to the image's
alpha in every pixel (the squares are all it covers).

Run with the add-on's tests (ctest blender.addon, tests/blender/run.sh)."""

import os
import subprocess

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BUILD = os.environ.get("SPANGLE_BUILD", os.path.join(ROOT, "build"))
SPANGLE = os.path.join(BUILD, "spangle")
W, H = 48, 32

SCENE = """
[render]
width = {w}
height = {h}
spp = 16
max_depth = 2
transparent_background = true
working_space = "lin_rec709"
[camera]
position = [0, 0, 3]
look_at = [0, 0, 0]
fov = 40
[environment]
color = [0.4, 0.5, 0.6]
[[material]]
name = "glitter"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.7 }}
[[material]]
name = "stone"
plugin = "smooth"
model = "diffuse"
params = {{ albedo = 0.3 }}
[[object]]
name = "hero"
mesh = "{meshes}/plane.ply"
material = "glitter"
rotate = [90, 0, 0]
scale = 0.3
[[object]]
name = "slab"
mesh = "{meshes}/plane.ply"
material = "stone"
rotate = [90, 0, 0]
translate = [0.45, 0.2, -0.5]
scale = 0.35
"""


def composite(image, matte_id, path):
    """Renders through the compositor, into an EXR at `path`, the Cryptomatte node's matte of
    `matte_id` over `image` (or, for matte_id None, the image's alpha), and returns it as a
    (rows bottom-up, columns) array."""
    scene = bpy.context.scene
    scene.use_nodes = True
    tree = scene.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    if matte_id is None:
        source = tree.nodes.new("CompositorNodeImage")
        source.image = image
        socket = source.outputs["Alpha"]
    else:
        crypto = tree.nodes.new("CompositorNodeCryptomatteV2")
        crypto.source = "IMAGE"
        crypto.image = image
        crypto.layer_name = "CryptoObject"
        crypto.matte_id = matte_id
        socket = crypto.outputs["Matte"]
    out = tree.nodes.new("CompositorNodeComposite")
    tree.links.new(socket, out.inputs["Image"])
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    scene.render.engine = "CYCLES"  # nothing to render: the compositor has no render layer
    scene.cycles.samples = 1
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    result = bpy.data.images.load(path)
    px = np.array(result.pixels[:], dtype=np.float32).reshape(H, W, 4)
    bpy.data.images.remove(result)
    return px[..., 0]


def test_blenders_cryptomatte_node_keys_each_object_by_name(tmp_path):
    meshes = os.path.join(ROOT, "assets", "meshes")
    scene_path = tmp_path / "two_squares.toml"
    scene_path.write_text(SCENE.format(w=W, h=H, meshes=meshes))
    exr = str(tmp_path / "two_squares.exr")
    subprocess.run([SPANGLE, "render", str(scene_path), "-o", exr, "--layers", "--float", "-q",
                    "--no-preview"], check=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    image = bpy.data.images.load(exr)
    alpha = composite(image, None, str(tmp_path / "alpha.exr"))
    hero = composite(image, "hero", str(tmp_path / "hero.exr"))
    slab = composite(image, "slab", str(tmp_path / "slab.exr"))
    # The squares are all the camera sees: their mattes add up to the coverage (alpha).
    assert alpha.max() == pytest.approx(1.0)
    np.testing.assert_allclose(hero + slab, alpha, atol=1e-4)
    # The hero square is in the middle of the frame, the slab up and to the right, behind it.
    assert hero[H // 2, W // 2] == pytest.approx(1.0, abs=1e-4)
    assert slab[H // 2, W // 2] == pytest.approx(0.0, abs=1e-4)
    up_right = (H // 2 + 4, W // 2 + 8)  # rows count up from the bottom in Blender
    assert slab[up_right] == pytest.approx(1.0, abs=1e-4)
    assert hero[up_right] == pytest.approx(0.0, abs=1e-4)
    # Each matte covers about its square's visible area in pixels, neither is empty.
    assert 40 < hero.sum() < 120 and 40 < slab.sum() < 160
