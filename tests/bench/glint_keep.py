#!/usr/bin/env python3
"""How many of a converged reference's glints a render keeps (docs/denoise.md).

    python3 tests/bench/glint_keep.py [--bright] REF.exr TEST.exr...

REF is a render written with --layers (it needs the glints and A layers); each TEST is a render
of the same scene, size and camera (denoised or not). The reference's glints are found as
`spangle flicker` finds them: pixels whose glints layer (Rec.709 luminance of its channels) is
brighter than 4 times its mean over the covered pixels and than 3 times the mean of its 5x5
neighbourhood (with --bright, the first test alone: every pixel of bright flake light, most of
them in glitter where neighbours glint too). A glint's contrast is the pixel's beauty luminance minus the mean of its 8
neighbours; a render keeps a glint when its contrast there is at least half the reference's.
Prints, per TEST, the share of glints kept and the median ratio of contrasts. Needs only
oiiotool (its --dumpdata), no Python packages.
"""
import os
import statistics
import subprocess
import sys
import tempfile

Y = (0.2126, 0.7152, 0.0722)


def read(path, channels):
    """The named channels of an EXR as a list of rows of tuples."""
    with tempfile.TemporaryDirectory() as tmp:
        part = os.path.join(tmp, "part.tif")
        subprocess.run(["oiiotool", path, "--ch", ",".join(channels), "-d", "float", "-o", part],
                       check=True)
        out = subprocess.run(["oiiotool", "--dumpdata", part], capture_output=True, text=True,
                             check=True).stdout
    pixels = {}
    width = height = 0
    for line in out.splitlines():
        line = line.strip()
        if not line.startswith("Pixel ("):
            continue
        head, values = line.split(":", 1)
        x, y = (int(v) for v in head[len("Pixel ("):-1].split(","))
        pixels[(x, y)] = tuple(float(v) for v in values.split())
        width, height = max(width, x + 1), max(height, y + 1)
    if not pixels:
        sys.exit(f"glint_keep.py: no pixels read from {path} (channels {channels})")
    return [[pixels[(x, y)] for x in range(width)] for y in range(height)]


def luminance(img):
    return [[Y[0] * p[0] + Y[1] * p[1] + Y[2] * p[2] for p in row] for row in img]


def glints(ref, local):
    layer = read(ref, ["glints.R", "glints.G", "glints.B", "A"])
    g = luminance(layer)
    h, w = len(g), len(g[0])
    covered = [g[y][x] for y in range(h) for x in range(w) if layer[y][x][3] > 0.999]
    threshold = 4.0 * sum(covered) / len(covered) if covered else 1.0
    found = []
    for y in range(h):
        for x in range(w):
            if not g[y][x] > threshold:
                continue
            box = [g[yy][xx] for yy in range(max(0, y - 2), min(h, y + 3))
                   for xx in range(max(0, x - 2), min(w, x + 3))]
            if not local or g[y][x] > 3.0 * sum(box) / len(box):
                found.append((x, y))
    return found


def contrast(lum, x, y):
    h, w = len(lum), len(lum[0])
    ring = [lum[yy][xx] for yy in range(max(0, y - 1), min(h, y + 2))
            for xx in range(max(0, x - 1), min(w, x + 2)) if (xx, yy) != (x, y)]
    return lum[y][x] - sum(ring) / len(ring)


def main():
    args = sys.argv[1:]
    local = "--bright" not in args
    args = [a for a in args if a != "--bright"]
    if len(args) < 2:
        sys.exit(__doc__)
    ref = args[0]
    found = glints(ref, local)
    ref_lum = luminance(read(ref, ["R", "G", "B"]))
    ref_c = {p: contrast(ref_lum, *p) for p in found}
    found = [p for p in found if ref_c[p] > 0.0]
    print(f"{ref}: {len(found)} glints")
    if not found:
        return
    for test in args[1:]:
        lum = luminance(read(test, ["R", "G", "B"]))
        if len(lum) != len(ref_lum) or len(lum[0]) != len(ref_lum[0]):
            sys.exit(f"glint_keep.py: {test} is not the size of {ref}")
        ratios = [contrast(lum, *p) / ref_c[p] for p in found]
        kept = sum(1 for r in ratios if r >= 0.5)
        print(f"{test}: {100.0 * kept / len(found):.1f}% kept (contrast at least half the "
              f"reference's), median contrast {statistics.median(ratios):.2f} of the reference's")


if __name__ == "__main__":
    main()
