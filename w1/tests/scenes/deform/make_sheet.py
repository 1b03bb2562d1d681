#!/usr/bin/env python3
"""Writes the bending sheet of tests/scenes/deform/: a flat 2 x 1.2 sheet (sheet.rest.ply) and
eight frames of it (sheet.0001.ply .. sheet.0008.ply) bent about the y axis with a curvature
that grows by 0.04 per frame, and stretched along its width by 1.5% of its rest width per frame
(as skin or cloth stretches: the points slide over the object's space, 0.015 units a frame at
the edges, where a bend alone mostly lifts them). The sheet is 48 quads across (the bend) and 1
along y, with vertex normals: a few kB per file. It also writes the flat sheet turned rigidly
about y as turn.toml turns it (turn.0001.ply .. turn.0008.ply, TURN_STEP degrees a frame): the
rigid motion as a deforming sequence, for turn_baked.toml.

    python3 tests/scenes/deform/make_sheet.py [OUT_DIR]   (default: this script's folder)
"""
import math
import os
import sys

COLUMNS = 48  # quads across the bend
HALF_WIDTH, HALF_HEIGHT = 1.0, 0.6
CURVATURE_0, CURVATURE_STEP, FRAMES = 0.2, 0.04, 8
STRETCH_STEP = 0.015  # of the rest width, per frame
TURN_STEP = 9.465 / 7.0  # degrees per frame: turn.toml's keys, 0 at frame 1 and 9.465 at 8


def bent(s, y, k):
    """The point at arc length s (from the middle) of a sheet of curvature k, and its normal."""
    if k == 0.0:
        return (s, y, 0.0), (0.0, 0.0, 1.0)
    a = k * s
    return (math.sin(a) / k, y, (1.0 - math.cos(a)) / k), (-math.sin(a), 0.0, math.cos(a))


def turned(vertex, degrees):
    """A point and normal turned about y (right-handed, as Spangle's rotate)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return tuple((v[0] * c + v[2] * s, v[1], -v[0] * s + v[2] * c) for v in vertex)


def write(path, k, stretch, degrees=0.0):
    verts, faces = [], []
    for y in (-HALF_HEIGHT, HALF_HEIGHT):
        for i in range(COLUMNS + 1):
            s = (-HALF_WIDTH + 2.0 * HALF_WIDTH * i / COLUMNS) * stretch
            verts.append(turned(bent(s, y, k), degrees))
    for i in range(COLUMNS):
        a, b, c, d = i, i + 1, COLUMNS + 2 + i, COLUMNS + 1 + i
        faces += [(a, b, c), (a, c, d)]
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\ncomment written by make_sheet.py, curvature %g\n" % k)
        f.write("element vertex %d\n" % len(verts))
        f.write("".join("property float %s\n" % n for n in ("x", "y", "z", "nx", "ny", "nz")))
        f.write("element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(faces))
        for (p, n) in verts:
            f.write("%.7g %.7g %.7g %.7g %.7g %.7g\n" % (p + n))
        for t in faces:
            f.write("3 %d %d %d\n" % t)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    write(os.path.join(out, "sheet.rest.ply"), 0.0, 1.0)
    for frame in range(1, FRAMES + 1):
        write(os.path.join(out, "sheet.%04d.ply" % frame), CURVATURE_0 + CURVATURE_STEP * (frame - 1),
              1.0 + STRETCH_STEP * (frame - 1))
        write(os.path.join(out, "turn.%04d.ply" % frame), 0.0, 1.0, TURN_STEP * (frame - 1))


if __name__ == "__main__":
    main()
