#!/usr/bin/env python3
"""Writes the small glTF scenes beside this script (seeds of the `gltf` fuzz target and scenes to
look at with `spangle render`): a lit, animated cube as .gltf (base64 buffer) and as .glb, a
flake-painted plane using SPANGLE_materials_flakes, and a skinned, morphing bar in the material
extensions read since (skin.gltf), and a textured, vertex-coloured torus compressed by the
tools users compress with: torus_draco.glb (draco_transcoder, KHR_draco_mesh_compression) and
torus_meshopt.glb (gltfpack -cc, EXT_meshopt_compression with quantisation and filters; Debian's
`draco` and `gltfpack` packages). Run it again after editing; the files are committed."""
import base64
import json
import math
import os
import shutil
import struct
import subprocess
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
PNG = open(os.path.join(HERE, "..", "textures", "roughness_ramp.png"), "rb").read()


class Buffer:
    def __init__(self):
        self.bin, self.views, self.accessors = b"", [], []

    def add(self, fmt, values, comps, type_, ctype):
        while len(self.bin) % 4:
            self.bin += b"\0"
        data = struct.pack("<%d%s" % (len(values), fmt), *values)
        self.views.append({"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)})
        self.bin += data
        acc = {"bufferView": len(self.views) - 1, "componentType": ctype,
               "count": len(values) // comps, "type": type_}
        if type_ == "VEC3" and ctype == 5126:
            acc["min"] = [min(values[i::3]) for i in range(3)]
            acc["max"] = [max(values[i::3]) for i in range(3)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def cube(buf):
    pos, nor, uv, idx = [], [], [], []
    for axis in range(3):
        for sign in (-1, 1):
            n = [0, 0, 0]
            n[axis] = sign
            u = [0, 0, 0]
            u[(axis + 1) % 3] = 1
            v = [0, 0, 0]
            v[(axis + 2) % 3] = 1
            base = len(pos) // 3
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos += [0.5 * (n[k] + a * u[k] + b * v[k]) for k in range(3)]
                nor += n
                uv += [(a + 1) / 2, (1 - b) / 2]
            quad = [0, 1, 2, 0, 2, 3] if sign > 0 else [0, 2, 1, 0, 3, 2]
            idx += [base + i for i in quad]
    return {"POSITION": buf.add("f", pos, 3, "VEC3", 5126),
            "NORMAL": buf.add("f", nor, 3, "VEC3", 5126),
            "TEXCOORD_0": buf.add("f", uv, 2, "VEC2", 5126)}, buf.add("H", idx, 1, "SCALAR", 5123)


def cube_scene():
    buf = Buffer()
    attrs, idx = cube(buf)
    t = buf.add("f", [0, 1, 2], 1, "SCALAR", 5126)
    r = buf.add("f", [0, 0, 0, 1, 0, 0.7071068, 0, 0.7071068, 0, 1, 0, 0], 4, "VEC4", 5126)
    doc = {
        "asset": {"version": "2.0", "generator": "tests/scenes/gltf/make_scenes.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_clearcoat"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "intensity": 4000, "color": [1, 0.9, 0.8]},
            {"type": "directional", "intensity": 1000},
            {"type": "spot", "intensity": 5000, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}}]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3, 4, 5]}],
        "nodes": [
            {"name": "Cube", "mesh": 0, "translation": [0, 0.5, 0]},
            {"name": "Floor", "mesh": 1, "scale": [6, 0.05, 6], "translation": [0, -0.025, 0]},
            {"name": "Camera", "camera": 0, "translation": [0, 1.5, 4], "rotation": [-0.1736482, 0, 0, 0.9848078]},
            {"name": "Lamp", "translation": [2, 3, 2], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "Sun", "rotation": [-0.3826834, 0, 0, 0.9238795], "extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"name": "Spot", "translation": [-2, 3, 0], "rotation": [-0.7071068, 0, 0, 0.7071068],
             "extensions": {"KHR_lights_punctual": {"light": 2}}}],
        "cameras": [{"name": "Camera", "type": "perspective",
                     "perspective": {"yfov": 0.7, "aspectRatio": 1.7777778, "znear": 0.1}}],
        "meshes": [{"name": "cube", "primitives": [{"attributes": attrs, "indices": idx, "material": 0}]},
                   {"name": "floor", "primitives": [{"attributes": attrs, "indices": idx, "material": 1}]}],
        "materials": [
            {"name": "Painted", "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [2, 2]}}},
                "baseColorFactor": [0.9, 0.4, 0.2, 1], "metallicFactor": 0.0, "roughnessFactor": 0.4},
             "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.05}}},
            {"name": "Floor", "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1],
                                                       "metallicFactor": 0.0, "roughnessFactor": 0.9}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 10497, "wrapT": 10497}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(PNG).decode()}],
        "animations": [{"name": "turn", "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}],
                        "samplers": [{"input": t, "output": r, "interpolation": "LINEAR"}]}],
    }
    return doc, buf


