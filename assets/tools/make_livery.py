#!/usr/bin/env python3
"""Writes the beetle's livery textures in assets/textures/:

    beetle_livery.png   base colour (sRGB): red paint, two white racing stripes over the hood,
                        roof and tail, a white roundel on each door, a thin pinstripe along
                        each side
    beetle_flakes.png   flake_weight (data): 0.45 in the paint, 0 under the stripes, roundels and
                        pinstripes (a flake mask: the livery is solid colour, the paint glitters)

The body (assets/tools/make_cages.py) is a cube-sphere whose six cube faces are uv tiles
0..5 along u: tile i covers u in [i, i + 1], v in [0, 1], and a tile's (s, t) in [0, 1]^2 is the
cube face's (u axis, v axis) coordinate (2 s - 1, 2 t - 1). The car is long along x (front +x),
wide along z, up along y. The textures span u in [0, 6]: the scene divides u by 6.

    python3 assets/tools/make_livery.py
"""
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "textures")
TILE = 256
SUPER = 4  # supersamples per axis: smooth edges

PAINT = (0.55, 0.03, 0.04)  # sRGB-encoded, as the scene's paint
WHITE = (0.88, 0.87, 0.82)
FLAKES = 0.45


def stripes(c):
    """Inside one of the two racing stripes, by the cube coordinate across the car (z)."""
    return 0.06 <= abs(c) <= 0.22


def livery(tile, s, t):
    """True where the livery (white, no flakes) is, at tile-local (s, t)."""
    a, b = 2 * s - 1, 2 * t - 1  # cube-face coordinates along the tile's u and v axes
    if tile == 2:  # roof: u axis z, v axis x
        return stripes(a)
    if tile == 0:  # front: u axis y, v axis z
        return stripes(b) and a > -0.3
    if tile == 1:  # rear: u axis z, v axis y
        return stripes(a) and b > -0.3
    if tile in (4, 5):  # sides: +z (u axis x, v axis y), -z (u axis y, v axis x)
        x, y = (a, b) if tile == 4 else (b, a)
        roundel = (x + 0.1) ** 2 + (y - 0.05) ** 2 <= 0.2 ** 2
        pinstripe = -0.2 <= y <= -0.17 and abs(x) <= 0.85
        return roundel or pinstripe
    return False


def write_png(path, width, height, channels, rows):
    """rows: bytes per row (channels x width, 8-bit)."""
    raw = b"".join(b"\x00" + r for r in rows)
    kind = {1: 0, 2: 4, 3: 2, 4: 6}[channels]

    def chunk(tag, data):
        c = struct.pack(">I", len(data)) + tag + data
        return c + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n"
    png += chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, kind, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9))
    png += chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def main():
    os.makedirs(OUT, exist_ok=True)
    width, height = 6 * TILE, TILE
    colour_rows, flake_rows = [], []
    for py in range(height):
        crow, frow = bytearray(), bytearray()
        for px in range(width):
            tile = px // TILE
            cover = 0
            for i in range(SUPER):
                for j in range(SUPER):
                    s = (px % TILE + (i + 0.5) / SUPER) / TILE
                    t = 1.0 - (py + (j + 0.5) / SUPER) / TILE  # row 0 is v = 1
                    cover += livery(tile, s, t)
            w = cover / (SUPER * SUPER)
            for k in range(3):
                crow.append(round(255 * (PAINT[k] * (1 - w) + WHITE[k] * w)))
            frow.append(round(255 * FLAKES * (1 - w)))
        colour_rows.append(bytes(crow))
        flake_rows.append(bytes(frow))
    write_png(os.path.join(OUT, "beetle_livery.png"), width, height, 3, colour_rows)
    write_png(os.path.join(OUT, "beetle_flakes.png"), width, height, 1, flake_rows)
    print("wrote", os.path.normpath(OUT))


if __name__ == "__main__":
    main()
