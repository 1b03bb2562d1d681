#!/usr/bin/env python3
"""Writes assets/env/studio.exr: a procedural lat-long studio environment (linear Rec.709).

A dim blue-grey sky gradient, a warm ground, two large soft boxes, a small hard key light and a
thin rim strip: the bright, compact shapes give glossy and glittering materials something to
reflect. The script writes Radiance RGBE (no dependencies), then converts it with oiiotool:

    python3 assets/tools/make_sky.py      # needs oiiotool (openimageio-tools) for the EXR
"""
import math
import os
import subprocess
import sys

W, H = 512, 256
HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "env")


def direction(x, y):
    """Pixel centre to a unit direction, matching Spangle's map: u = 0.5 looks down -z, row 0 up."""
    u, v = (x + 0.5) / W, (y + 0.5) / H
    phi, theta = (u - 0.5) * 2 * math.pi, v * math.pi
    s = math.sin(theta)
    return s * math.sin(phi), math.cos(theta), -s * math.cos(phi)


def box(d, centre, half_w, half_h, softness):
    """A soft-edged rectangular panel around direction `centre` (azimuth, elevation in degrees)."""
    az, el = centre
    x, y, z = d
    d_az = math.degrees(math.atan2(x, -z)) - az
    d_az = (d_az + 180) % 360 - 180
    d_el = math.degrees(math.asin(max(-1.0, min(1.0, y)))) - el
    fx = max(0.0, abs(d_az) - half_w) / softness
    fy = max(0.0, abs(d_el) - half_h) / softness
    return math.exp(-(fx * fx + fy * fy))


def radiance(d):
    x, y, z = d
    if y >= 0:
        t = y ** 0.5
        sky = [0.35 * (1 - t) + 0.10 * t, 0.38 * (1 - t) + 0.16 * t, 0.42 * (1 - t) + 0.30 * t]
    else:
        g = min(1.0, -y * 4)
        sky = [0.16 * (1 - g) + 0.09 * g, 0.14 * (1 - g) + 0.07 * g, 0.12 * (1 - g) + 0.05 * g]
    light = [0.0, 0.0, 0.0]
    for centre, hw, hh, soft, col in (((-60, 35), 22, 12, 2.5, (9.0, 9.0, 8.5)),
                                      ((70, 25), 14, 18, 2.5, (5.0, 5.4, 6.0)),
                                      ((160, 10), 40, 1.5, 1.0, (6.0, 6.0, 6.0))):
        k = box(d, centre, hw, hh, soft)
        light = [l + k * c for l, c in zip(light, col)]
    k = box(d, (20, 55), 1.2, 1.2, 0.4)  # small, hard key light
    light = [l + k * c for l, c in zip(light, (400.0, 380.0, 340.0))]
    return [s + l for s, l in zip(sky, light)]


def rgbe(c):
    m = max(c)
    if m < 1e-32:
        return bytes((0, 0, 0, 0))
    mant, exp = math.frexp(m)
    scale = mant * 256.0 / m
    return bytes((int(c[0] * scale), int(c[1] * scale), int(c[2] * scale), exp + 128))


def main():
    os.makedirs(OUT, exist_ok=True)
    hdr = os.path.join(OUT, "studio.hdr")
    with open(hdr, "wb") as f:
        f.write(f"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {H} +X {W}\n".encode("ascii"))
        for y in range(H):
            f.write(b"".join(rgbe(radiance(direction(x, y))) for x in range(W)))
    exr = os.path.join(OUT, "studio.exr")
    subprocess.run(["oiiotool", hdr, "-d", "half", "--compression", "zip", "-o", exr], check=True)
    os.remove(hdr)


if __name__ == "__main__":
    sys.exit(main())