def flake_scene():
    buf = Buffer()
    pos = buf.add("f", [-1, 0, 1, 1, 0, 1, 1, 0, -1, -1, 0, -1], 3, "VEC3", 5126)
    nor = buf.add("f", [0, 1, 0] * 4, 3, "VEC3", 5126)
    uv = buf.add("f", [0, 1, 1, 1, 1, 0, 0, 0], 2, "VEC2", 5126)
    idx = buf.add("H", [0, 1, 2, 0, 2, 3], 1, "SCALAR", 5123)
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["SPANGLE_materials_flakes", "KHR_materials_clearcoat"],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 1.2, 2], "rotation": [-0.2588190, 0, 0, 0.9659258]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.6, "znear": 0.05}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nor, "TEXCOORD_0": uv},
                                    "indices": idx, "material": 0}]}],
        "materials": [{"name": "CarPaint",
                       "pbrMetallicRoughness": {"baseColorFactor": [0.05, 0.01, 0.01, 1]},
                       "extensions": {
                           "KHR_materials_clearcoat": {"clearcoatFactor": 1.0},
                           "SPANGLE_materials_flakes": {"density": 200000, "flake_roughness": 0.15,
                                                        "gamma": 3, "preset": "aluminium", "seed": 1,
                                                        "flake_color": [1, 0.95, 0.9]}}}],
    }
    return doc, buf


def skin_scene():
    """A bar of three rows on a two-joint skin, bending over a second, with a morph target whose
    weight is animated, in four materials of the extensions read since: specular-glossiness,
    sheen, unlit and tinted glass with a volume."""
    buf = Buffer()
    bar = [0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0]
    # One bar per material, side by side (1.5 apart in x).
    pos = [buf.add("f", [v + (1.5 * k if i % 3 == 0 else 0) for i, v in enumerate(bar)], 3,
                   "VEC3", 5126) for k in range(4)]
    nor = buf.add("f", [0, 0, 1] * 6, 3, "VEC3", 5126)
    idx = buf.add("H", [0, 1, 3, 0, 3, 2, 2, 3, 5, 2, 5, 4], 1, "SCALAR", 5123)
    joints = buf.add("H", [0, 0, 0, 0] * 2 + [0, 1, 0, 0] * 2 + [1, 0, 0, 0] * 2, 4, "VEC4", 5123)
    weights = buf.add("f", [1, 0, 0, 0] * 2 + [0.5, 0.5, 0, 0] * 2 + [1, 0, 0, 0] * 2, 4,
                      "VEC4", 5126)
    dpos = buf.add("f", [0.2, 0, 0.3] * 6, 3, "VEC3", 5126)
    ibm = buf.add("f", [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1,
                        1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, 0, 1], 16, "MAT4", 5126)
    times = buf.add("f", [0, 1], 1, "SCALAR", 5126)
    turn = buf.add("f", [0, 0, 0, 1, 0, 0, 0.7071068, 0.7071068], 4, "VEC4", 5126)
    wkeys = buf.add("f", [0, 1], 1, "SCALAR", 5126)

    def prim(material):
        return {"attributes": {"POSITION": pos[material], "NORMAL": nor, "JOINTS_0": joints,
                               "WEIGHTS_0": weights},
                "targets": [{"POSITION": dpos}], "indices": idx, "material": material}
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_pbrSpecularGlossiness", "KHR_materials_sheen",
                           "KHR_materials_unlit", "KHR_materials_transmission",
                           "KHR_materials_volume"],
        "nodes": [{"name": "bar", "mesh": 0, "skin": 0}, {"name": "root", "children": [2]},
                  {"name": "bend", "translation": [0, 1, 0]}],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm}],
        "meshes": [{"primitives": [prim(0), prim(1), prim(2), prim(3)], "weights": [0.25]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}},
                                     {"sampler": 1, "target": {"node": 0, "path": "weights"}}],
                        "samplers": [{"input": times, "output": turn},
                                     {"input": times, "output": wkeys}]}],
        "materials": [
            {"name": "SpecGloss", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                "diffuseFactor": [0.5, 0.4, 0.3, 1], "specularFactor": [0.9, 0.9, 0.9],
                "glossinessFactor": 0.6}}},
            {"name": "Velvet", "pbrMetallicRoughness": {"baseColorFactor": [0.3, 0.02, 0.05, 1],
                                                        "metallicFactor": 0},
             "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 0.6, 0.7],
                                                    "sheenRoughnessFactor": 0.3}}},
            {"name": "Unlit", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.6, 0.9, 1]},
             "extensions": {"KHR_materials_unlit": {}}},
            {"name": "Glass", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.3, 1],
                                                       "metallicFactor": 0,
                                                       "roughnessFactor": 0.1},
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1},
                            "KHR_materials_volume": {"thicknessFactor": 0.5,
                                                     "attenuationDistance": 1,
                                                     "attenuationColor": [0.9, 0.5, 0.2]}}}],
    }
    return doc, buf


