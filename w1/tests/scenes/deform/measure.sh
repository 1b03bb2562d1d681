#!/usr/bin/env bash
# The flicker of object-space glitter on a bending sheet, three ways (docs/animation.md):
#   bend    the sheet's frames with its rest pose (bend.toml): the flakes stay on the sheet
#   norest  the same frames without a rest pose (bend_norest.toml.in, one file a frame): the
#           flakes swim; measured through bend's layers (the same geometry: the same P, Z, A and
#           object, and the rest positions that tell which point is which), with its own glints
#   turn    the flat sheet turning rigidly by the mean change of tilt of the bend (turn.toml)
#   baked   the same turn baked into a deforming sequence with the flat sheet as its rest pose
#           (turn_baked.toml): should persist as turn does
#
#   bash tests/scenes/deform/measure.sh build/spangle OUT_DIR
# also writes OUT_DIR/deform-glints.png (docs/deform-glints.png): frames 1 and 8 with the rest
# pose, and a crop of frames 4, 5 and 6 as red, green and blue, with and without it.
set -eu
S=$(realpath "$1")
OUT=$2
D=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT"
python3 "$D/make_sheet.py"
"$S" render "$D/bend.toml" --frames 1..8 --layers -o "$OUT/bend.####.exr" -q
"$S" render "$D/turn.toml" --frames 1..8 --layers -o "$OUT/turn.####.exr" -q
"$S" render "$D/turn_baked.toml" --frames 1..8 --layers -o "$OUT/baked.####.exr" -q
for f in 1 2 3 4 5 6 7 8; do
    F=$(printf %04d "$f")
    sed "s#sheet.FRAME.ply#$D/sheet.$F.ply#" "$D/bend_norest.toml.in" > "$OUT/norest.$F.toml"
    "$S" render "$OUT/norest.$F.toml" --layers -o "$OUT/norest_own.$F.exr" -q
    # bend's channels and header, norest's glints.
    oiiotool "$OUT/bend.$F.exr" --ch "R,G,B,A,Z,object,N.X,N.Y,N.Z,P.X,P.Y,P.Z,Pobj.X,Pobj.Y,Pobj.Z" \
        "$OUT/norest_own.$F.exr" --ch "glints.R,glints.G,glints.B" --chappend \
        -o "$OUT/norest.$F.exr"
done
for run in bend norest turn baked; do
    echo "== $run"
    "$S" flicker "$OUT"/$run.000[1-8].exr
done
# The picture: a crop near the sheet's right edge (where it stretches most), 5x, frames 4, 5, 6
# in the red, green and blue channels: a flake that stays on the sheet draws a red-green-blue
# run as the sheet carries it; one that swims shows one colour.
for run in bend norest_own; do
    for f in 4 5 6; do
        oiiotool "$OUT/$run.000$f.png" --cut 64x36+224+48 --resample 320x180 -o "$OUT/crop_$run.$f.png"
    done
    oiiotool "$OUT/crop_$run.4.png" --ch R "$OUT/crop_$run.5.png" --ch G --chappend \
        "$OUT/crop_$run.6.png" --ch B --chappend --chnames R,G,B -o "$OUT/rgb_$run.png"
done
oiiotool "$OUT/bend.0001.png" "$OUT/bend.0008.png" "$OUT/rgb_bend.png" "$OUT/rgb_norest_own.png" \
    --mosaic:pad=4 2x2 -o "$OUT/deform-glints.png"
