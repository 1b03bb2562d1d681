#!/usr/bin/env python3
"""Prints the 3x3 matrices used in assets/ocio/config.ocio, computed from chromaticities.

Reference space of the config: ACES2065-1 (AP0 primaries, ACES white). Spaces with a D65 white
are adapted to the ACES white with the Bradford transform. Run: python3 ocio_matrices.py
"""

AP0 = ((0.7347, 0.2653), (0.0, 1.0), (0.0001, -0.0770), (0.32168, 0.33767))
AP1 = ((0.713, 0.293), (0.165, 0.830), (0.128, 0.044), (0.32168, 0.33767))
REC709 = ((0.64, 0.33), (0.30, 0.60), (0.15, 0.06), (0.3127, 0.3290))
BRADFORD = ((0.8951, 0.2664, -0.1614), (-0.7502, 1.7135, 0.0367), (0.0389, -0.0685, 1.0296))


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def vec(a, v):
    return [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]


def inv(m):
    a, b, c = m[0]
    d, e, f = m[1]
    g, h, i = m[2]
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return [[(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det],
            [(f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det],
            [(d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det]]


def xyz(xy):
    x, y = xy
    return [x / y, 1.0, (1 - x - y) / y]


def rgb_to_xyz(prims):
    cols = [xyz(p) for p in prims[:3]]
    m = [[cols[j][i] for j in range(3)] for i in range(3)]
    s = vec(inv(m), xyz(prims[3]))
    return [[m[i][j] * s[j] for j in range(3)] for i in range(3)]


def bradford(src_white, dst_white):
    s = vec(BRADFORD, xyz(src_white))
    d = vec(BRADFORD, xyz(dst_white))
    scale = [[d[0] / s[0], 0, 0], [0, d[1] / s[1], 0], [0, 0, d[2] / s[2]]]
    return mul(inv(BRADFORD), mul(scale, BRADFORD))


def to_ap0(prims):
    m = rgb_to_xyz(prims)
    if prims[3] != AP0[3]:
        m = mul(bradford(prims[3], AP0[3]), m)
    return mul(inv(rgb_to_xyz(AP0)), m)


def show(name, m):
    flat = [m[i][j] for i in range(3) for j in range(3)]
    cells = ", ".join(f"{v:.10f}" for v in flat[0:3]) + ", 0, " + \
        ", ".join(f"{v:.10f}" for v in flat[3:6]) + ", 0, " + \
        ", ".join(f"{v:.10f}" for v in flat[6:9]) + ", 0, 0, 0, 0, 1"
    print(f"{name}: [{cells}]")


show("ACEScg -> ACES2065-1", to_ap0(AP1))
show("lin_rec709 -> ACES2065-1", to_ap0(REC709))
xyz_d65_from_ap0 = mul(bradford(AP0[3], REC709[3]), rgb_to_xyz(AP0))
show("ACES2065-1 -> CIE-XYZ-D65", xyz_d65_from_ap0)
