#!/usr/bin/env python3
"""Writes the load benchmark of the pbrt reader (issue 24): the same 2-million-triangle grid as
a pbrt trianglemesh, as a pbrt plymesh and as a TOML scene of the PLY, into OUT_DIR.

    python3 tests/bench/make_pbrt_load.py OUT_DIR [N]
    /usr/bin/time -v build/spangle render OUT_DIR/grid_trianglemesh.pbrt -o x.exr --size 64x64 --spp 1 --stats

N x N quads (N = 1000: 2,000,000 triangles, 1,002,001 vertices)."""
import os
import struct
import sys


def main():
    out = sys.argv[1]
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
    os.makedirs(out, exist_ok=True)
    verts = [(i / n * 4 - 2, 0.0, j / n * 4 - 2) for j in range(n + 1) for i in range(n + 1)]
    tris = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            b, c, d = a + 1, a + n + 1, a + n + 2
            tris.append((a, c, b))
            tris.append((b, c, d))
    with open(os.path.join(out, "grid.ply"), "wb") as f:
        f.write(b"ply\nformat binary_little_endian 1.0\n")
        f.write(b"element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(verts))
        f.write(b"element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(tris))
        f.write(b"".join(struct.pack("<3f", *v) for v in verts))
        f.write(b"".join(struct.pack("<B3i", 3, *t) for t in tris))
    head = ('LookAt 0 3 3  0 0 0  0 1 0\nCamera "perspective" "float fov" 45\n'
            'Film "image" "integer xresolution" 64 "integer yresolution" 64\nWorldBegin\n'
            'LightSource "infinite" "rgb L" [1 1 1]\n')
    with open(os.path.join(out, "grid_plymesh.pbrt"), "w") as f:
        f.write(head + 'Shape "plymesh" "string filename" "grid.ply"\n')
    with open(os.path.join(out, "grid_trianglemesh.pbrt"), "w") as f:
        f.write(head + 'Shape "trianglemesh" "point3 P" [\n')
        for k in range(0, len(verts), 8):
            f.write(" ".join("%.6g %.6g %.6g" % v for v in verts[k:k + 8]) + "\n")
        f.write(']\n  "integer indices" [\n')
        for k in range(0, len(tris), 16):
            f.write(" ".join("%d %d %d" % t for t in tris[k:k + 16]) + "\n")
        f.write("]\n")
    with open(os.path.join(out, "grid.toml"), "w") as f:
        f.write('[render]\nwidth = 64\nheight = 64\n\n[camera]\nposition = [0, 3, 3]\n'
                'look_at = [0, 0, 0]\nfov = 45\n\n[environment]\ncolor = [1, 1, 1]\n\n'
                '[[material]]\nname = "grey"\nplugin = "smooth"\nmodel = "diffuse"\n\n'
                '[[object]]\nmesh = "grid.ply"\nmaterial = "grey"\n')


if __name__ == "__main__":
    main()
