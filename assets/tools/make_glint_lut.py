#!/usr/bin/env python3
"""Writes assets/ocio/glint_view.spi3d, the 3D LUT of the shipped config's "Glint" view.

The view is a hue-preserving tone map: per pixel, in linear Rec.709,

    m = max(R, G, B)          the brightest channel
    d = m / (m + 0.8)         the tone curve: 0.18 -> 0.184, 1 -> 0.56, 10 -> 0.93, 100 -> 0.99
    out = (R, G, B) * d / m   every channel scaled alike: the ratios between channels are kept

then clipped to [0, 1] and sRGB-encoded by the config. Because all three channels are scaled by
the same factor, a glint ten times brighter than white keeps its colour instead of clipping to
white channel by channel (the Standard view) or desaturating towards white (ACES 1.0).

In the config the LUT sits between two log2 encodings (OCIO LogAffineTransforms):
  input  u = (log2(x / 0.18) + 10) / 20    20 stops around middle grey, 0.000176 .. 184
  output y = (log2(d) + 12) / 12           display-linear 2^-12 .. 1
In these coordinates log(out_c) = log(x_c) - log(m) + log(d(m)) is linear inside each region where
the same channel is the largest, which is what tetrahedral interpolation reproduces; only the
gentle curve log d(log m) is approximated between the 33 nodes (0.625 stops apart).

Run from the repository root:  python3 assets/tools/make_glint_lut.py
"""

import math
import os

N = 33
STOPS_BELOW, STOPS_ABOVE = 10.0, 10.0
OUT_STOPS = 12.0
K = 0.8  # the curve's half-brightness point: d(K) = 0.5


def decode_input(u):
    return 0.18 * 2.0 ** ((STOPS_BELOW + STOPS_ABOVE) * u - STOPS_BELOW)


def encode_output(d):
    d = max(d, 2.0 ** -OUT_STOPS)
    return min(1.0, max(0.0, (math.log2(d) + OUT_STOPS) / OUT_STOPS))


def tone(rgb):
    m = max(rgb)
    d = m / (m + K)
    return [encode_output(c * d / m) for c in rgb]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    path = os.path.join(here, "..", "ocio", "glint_view.spi3d")
    lines = ["SPILUT 1.0", "3 3", f"{N} {N} {N}"]
    for r in range(N):
        for g in range(N):
            for b in range(N):
                x = [decode_input(i / (N - 1)) for i in (r, g, b)]
                y = tone(x)
                lines.append(f"{r} {g} {b} {y[0]:.6f} {y[1]:.6f} {y[2]:.6f}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {os.path.normpath(path)} ({N}^3 nodes)")


if __name__ == "__main__":
    main()
