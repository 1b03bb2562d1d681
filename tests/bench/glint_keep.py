#!/usr/bin/env python3
"""How many of a converged reference's glints a render keeps (docs/denoise.md).

    python3 tests/bench/glint_keep.py [--bright] REF.exr TEST.exr...

REF is a render written with --layers (it needs the glints and A layers); each TEST is a render
of the same scene, size and camera, denoised or not. Where an image has a `background` layer
(the environment seen directly, kept apart by --layers) it is added back to R, G, B, so images
written with and without --layers compare alike.

The reference's glints are found as `spangle flicker` finds them: covered pixels whose glints
layer (Rec.709 luminance of its channels) is brighter than 4 times its mean over the covered
pixels and than 3 times the mean of its 5x5 neighbourhood. With --bright the first test alone
counts: every pixel of bright flake light, most of them inside glitter whose neighbours glint
too. A glint's contrast is the pixel's luminance minus the mean of its 8 neighbours; glints on
the image's border (fewer neighbours) and glints that stand out of their neighbours by less than
a tenth of their own luminance in the reference (a contrast too small to measure a ratio of)
are left out, and counted. A render keeps a glint when its contrast there is at least half the
reference's. Prints, per TEST, the share of glints kept and the median ratio of contrasts.
Needs only oiiotool (openimageio-tools), no Python packages.
"""
import argparse
import math
import os
import statistics
import subprocess
import sys
import tempfile

REC709_Y = (0.2126, 0.7152, 0.0722)
MIN_CONTRAST = 0.1  # of the reference pixel's luminance


def fail(message):
    sys.exit(f"glint_keep.py: {message}")


def oiiotool(*args):
    try:
        return subprocess.run(["oiiotool", *args], capture_output=True, text=True,
                              check=True).stdout
    except FileNotFoundError:
        fail("needs oiiotool (apt-get install openimageio-tools)")
    except subprocess.CalledProcessError as e:
        fail(f"oiiotool {' '.join(args)}: {e.stderr.strip() or e.stdout.strip()}")


def channels(path):
    """The channel names of an image."""
    for line in oiiotool("--info", "-v", path).splitlines():
        line = line.strip()
        if line.startswith("channel list:"):
            return [c.split("(")[0].strip() for c in line[len("channel list:"):].split(",")]
    fail(f"cannot read the channels of {path}")


def read(path, names):
    """The named channels of an image as rows of tuples; its data window must start at 0, 0
    (a whole frame, not a crop window)."""
    with tempfile.TemporaryDirectory() as tmp:
        part = os.path.join(tmp, "part.tif")
        oiiotool(path, "--ch", ",".join(names), "-d", "float", "-o", part)
        out = oiiotool("--dumpdata", part)
    pixels = {}
    for line in out.splitlines():
        line = line.strip()
        if not line.startswith("Pixel ("):
            continue
        head, values = line.split(":", 1)
        x, y = (int(v) for v in head[len("Pixel ("):-1].split(","))
        pixels[(x, y)] = tuple(float(v) for v in values.split())
    if not pixels:
        fail(f"no pixels read from {path}")
    xs, ys = [p[0] for p in pixels], [p[1] for p in pixels]
    width, height = max(xs) + 1, max(ys) + 1
    if min(xs) != 0 or min(ys) != 0 or len(pixels) != width * height:
        fail(f"{path} is not a whole frame (a crop window?); merge its parts first")
    return [[pixels[(x, y)] for x in range(width)] for y in range(height)]


BEAUTY = ["R", "G", "B"]
BACKGROUND = ["background.R", "background.G", "background.B"]
GLINTS = ["glints.R", "glints.G", "glints.B", "A"]


