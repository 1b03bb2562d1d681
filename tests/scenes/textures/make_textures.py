#!/usr/bin/env python3
"""Writes the test textures beside this file (committed; rerun only to change them):

    ripple_normal.png    64 x 64 tangent-space normal map of concentric ripples (OpenGL, green up)
    roughness_ramp.png   32 x 4 roughness from 0.02 (left) to 0.6 (right), data
    half_alpha.png       16 x 16 RGBA: green, alpha 0 in the left half and 1 in the right
    lace.png             64 x 64 grey + alpha: cream, round holes (alpha 0) on a 16-pixel grid
    red_opaque.png       8 x 8 RGBA: pure red, alpha 1 everywhere (pbrt drops such an alpha)
    red.webp             8 x 8 pure red, lossy WebP (`oiiotool red_opaque.png -o red.webp`; glTF EXT_texture_webp)

    python3 tests/scenes/textures/make_textures.py
"""
import math
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "..", "assets", "tools"))
from make_livery import write_png  # noqa: E402


def main():
    n = 64
    rows = []
    for py in range(n):
        row = bytearray()
        for px in range(n):
            x = (px + 0.5) / n - 0.5
            y = 0.5 - (py + 0.5) / n
            r = math.hypot(x, y)
            slope = 0.6 * math.cos(2 * math.pi * 6 * r)
            nx, ny = (slope * x / r, slope * y / r) if r > 0 else (0.0, 0.0)
            length = math.sqrt(nx * nx + ny * ny + 1.0)
            for c in (nx / length, ny / length, 1.0 / length):
                row.append(round(255 * (0.5 * c + 0.5)))
        rows.append(bytes(row))
    write_png(os.path.join(HERE, "ripple_normal.png"), n, n, 3, rows)
    ramp = [bytes(round(255 * (0.02 + 0.58 * (px + 0.5) / 32)) for px in range(32)) for _ in range(4)]
    write_png(os.path.join(HERE, "roughness_ramp.png"), 32, 4, 1, ramp)
    half = [bytes(v for px in range(16) for v in (40, 160, 60, 0 if px < 8 else 255))
            for _ in range(16)]
    write_png(os.path.join(HERE, "half_alpha.png"), 16, 16, 4, half)
    lace = [bytes(v for px in range(64)
                  for v in (225, 0 if math.hypot(px % 16 - 7.5, py % 16 - 7.5) < 5.5 else 255))
            for py in range(64)]
    write_png(os.path.join(HERE, "lace.png"), 64, 64, 2, lace)
    write_png(os.path.join(HERE, "red_opaque.png"), 8, 8, 4, [bytes((255, 0, 0, 255) * 8)] * 8)


if __name__ == "__main__":
    main()
