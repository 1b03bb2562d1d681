"""glTF skins and morph targets as Blender's own exporter writes them, against Blender's own
deformation: a cylinder on a two-bone armature (moved, turned and scaled as a whole, the upper
bone keyed to bend 80 degrees) with a
shape key keyed from 0 to 1, exported to .glb; `spangle convert` writes the deforming mesh as one
PLY per frame; every vertex of those frames must lie where Blender's evaluated mesh has one (and
the other way round), to float rounding.

Run with the add-on's tests (tests/blender/run.sh, ctest blender.addon).
"""

import math
import os
import subprocess

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BUILD = os.environ.get("SPANGLE_BUILD", os.path.join(ROOT, "build"))
SPANGLE = os.path.join(BUILD, "spangle")


def bending_cylinder():
    """The cylinder, its armature and their keys (frames 1 to 24); returns the cylinder."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cylinder_add(vertices=16, radius=0.3, depth=2, location=(0, 0, 1))
    cyl = bpy.context.active_object
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.subdivide(number_cuts=6)
    bpy.ops.object.mode_set(mode="OBJECT")
    cyl.shape_key_add(name="Basis")
    bulge = cyl.shape_key_add(name="Bulge")
    for i, v in enumerate(cyl.data.vertices):
        f = 1 + 0.5 * math.exp(-(v.co.z ** 2) / 0.1)
        bulge.data[i].co = (v.co.x * f, v.co.y * f, v.co.z)
    for frame, value in ((1, 0.0), (24, 1.0)):
        bulge.value = value
        bulge.keyframe_insert("value", frame=frame)
    bpy.ops.object.armature_add(location=(0, 0, 0))
    arm = bpy.context.active_object
    bpy.ops.object.mode_set(mode="EDIT")
    lower = arm.data.edit_bones[0]
    lower.head, lower.tail, lower.name = (0, 0, 0), (0, 0, 1), "lower"
    upper = arm.data.edit_bones.new("upper")
    upper.head, upper.tail, upper.parent = (0, 0, 1), (0, 0, 2), lower
    bpy.ops.object.mode_set(mode="OBJECT")
    cyl.select_set(True)
    arm.select_set(True)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.parent_set(type="ARMATURE_AUTO")
    bpy.ops.object.mode_set(mode="POSE")
    bone = arm.pose.bones["upper"]
    bone.rotation_mode = "XYZ"
    for frame, angle in ((1, 0.0), (24, 80.0)):
        bone.rotation_euler = (math.radians(angle), 0, 0)
        bone.keyframe_insert("rotation_euler", frame=frame)
    bpy.ops.object.mode_set(mode="OBJECT")
    # The armature moved, turned and scaled as a whole: the object's placement (its first
    # joint's) carries that, the deformation the bend.
    arm.location = (1.0, 0.5, -0.25)
    arm.rotation_euler = (0.0, 0.0, math.radians(30.0))
    arm.scale = (0.5, 0.5, 0.5)
    bpy.context.scene.frame_start, bpy.context.scene.frame_end = 1, 24
    return cyl


def blender_points(cyl, frame):
    """World positions of the evaluated cylinder at `frame`, in glTF's axes (y up)."""
    bpy.context.scene.frame_set(frame)
    ev = cyl.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = ev.to_mesh()
    pts = np.array([tuple(ev.matrix_world @ v.co) for v in mesh.vertices], dtype=np.float64)
    ev.to_mesh_clear()
    return np.stack([pts[:, 0], pts[:, 2], -pts[:, 1]], axis=1)


def ply_points(path):
    """Vertex positions of a binary PLY written by spangle (float x y z first)."""
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    count = int(next(l for l in header if l.startswith("element vertex")).split()[-1])
    props = sum(1 for l in header if l.startswith("property float"))
    return np.frombuffer(data[end:end + count * props * 4], dtype="<f4").reshape(count, props)[:, :3]


def placement(toml_text):
    """The first object's placement (its `matrix`, 3 x 4 rows) of a converted scene, checked
    to be the same at every key (Blender's exporter keys the root bone's still channels)."""
    import tomllib
    obj = tomllib.loads(toml_text)["object"][0]
    m = np.array(obj["matrix"], dtype=np.float64).reshape(3, 4)
    for key in obj.get("keys", []):
        assert np.allclose(np.array(key["matrix"]).reshape(3, 4), m, atol=1e-6), key
    return m


def farthest(a, b):
    """The largest distance from a point of a to its nearest point of b."""
    worst = 0.0
    for i in range(0, len(a), 256):
        d = np.sqrt(((a[i:i + 256, None, :] - b[None, :, :]) ** 2).sum(-1)).min(axis=1)
        worst = max(worst, float(d.max()))
    return worst


def test_a_skinned_and_morphed_gltf_deforms_as_blender_deforms_it(tmp_path):
    cyl = bending_cylinder()
    glb = str(tmp_path / "bend.glb")
    bpy.ops.export_scene.gltf(filepath=glb, export_animations=True, export_skins=True,
                              export_morph=True)
    out = subprocess.run([SPANGLE, "convert", glb, "-o", str(tmp_path / "bend.toml")],
                         capture_output=True, text=True, check=True)
    toml = (tmp_path / "bend.toml").read_text()
    assert 'mesh = "bend_meshes/deform_000.####.ply"' in toml, toml
    assert "rest_mesh" in toml
    said = [line.split(": ", 2)[-1] for line in out.stderr.splitlines() if "warning" in line]
    assert not [m for m in said if "skin" in m or "morph" in m or "dropped" in m], said
    # Blender's exporter keys frame f at f / fps seconds, Spangle's frame f is (f - 1) / fps:
    # Blender's frame f is Spangle's f + 1.
    m = placement(toml)
    for frame in (1, 6, 12, 24):
        local = ply_points(str(tmp_path / "bend_meshes" / f"deform_000.{frame + 1:04d}.ply"))
        ours = local.astype(np.float64) @ m[:, :3].T + m[:, 3]
        theirs = blender_points(cyl, frame)
        size = float(np.abs(theirs).max())
        assert farthest(ours, theirs) < 2e-6 * size, frame
        assert farthest(theirs, ours) < 2e-6 * size, frame
    # The bend happened: the top of the cylinder came down by a good part of its height.
    top0 = blender_points(cyl, 1)[:, 1].max()
    top24 = blender_points(cyl, 24)[:, 1].max()
    assert top0 - top24 > 0.15
