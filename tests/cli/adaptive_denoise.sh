#!/usr/bin/env bash
# Adaptive sampling, the denoiser and inspect from the command line: an adaptive render's crops
# merge into exactly the whole render (spp layer included); --spp-range with adaptive sampling,
# --denoise with --spp-range and a denoiser that cannot be opened are refused, writing nothing;
# --denoise keeps the noisy beauty as a layer; inspect reads every layer and tells glints from
# fireflies.
#   adaptive_denoise.sh SPANGLE REPO_DIR
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/err.txt" 2>/dev/null; exit 1; }
SCENE="$REPO/assets/scenes/demo.toml"
ARGS=(--size 90x50 --spp 64 --noise-threshold 0.05 --min-spp 8 -q --no-preview --float)

# A min_spp that, rounded up, reaches the most a pixel takes leaves nothing to adapt: said (the
# header said adaptive over an image of fixed samples, without a word).
"$S" render "$SCENE" -o "$T/flat.exr" --size 16x16 --spp 10 --min-spp 9 --noise-threshold 0.05 \
    -q --no-preview 2> "$T/err.txt" || fail "adaptive render with min_spp at spp"
grep -q "adaptive sampling has nothing to adapt" "$T/err.txt" || fail "not said"

"$S" render "$SCENE" -o "$T/whole.exr" "${ARGS[@]}" 2> "$T/err.txt" || fail "adaptive render"
oiiotool --info -v "$T/whole.exr" | grep -q "channel list: R, G, B, spp" || fail "no spp layer"
"$S" render "$SCENE" -o "$T/left.exr" "${ARGS[@]}" --crop 0,0,37,50 2> "$T/err.txt" || fail "left crop"
"$S" render "$SCENE" -o "$T/right.exr" "${ARGS[@]}" --crop 37,0,90,50 2> "$T/err.txt" || fail "right crop"
"$S" merge "$T/left.exr" "$T/right.exr" -o "$T/merged.exr" > /dev/null 2> "$T/err.txt" || fail "merge"
oiiotool "$T/whole.exr" "$T/merged.exr" --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
    { cat "$T/diff.txt"; fail "the merged adaptive crops differ from the whole render"; }

# A part of other adaptive settings is a part of another render: refused (it merged into a
# quilt of two thresholds).
"$S" render "$SCENE" -o "$T/other.exr" "${ARGS[@]/0.05/0.5}" --crop 37,0,90,50 2> "$T/err.txt" || fail "other crop"
"$S" merge "$T/left.exr" "$T/other.exr" -o "$T/quilt.exr" > /dev/null 2> "$T/err.txt" &&
    fail "crops of different noise thresholds merged"
grep -q "sampled 'adaptive 0.5 min_spp 8 max_spp 64'" "$T/err.txt" || fail "no reason for refusing the quilt"
[ ! -e "$T/quilt.exr" ] || fail "a refused merge wrote its output"

# A scene whose [render] asks for adaptive sampling, split by --spp-range: refused once read.
sed -e "s#\"\.\./\.\./#\"$REPO/#g" -e 's/^seed = 3/seed = 3\nnoise_threshold = 0.05/' \
    "$REPO/tests/scenes/small_lit.toml" > "$T/adaptive.toml"
grep -q "^noise_threshold" "$T/adaptive.toml" || fail "the adaptive scene was not made"
"$S" render "$T/adaptive.toml" -o "$T/range.exr" --spp-range 0..4 -q 2> "$T/err.txt"
[ $? -eq 1 ] || fail "an adaptive render split by --spp-range was not refused: $(cat "$T/err.txt")"
grep -q "adaptive.toml:[0-9]*:[0-9]*: error: --spp-range cannot split this scene's adaptive render" "$T/err.txt" ||
    fail "the refusal of --spp-range is not said at the scene's noise_threshold"
[ ! -e "$T/range.exr" ] || fail "an output was written for a refused sample range"
# The same clash between two options is a usage error (2), found before the scene is read.
"$S" render "$SCENE" -o "$T/range.exr" --noise-threshold 0.1 --spp-range 0..2 2> "$T/err.txt"
[ $? -eq 2 ] || fail "--noise-threshold with --spp-range is not a usage error"
grep -q "cannot split an adaptive render" "$T/err.txt" || fail "no reason for refusing --spp-range"
"$S" render "$SCENE" -o "$T/dr.exr" --spp 4 --denoise --spp-range 0..2 2> "$T/err.txt"
[ $? -eq 2 ] || fail "--denoise with --spp-range is not a usage error"
SPANGLE_OIDN="$T/nowhere.so" "$S" render "$SCENE" -o "$T/nolib.exr" --size 90x50 --spp 2 -q \
    --denoise 2> "$T/err.txt"
[ $? -eq 1 ] || fail "a denoiser that cannot be opened did not fail the render"
grep -q "Open Image Denoise 2 could not be opened" "$T/err.txt" || fail "no reason for the denoiser"
[ ! -e "$T/nolib.exr" ] || fail "an output was written without its denoiser"

