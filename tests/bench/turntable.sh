#!/usr/bin/env bash
# A turntable of the glitter beetle and how much its glints flicker, against the same sequence
# with the flakes' seed changed every frame (what a per-frame random realisation looks like).
#   tests/bench/turntable.sh OUT_DIR [FRAMES=12] [SIZE=480x270] [SPP=32] [DEGREES_PER_FRAME=2]
# Writes OUT_DIR/fixed/beetle.####.exr (+ .png), OUT_DIR/reseeded/..., the two `spangle flicker`
# reports, and a contact sheet of the fixed sequence. The camera orbits the car (the flicker
# measurement reprojects through world positions, which a moving camera keeps still).
set -eu
OUT=${1:?usage: turntable.sh OUT_DIR [FRAMES] [SIZE] [SPP] [DEGREES_PER_FRAME]}
FRAMES=${2:-12} SIZE=${3:-480x270} SPP=${4:-32} STEP=${5:-2}
REPO=$(cd "$(dirname "$0")/../.." && pwd)
S="$REPO/build/spangle"
mkdir -p "$OUT/fixed" "$OUT/reseeded"

# The beetle scene with absolute asset paths and an orbiting camera: one key per frame, on the
# circle through the scene's own camera position around the car's vertical axis.
sed "s#\"\.\./#\"$REPO/assets/#g" "$REPO/assets/scenes/beetle.toml" > "$OUT/turntable.toml"
python3 - "$OUT/turntable.toml" "$FRAMES" "$STEP" <<'PY'
import math, sys
path, frames, step = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
cx, cz = 0.1, 0.0                      # look_at of beetle.toml
px, py, pz = 4.6, 1.9, 4.2             # its camera position
r, a0 = math.hypot(px - cx, pz - cz), math.atan2(pz - cz, px - cx)
with open(path, "a") as f:
    for k in range(frames):
        a = a0 + math.radians(step * k)
        f.write(f"\n[[camera.keys]]\nframe = {k + 1}\nposition = [{cx + r * math.cos(a):.6f}, {py}, {cz + r * math.sin(a):.6f}]\n")
PY

"$S" render "$OUT/turntable.toml" -o "$OUT/fixed/beetle.####.exr" --frames "1..$FRAMES" \
    --size "$SIZE" --spp "$SPP" --layers -q
for f in $(seq 1 "$FRAMES"); do
    sed "s/coat_roughness = 0.0 }/coat_roughness = 0.0, seed = $f }/" "$OUT/turntable.toml" > "$OUT/reseeded.toml"
    "$S" render "$OUT/reseeded.toml" -o "$OUT/reseeded/beetle.####.exr" --frames "$f..$f" \
        --size "$SIZE" --spp "$SPP" --layers -q
done
"$S" flicker "$OUT"/fixed/beetle.*.exr | tee "$OUT/flicker_fixed.txt"
# The same glint threshold for both sequences.
T=$(sed -n 's/^glint mask threshold: \([^,]*\),.*/\1/p' "$OUT/flicker_fixed.txt")
"$S" flicker "$OUT"/reseeded/beetle.*.exr --threshold "$T" | tee "$OUT/flicker_reseeded.txt"
oiiotool $(ls "$OUT"/fixed/beetle.*.png | head -8) --mosaic 4x2 -o "$OUT/contact_sheet.png"
