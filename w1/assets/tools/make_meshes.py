#!/usr/bin/env python3
"""Writes the simple meshes in assets/meshes/: a UV sphere (OBJ with normals and uvs) and a
ground plane (binary little-endian PLY with normals and uvs). Run from anywhere:

    python3 assets/tools/make_meshes.py
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "meshes")


def sphere_obj(path, rings=48, segments=96):
    """Unit sphere centred at the origin; u around the equator, v from the south pole."""
    lines = ["# UV sphere, radius 1, written by assets/tools/make_meshes.py"]
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2 * math.pi * s / segments
            x, y, z = math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi)
            lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
            lines.append(f"vn {x:.6f} {y:.6f} {z:.6f}")
            lines.append(f"vt {s / segments:.6f} {1 - r / rings:.6f}")
    w = segments + 1
    for r in range(rings):
        for s in range(segments):
            a, b, c, d = r * w + s + 1, r * w + s + 2, (r + 1) * w + s + 2, (r + 1) * w + s + 1
            if r != 0:
                lines.append(f"f {a}/{a}/{a} {d}/{d}/{d} {b}/{b}/{b}")
            if r != rings - 1:
                lines.append(f"f {b}/{b}/{b} {d}/{d}/{d} {c}/{c}/{c}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def plane_ply(path, half=1.0, n=4):
    """Square in the xz plane at y = 0, normal +y, uv in [0, n] (n tiles across)."""
    verts = [(-half, 0, -half, 0, 0), (half, 0, -half, n, 0), (half, 0, half, n, n), (-half, 0, half, 0, n)]
    header = ("ply\nformat binary_little_endian 1.0\ncomment ground plane, assets/tools/make_meshes.py\n"
              f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              "property float s\nproperty float t\n"
              "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for x, y, z, u, v in verts:
            f.write(struct.pack("<8f", x, y, z, 0, 1, 0, u, v))
        for tri in ((0, 2, 1), (0, 3, 2)):
            f.write(struct.pack("<B3i", 3, *tri))


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    sphere_obj(os.path.join(OUT, "sphere.obj"))
    plane_ply(os.path.join(OUT, "plane.ply"))
