#!/usr/bin/env bash
# The glitter beetle composited over a photograph-like plate, as docs/layers.md describes it: the
# plate (assets/scenes/concrete_plate.toml: a concrete floor in the beetle's studio), the beetle
# with --layers on a transparent background with the floor as a shadow catcher
# (assets/scenes/beetle_plate.toml), then with oiiotool
#   comp         = beetle over plate                       (premultiplied RGBA: its shadow is A)
#   glints x2    = (beauty + glints, A) over plate          (rest + 2 glints: the sparkle graded)
# and a film grain over both, as a photograph has. Writes OUT/plate.exr, OUT/beetle.exr,
# OUT/comp.exr, OUT/comp_glints2.exr and OUT/beetle_composite.png (the two side by side through
# the Glint view).
#
#   bash tests/bench/composite_beetle.sh BUILD OUT [WxH] [SPP]     (640x360, 64 spp by default)
set -eu
BUILD=$1 OUT=$2 SIZE=${3:-640x360} SPP=${4:-64}
REPO=$(cd "$(dirname "$0")/../.." && pwd)
S=$BUILD/spangle
OCIO_CONFIG=$REPO/assets/ocio/config.ocio
mkdir -p "$OUT"
"$S" render "$REPO/assets/scenes/concrete_plate.toml" -o "$OUT/plate.exr" --size "$SIZE" \
    --spp "$SPP" --float --no-preview -q
"$S" render "$REPO/assets/scenes/beetle_plate.toml" -o "$OUT/beetle.exr" --size "$SIZE" \
    --spp "$SPP" --layers --float --no-preview -q
grain=(--noise:type=gaussian:mean=0:stddev=0.012:mono=1)
oiiotool "$OUT/beetle.exr" --ch R,G,B,A "$OUT/plate.exr" --ch R,G,B --ch R,G,B,A=1 --over \
    "${grain[@]}" -o "$OUT/comp.exr"
oiiotool "$OUT/beetle.exr" --ch R,G,B "$OUT/beetle.exr" --ch glints.R,glints.G,glints.B \
    --chnames R,G,B --add "$OUT/beetle.exr" --ch A --chappend \
    "$OUT/plate.exr" --ch R,G,B --ch R,G,B,A=1 --over "${grain[@]}" -o "$OUT/comp_glints2.exr"
oiiotool --colorconfig "$OCIO_CONFIG" "$OUT/comp.exr" --ch R,G,B --iscolorspace ACEScg --ociodisplay sRGB Glint \
    "$OUT/comp_glints2.exr" --ch R,G,B --iscolorspace ACEScg --ociodisplay sRGB Glint --mosaic:pad=8 2x1 \
    -d uint8 -o "$OUT/beetle_composite.png"
echo "wrote $OUT/beetle_composite.png"