"$S" render "$SCENE" -o "$T/layers.exr" --size 90x50 --spp 4 -q --no-preview --layers 2> "$T/err.txt" || fail "layers render"
"$S" inspect "$T/layers.exr" --against "$T/whole.exr" > "$T/out.txt" 2> "$T/err.txt" || fail "inspect"
grep -q "^glints (> 10x the 3x3 median" "$T/out.txt" || fail "inspect did not tell glints apart: $(cat "$T/out.txt")"
grep -q "^  glints.R  *min " "$T/out.txt" || fail "inspect did not print the layers: $(cat "$T/out.txt")"
grep -q "^relMSE against " "$T/out.txt" || fail "inspect did not compare: $(cat "$T/out.txt")"
# plain.exr keeps the sky in RGB, layers.exr (the same samples) in its background layer: the
# comparison takes RGB plus background for the layered one, says so, and finds them equal (RGB
# alone measured the sky: a denoised render read relMSE 0.15 against its plain reference).
"$S" render "$SCENE" -o "$T/plain.exr" --size 90x50 --spp 4 -q --no-preview --float 2> "$T/err.txt" || fail "plain render"
"$S" render "$SCENE" -o "$T/layersf.exr" --size 90x50 --spp 4 -q --no-preview --layers --float 2> "$T/err.txt" || fail "layers render"
for pair in "layersf.exr plain.exr" "plain.exr layersf.exr"; do
    set -- $pair
    "$S" inspect "$T/$1" --against "$T/$2" > "$T/out.txt" 2> "$T/err.txt" || fail "inspect $pair"
    grep -q "^compared: '$T/layersf.exr' as its RGB plus its 'background' layer" "$T/out.txt" ||
        fail "inspect --against did not say how it took the sky ($pair): $(cat "$T/out.txt")"
    sed -n 's/^relMSE against .*: //p' "$T/out.txt" |
        awk '{found = 1; if (!($1 ~ /^[0-9][0-9.e+-]*$/) || $1 + 0 > 1e-9) bad = 1} END {exit !(found && !bad)}' ||
        fail "a layered render and its plain twin differ ($pair): $(grep relMSE "$T/out.txt")"
done
"$S" inspect "$T/layers.exr" --against "$T/layers.exr" > "$T/out.txt" 2> "$T/err.txt" || fail "inspect"
[ ! -s "$T/err.txt" ] || fail "inspect --against of renders made alike warned: $(cat "$T/err.txt")"

# The denoiser itself, where the install script put it in place.
if [ -f /opt/spangle/oidn/lib/libOpenImageDenoise.so.2 ] || [ -n "${SPANGLE_OIDN:-}" ]; then
    "$S" render "$SCENE" -o "$T/dn.exr" --size 90x50 --spp 4 -q --no-preview --denoise 2> "$T/err.txt" || fail "denoise"
    oiiotool --info -v "$T/dn.exr" | grep -q "noisy.R" || fail "the noisy beauty is not a layer"
    # As with --layers the sky is a layer of its own, and pixels no camera ray covered (A 0)
    # stay 0 (the sky was in RGB where A said 0; the denoiser spread light into them).
    oiiotool --info -v "$T/dn.exr" | grep -q "background.R" || fail "--denoise has no background layer"
    A0=$(oiiotool "$T/dn.exr" --ch A --colorcount:eps=0 0 | awk 'NF {n = $1} END {print n}')
    RGBA0=$(oiiotool "$T/dn.exr" --ch R,G,B,A --colorcount:eps=0,0,0,0 "0,0,0,0" | awk 'NF {n = $1} END {print n}')
    [ "${A0:-0}" -gt 0 ] && [ "$A0" = "$RGBA0" ] ||
        fail "pixels with A 0 are not black after denoising ($A0 with A 0, $RGBA0 all 0)"
    # Every mode denoises its final image: each frame of --frames, and --watch's finished image.
    "$S" render "$SCENE" -o "$T/seq.#.exr" --size 90x50 --spp 4 -q --no-preview --denoise \
        --frames 1..2 2> "$T/err.txt" || fail "denoised frames"
    for f in 1 2; do
        oiiotool --info -v "$T/seq.$f.exr" | grep -q "noisy.R" || fail "frame $f was not denoised"
    done
    "$S" render "$SCENE" -o "$T/w.exr" --size 90x50 --spp 4 --no-preview --denoise --watch \
        > "$T/watch.txt" 2>&1 &
    PID=$!
    for _ in $(seq 1 300); do grep -q "watching for changes" "$T/watch.txt" && break; sleep 0.1; done
    kill -INT $PID; wait $PID
    oiiotool --info -v "$T/w.exr" | grep -q "noisy.R" || fail "--watch did not denoise its finished image"
    # Denoised parts do not add up to the denoised whole (a seam): merge refuses them.
    "$S" render "$SCENE" -o "$T/dl.exr" --size 90x50 --spp 4 -q --no-preview --denoise --crop 0,0,45,50 2> "$T/err.txt" || fail "denoised crop"
    "$S" render "$SCENE" -o "$T/dr2.exr" --size 90x50 --spp 4 -q --no-preview --denoise --crop 45,0,90,50 2> "$T/err.txt" || fail "denoised crop"
    "$S" merge "$T/dl.exr" "$T/dr2.exr" -o "$T/dm.exr" > /dev/null 2> "$T/err.txt" && fail "denoised crops merged"
    grep -q "was denoised (--denoise)" "$T/err.txt" || fail "no reason for refusing denoised parts"
    # An image too small for the network is written as rendered, said.
    "$S" render "$SCENE" -o "$T/tiny.exr" --size 4x4 --spp 2 -q --no-preview --denoise 2> "$T/err.txt" || fail "tiny denoise"
    grep -q "too small to denoise" "$T/err.txt" || fail "a 4x4 denoise was not said to be skipped"
fi
# The layers --denoise writes refuse a lossy compression as --layers does.
"$S" render "$SCENE" -o "$T/lossy.exr" --size 90x50 --spp 2 -q --denoise --compression pxr24 2> "$T/err.txt"
[ $? -eq 2 ] || fail "--denoise with a lossy compression is not a usage error"
echo PASS
