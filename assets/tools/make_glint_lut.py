#!/usr/bin/env python3
"""Writes the 3D LUTs of the shipped config's two hue-keeping views:

assets/ocio/sparkle_view.spi3d, the "Sparkle" view (the default). Per pixel, in linear Rec.709,

    m = max(R, G, B)                    the brightest channel
    d = m                     m <= 0.5  the tone curve: linear up to 0.5 (middle grey stays 0.18),
    d = 0.5 + 0.5 (1 - exp(-(m - 0.5) / 0.5))  then a shoulder: 1 -> 0.816, 2 -> 0.975, 4 -> 0.9995
    c = (R, G, B) * d / m               every channel scaled alike: the hue is kept
    w = smoothstep((log2 m - 1) / 5)    0 up to m = 2, 1 from m = 64: how far past white it is
    out = (1 - w) c + w (d, d, d)       very bright pixels go to white, as an eye or film sees them

so diffuse white (1.0) shows at 0.82 (sRGB 235 of 255), a coloured glint up to twice diffuse
white keeps its colour exactly, and a glint of 8 is about a third of the way to white, one of 44
is 97% there: a sparkle has a white core with a coloured rim, where its filtered neighbours are
less bright.

assets/ocio/glint_view.spi3d, the "Glint" view: the same scaling without the white,

    d = m / (m + 0.8)         the tone curve: 0.18 -> 0.184, 1 -> 0.56, 10 -> 0.93, 100 -> 0.99
    out = (R, G, B) * d / m   every channel scaled alike: the ratios between channels are kept

Because all three channels are scaled by the same factor, a glint ten times brighter than white
keeps its colour instead of clipping to white channel by channel (the Standard view) or
desaturating towards white (ACES 1.0); it never reaches white.

Both are then clipped to [0, 1] and sRGB-encoded by the config. In the config each LUT sits
between two log2 encodings (OCIO LogAffineTransforms):
  input  u = (log2(x / 0.18) + 10) / 20    20 stops around middle grey, 0.000176 .. 184
  output y = (log2(d) + 12) / 12           display-linear 2^-12 .. 1
In these coordinates log(out_c) = log(x_c) - log(m) + log(d(m)) is linear inside each region where
the same channel is the largest, which is what tetrahedral interpolation reproduces; only the
gentle curves (log d and the white blend against log m) are approximated between the 33 nodes
(0.625 stops apart).

Run from the repository root:  python3 assets/tools/make_glint_lut.py
"""

import math
import os

N = 33
STOPS_BELOW, STOPS_ABOVE = 10.0, 10.0
OUT_STOPS = 12.0
K = 0.8  # the Glint curve's half-brightness point: d(K) = 0.5
TOE = 0.5  # the Sparkle curve is linear below this, a shoulder above
WHITE_FROM, WHITE_STOPS = 1.0, 5.0  # Sparkle: the white blend runs from log2 m = 1 over 5 stops


def decode_input(u):
    return 0.18 * 2.0 ** ((STOPS_BELOW + STOPS_ABOVE) * u - STOPS_BELOW)


def encode_output(d):
    d = max(d, 2.0 ** -OUT_STOPS)
    return min(1.0, max(0.0, (math.log2(d) + OUT_STOPS) / OUT_STOPS))


def glint(rgb):
    """The Glint view in display-linear values."""
    m = max(rgb)
    d = m / (m + K)
    return [c * d / m for c in rgb]


def sparkle(rgb):
    """The Sparkle view in display-linear values."""
    m = max(rgb)
    d = m if m <= TOE else TOE + (1 - TOE) * (1 - math.exp(-(m - TOE) / (1 - TOE)))
    t = min(1.0, max(0.0, (math.log2(m) - WHITE_FROM) / WHITE_STOPS))
    w = t * t * (3 - 2 * t)
    return [(1 - w) * c * d / m + w * d for c in rgb]


def write(name, tone):
    here = os.path.dirname(os.path.abspath(__file__))
    path = os.path.join(here, "..", "ocio", name)
    lines = ["SPILUT 1.0", "3 3", f"{N} {N} {N}"]
    for r in range(N):
        for g in range(N):
            for b in range(N):
                x = [decode_input(i / (N - 1)) for i in (r, g, b)]
                y = [encode_output(c) for c in tone(x)]
                lines.append(f"{r} {g} {b} {y[0]:.6f} {y[1]:.6f} {y[2]:.6f}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"wrote {os.path.normpath(path)} ({N}^3 nodes)")


def main():
    write("glint_view.spi3d", glint)
    write("sparkle_view.spi3d", sparkle)


if __name__ == "__main__":
    main()