def load(path, extra=()):
    """An image's R, G, B, its background layer where it has one, and the `extra` channels, read
    in one pass: (rows of pixel tuples, the index of each channel name in a tuple)."""
    have = set(channels(path))
    if not set(BEAUTY) <= have:
        fail(f"{path} has no R, G, B")
    if not set(extra) <= have:
        fail(f"{path} has no {', '.join(extra)}: render the reference with --layers")
    names = BEAUTY + (BACKGROUND if set(BACKGROUND) <= have else []) + list(extra)
    return read(path, names), {n: i for i, n in enumerate(names)}


def luminance(p, i):
    """Rec.709 luminance of the three channels of pixel tuple `p` from index `i`."""
    return sum(w * c for w, c in zip(REC709_Y, p[i:i + 3]))


def beauty(img, col):
    """Luminance of R, G, B, plus the background layer where the image has one."""
    back = col.get(BACKGROUND[0])
    return [[luminance(p, 0) + (luminance(p, back) if back is not None else 0.0) for p in row]
            for row in img]


def glints(img, col, local):
    """The reference's glint pixels, as `spangle flicker` finds them (local) or every covered
    pixel above the threshold (not local). Non-finite values count as nothing."""
    gi, ai = col[GLINTS[0]], col["A"]
    g = [[v if math.isfinite(v) else 0.0 for v in (luminance(p, gi) for p in row)] for row in img]
    h, w = len(g), len(g[0])
    covered = [g[y][x] for y in range(h) for x in range(w) if img[y][x][ai] > 0.999]
    threshold = 4.0 * sum(covered) / len(covered) if covered else 1.0
    found = []
    for y in range(h):
        for x in range(w):
            if not (img[y][x][ai] > 0.999 and g[y][x] > threshold):
                continue
            box = [g[yy][xx] for yy in range(max(0, y - 2), min(h, y + 3))
                   for xx in range(max(0, x - 2), min(w, x + 3))]
            if not local or g[y][x] > 3.0 * sum(box) / len(box):
                found.append((x, y))
    return found


def contrast(lum, x, y):
    """The pixel's luminance minus the mean of its 8 neighbours (an inner pixel)."""
    ring = [lum[yy][xx] for yy in (y - 1, y, y + 1) for xx in (x - 1, x, x + 1)
            if (xx, yy) != (x, y)]
    return lum[y][x] - sum(ring) / 8.0


def main():
    ap = argparse.ArgumentParser(description="How many of a reference's glints renders keep.")
    ap.add_argument("--bright", action="store_true",
                    help="every pixel of bright flake light, not only flicker's glints")
    ap.add_argument("reference", help="the converged render, written with --layers")
    ap.add_argument("tests", nargs="+", help="renders of the same scene, size and camera")
    a = ap.parse_args()

    ref, col = load(a.reference, GLINTS)
    ref_lum = beauty(ref, col)
    h, w = len(ref_lum), len(ref_lum[0])
    found = glints(ref, col, not a.bright)
    inner = [(x, y) for x, y in found if 0 < x < w - 1 and 0 < y < h - 1]
    ref_c = {p: contrast(ref_lum, *p) for p in inner}
    measured = [p for p in inner
                if math.isfinite(ref_c[p]) and ref_c[p] > MIN_CONTRAST * ref_lum[p[1]][p[0]]]
    print(f"{a.reference}: {len(found)} glints, {len(measured)} measured "
          f"({len(found) - len(inner)} on the border, {len(inner) - len(measured)} standing out "
          f"of their neighbours by less than {MIN_CONTRAST:g} of their luminance)")
    if not measured:
        return
    for test in a.tests:
        lum = beauty(*load(test))
        if len(lum) != h or len(lum[0]) != w:
            fail(f"{test} is not the size of {a.reference}")
        ratios = [contrast(lum, *p) / ref_c[p] for p in measured]
        ratios = [r if math.isfinite(r) else 0.0 for r in ratios]
        kept = sum(1 for r in ratios if r >= 0.5)
        print(f"{test}: {100.0 * kept / len(measured):.1f}% kept (contrast at least half the "
              f"reference's), median contrast {statistics.median(ratios):.2f} of the reference's")


if __name__ == "__main__":
    main()
