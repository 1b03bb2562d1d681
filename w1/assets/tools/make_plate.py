#!/usr/bin/env python3
"""Writes assets/textures/concrete.png, a weathered concrete floor (sRGB, 512 x 512, tiling): the
texture of the photograph-like plate the beetle is composited over (tests/bench/composite_beetle.sh,
docs/layers.md). Value noise in four octaves for the mottling, a finer one for the aggregate,
scattered dark pits and pale stones, and two broad stains; every lattice wraps, so the texture
tiles.

    python3 assets/tools/make_plate.py
"""
import math
import os
import random
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_livery import write_png  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "textures", "concrete.png")
SIZE = 512


def lattice(n, rng):
    return [[rng.random() for _ in range(n)] for _ in range(n)]


def value_noise(grid, n, x, y):
    """Smoothly interpolated lattice noise at (x, y) in [0, 1)^2 on an n x n wrapping grid."""
    gx, gy = x * n, y * n
    i, j = int(gx), int(gy)
    fx, fy = gx - i, gy - j
    sx, sy = fx * fx * (3 - 2 * fx), fy * fy * (3 - 2 * fy)
    i0, j0, i1, j1 = i % n, j % n, (i + 1) % n, (j + 1) % n
    a = grid[j0][i0] + (grid[j0][i1] - grid[j0][i0]) * sx
    b = grid[j1][i0] + (grid[j1][i1] - grid[j1][i0]) * sx
    return a + (b - a) * sy


def main():
    rng = random.Random(29)
    octaves = [(n, lattice(n, rng)) for n in (4, 8, 16, 32)]
    fine = (128, lattice(128, rng))
    stains = [(rng.random(), rng.random(), 0.12 + 0.1 * rng.random()) for _ in range(2)]
    pits = {}
    for _ in range(2600):
        x, y = rng.randrange(SIZE), rng.randrange(SIZE)
        pits[(x, y)] = rng.choice((-0.35, -0.25, 0.18))
    rows = []
    for py in range(SIZE):
        row = bytearray()
        y = py / SIZE
        for px in range(SIZE):
            x = px / SIZE
            m = sum(value_noise(g, n, x, y) / (1 + k) for k, (n, g) in enumerate(octaves)) / 2.08
            grain = value_noise(fine[1], fine[0], x, y)
            v = 0.46 + 0.22 * (m - 0.5) + 0.08 * (grain - 0.5)
            for sx, sy, r in stains:
                dx = min(abs(x - sx), 1 - abs(x - sx))
                dy = min(abs(y - sy), 1 - abs(y - sy))
                v -= 0.07 * math.exp(-(dx * dx + dy * dy) / (r * r))
            v += pits.get((px, py), 0.0)
            v = min(max(v, 0.0), 1.0)
            # Slightly warm grey, as concrete under daylight.
            row += bytes(int(255 * min(1.0, v * c) + 0.5) for c in (1.04, 1.0, 0.93))
        rows.append(bytes(row))
    write_png(OUT, SIZE, SIZE, 3, rows)


if __name__ == "__main__":
    main()