def write_gltf(name, doc, buf):
    doc["buffers"] = [{"byteLength": len(buf.bin),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(buf.bin).decode()}]
    doc["bufferViews"], doc["accessors"] = buf.views, buf.accessors
    with open(os.path.join(HERE, name), "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


def write_glb(name, doc, buf):
    doc = dict(doc)
    doc["buffers"] = [{"byteLength": len(buf.bin)}]
    doc["bufferViews"], doc["accessors"] = buf.views, buf.accessors
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    b = buf.bin + b"\0" * (-len(buf.bin) % 4)
    out = b"glTF" + struct.pack("<II", 2, 12 + 8 + len(j) + 8 + len(b))
    out += struct.pack("<II", len(j), 0x4E4F534A) + j + struct.pack("<II", len(b), 0x004E4942) + b
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(out)


def torus_scene():
    """A torus of 24 x 12 quads with normals, uvs, vertex colours and a textured material."""
    buf = Buffer()
    pos, nor, uv, col, idx = [], [], [], [], []
    nu, nv = 24, 12
    for j in range(nv + 1):
        for i in range(nu + 1):
            u, v = i / nu, j / nv
            a, b = 2 * math.pi * u, 2 * math.pi * v
            n = [math.cos(a) * math.cos(b), math.sin(b), math.sin(a) * math.cos(b)]
            c = [math.cos(a), 0.0, math.sin(a)]
            pos += [c[k] + 0.4 * n[k] for k in range(3)]
            nor += n
            uv += [u, v]
            col += [u, v, 1 - u, 1.0]
    for j in range(nv):
        for i in range(nu):
            a = j * (nu + 1) + i
            b = a + nu + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    attrs = {"POSITION": buf.add("f", pos, 3, "VEC3", 5126),
             "NORMAL": buf.add("f", nor, 3, "VEC3", 5126),
             "TEXCOORD_0": buf.add("f", uv, 2, "VEC2", 5126),
             "COLOR_0": buf.add("f", col, 4, "VEC4", 5126)}
    buf.accessors[attrs["POSITION"]].update({"min": [-1.4, -0.4, -1.4], "max": [1.4, 0.4, 1.4]})
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "images": [{"uri": "texture.png"}], "textures": [{"source": 0}],
           "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
           "meshes": [{"primitives": [{"attributes": attrs,
                                       "indices": buf.add("H", idx, 1, "SCALAR", 5123),
                                       "material": 0}]}]}
    return doc, buf


def compressed_toruses():
    """torus_draco.glb and torus_meshopt.glb, from the torus as .gltf + .bin (the form both tools
    read), when the tools are installed."""
    if not shutil.which("draco_transcoder") or not shutil.which("gltfpack"):
        print("draco_transcoder or gltfpack not found: the compressed toruses are kept as they are")
        return
    doc, buf = torus_scene()
    with tempfile.TemporaryDirectory() as tmp:
        doc["buffers"] = [{"byteLength": len(buf.bin), "uri": "torus.bin"}]
        doc["bufferViews"], doc["accessors"] = buf.views, buf.accessors
        with open(os.path.join(tmp, "torus.gltf"), "w") as f:
            json.dump(doc, f)
        with open(os.path.join(tmp, "torus.bin"), "wb") as f:
            f.write(buf.bin)
        with open(os.path.join(tmp, "texture.png"), "wb") as f:
            f.write(PNG)
        src = os.path.join(tmp, "torus.gltf")
        subprocess.run(["draco_transcoder", "-i", src, "-o", os.path.join(HERE, "torus_draco.glb"),
                        "-qp", "12"], check=True, stdout=subprocess.DEVNULL)
        subprocess.run(["gltfpack", "-i", src, "-o", os.path.join(HERE, "torus_meshopt.glb"),
                        "-cc"], check=True, stdout=subprocess.DEVNULL)


if __name__ == "__main__":
    doc, buf = cube_scene()
    write_gltf("cube.gltf", json.loads(json.dumps(doc)), buf)
    write_glb("cube.glb", doc, buf)
    write_gltf("flakes.gltf", *flake_scene())
    write_gltf("skin.gltf", *skin_scene())
    compressed_toruses()
