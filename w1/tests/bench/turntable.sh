#!/usr/bin/env bash
# A turntable of the glitter beetle and how much its glints flicker, against the same sequence
# with the flakes' seed changed every frame (what a per-frame random realisation looks like).
#   tests/bench/turntable.sh OUT_DIR [FRAMES=12] [SIZE=480x270] [SPP=32] [DEGREES_PER_FRAME=2]
#                            [MOTION=turn|orbit]
# turn (the default): the car turns on the spot under the studio light and the fixed camera
# (every beetle object keyed about the vertical axis); orbit: the camera circles the still car.
# Writes OUT_DIR/fixed/beetle.####.exr (+ .png), OUT_DIR/reseeded/..., the two `spangle flicker`
# reports, a contact sheet of the fixed sequence, an animated GIF of it and, when ffmpeg is
# installed, an MP4 of each sequence.
set -eu -o pipefail
OUT=${1:?usage: turntable.sh OUT_DIR [FRAMES] [SIZE] [SPP] [DEGREES_PER_FRAME] [turn|orbit]}
FRAMES=${2:-12} SIZE=${3:-480x270} SPP=${4:-32} STEP=${5:-2} MOTION=${6:-turn}
[ "$FRAMES" -ge 2 ] 2>/dev/null || { echo "turntable.sh: FRAMES must be a number of at least 2 (flicker compares frames), not '$FRAMES'" >&2; exit 2; }
case "$MOTION" in turn|orbit) ;; *) echo "turntable.sh: MOTION is turn or orbit, not '$MOTION'" >&2; exit 2 ;; esac
REPO=$(cd "$(dirname "$0")/../.." && pwd)
S="$REPO/build/spangle"
# Frames of an earlier run into OUT would join the measurement and the GIF: start afresh.
rm -f "$OUT"/fixed/beetle.*.exr "$OUT"/fixed/beetle.*.png "$OUT"/reseeded/beetle.*.exr \
    "$OUT"/reseeded/beetle.*.png
mkdir -p "$OUT/fixed" "$OUT/reseeded"

# The beetle scene with absolute asset paths and its motion: keys at the first and last frame,
# linear in between (a constant speed).
sed "s#\"\.\./#\"$REPO/assets/#g" "$REPO/assets/scenes/beetle.toml" > "$OUT/turntable.toml"
python3 - "$OUT/turntable.toml" "$FRAMES" "$STEP" "$MOTION" <<'PY'
import math, re, sys
path, frames, step, motion = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
text = open(path).read()
last = frames if frames > 1 else 2
if motion == "orbit":
    cx, cz = 0.05, 0.0                     # look_at of beetle.toml
    px, py, pz = 4.3, 1.75, 3.6            # its camera position
    r, a0 = math.hypot(px - cx, pz - cz), math.atan2(pz - cz, px - cx)
    text += "\n"
    for k in range(frames):
        a = a0 + math.radians(step * k)
        text += f"\n[[camera.keys]]\nframe = {k + 1}\nposition = [{cx + r * math.cos(a):.6f}, {py}, {cz + r * math.sin(a):.6f}]\n"
else:
    # Every [[object]] whose mesh is part of the car turns about the vertical axis; its keys go
    # at the end of its table (before the next table header).
    blocks = re.split(r"(?m)^(?=\[)", text)
    out = []
    for b in blocks:
        if b.startswith("[[object]]") and "beetle_" in b:
            b = b.rstrip("\n") + (
                f'\ninterpolation = "linear"\n\n[[object.keys]]\nframe = 1\nrotate = [0, 0, 0]\n'
                f"\n[[object.keys]]\nframe = {last}\nrotate = [0, {step * (last - 1):.6f}, 0]\n\n")
        out.append(b)
    text = "".join(out)
open(path, "w").write(text)
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
# 12 frames per second, looping.
oiiotool "$OUT"/fixed/beetle.*.png --siappendall --attrib:type=rational FramesPerSecond 12/1 \
    -o "$OUT/turntable.gif"
if command -v ffmpeg > /dev/null; then
    for s in fixed reseeded; do
        ffmpeg -loglevel error -y -framerate 12 -i "$OUT/$s/beetle.%04d.png" -c:v libx264 \
            -vf "pad=ceil(iw/2)*2:ceil(ih/2)*2" -pix_fmt yuv420p -crf 18 "$OUT/turntable_$s.mp4"
    done
    echo "wrote $OUT/turntable_fixed.mp4 and $OUT/turntable_reseeded.mp4"
else
    echo "ffmpeg is not installed: no MP4 (apt-get install ffmpeg); $OUT/turntable.gif has the frames"
fi
