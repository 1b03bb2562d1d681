#!/usr/bin/env bash
# `spangle inspect` as a farm's quality check: it says how an image was rendered (partial, the
# samples per pixel, a sample range), measures an AOV-only EXR by its channels (it refused it),
# reads another file's 32-bit integer channels, decodes a PNG's sRGB before measuring (it took
# encoded values for linear), leaves NaN pixels out of a relMSE (it printed nan), and counts the
# glints of a reference (or of two: two seeds) that an image keeps.
#   inspect_files.sh SPANGLE PLUGIN_DIR SCENE_DIR
set -u
S=$1 PLUGINS=$2 SCENES=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
cp "$SCENES/flake_uvless.toml" "$SCENES/uvless_ball.obj" "$T/"
cd "$T"
fail() { echo "FAIL: $*"; exit 1; }
"$S" render flake_uvless.toml -o part.exr --size 48x32 --spp 16 --spp-range 0..8 -q --threads 2 \
    --plugin-path "$PLUGINS" || fail "render"
"$S" inspect part.exr > out.txt || fail "inspect part.exr: $(cat out.txt)"
grep -q "^render: 8 samples per pixel" out.txt || fail "no samples per pixel: $(cat out.txt)"
grep -q "^render: samples 0..8 of a frame of 16" out.txt || fail "no sample range: $(cat out.txt)"
"$S" render flake_uvless.toml -o whole.exr --size 48x32 --spp 4 -q --threads 2 \
    --plugin-path "$PLUGINS" || fail "render"
oiiotool whole.exr --ch R,G,B --chnames diffuse.R,diffuse.G,diffuse.B -o aov.exr
"$S" inspect aov.exr > out.txt || fail "inspect aov.exr refused: $(cat out.txt)"
grep -q "no R, G and B channels (nor Y): its channels alone" out.txt || fail "$(cat out.txt)"
grep -q "diffuse.G .*mean" out.txt || fail "AOV channel not measured: $(cat out.txt)"
oiiotool --pattern constant:color=0.5,0.5,0.5 8x8 3 -d uint32 -o ints.exr
"$S" inspect ints.exr > out.txt || fail "integer EXR: $(cat out.txt)"
grep -q "^mean luminance" out.txt || fail "integer EXR not measured: $(cat out.txt)"
# A PNG of sRGB 0.5 (188/255 is 0.5 in linear) measures about 0.5, not 0.74.
oiiotool --pattern constant:color=0.5,0.5,0.5 8x8 3 --tocolorspace sRGB -d uint8 -o half.png
"$S" inspect half.png > out.txt || fail "PNG: $(cat out.txt)"
grep -q "sRGB-encoded, decoded to linear" out.txt || fail "PNG not decoded: $(cat out.txt)"
python3 - out.txt <<'PY' || fail "PNG mean: $(cat out.txt)"
import re, sys
m = float(re.search(r"mean luminance: ([0-9.e+-]+)", open(sys.argv[1]).read()).group(1))
sys.exit(0 if abs(m - 0.5) < 0.01 else 1)
PY
# NaN pixels are left out of a relMSE (and counted), not made its value.
oiiotool --pattern constant:color=nan,nan,nan 4x4 3 whole.exr --ch R,G,B --paste +0+0 -o nan.exr
"$S" inspect nan.exr --against whole.exr > out.txt 2>&1 || fail "NaN: $(cat out.txt)"
grep -q "relMSE against whole.exr: [0-9].*16 left out" out.txt || fail "NaN relMSE: $(cat out.txt)"
# An image of no finite pixel has no mean (it read 0).
oiiotool --pattern constant:color=nan,nan,nan 4x4 3 -o allnan.exr
"$S" inspect allnan.exr > out.txt 2>&1 || fail "all NaN: $(cat out.txt)"
grep -q "^mean luminance: none (no pixel is finite)$" out.txt || fail "all-NaN mean: $(cat out.txt)"
"$S" inspect allnan.exr --against allnan.exr > out.txt 2>&1 && fail "a comparison of no pixel passed: $(cat out.txt)"
grep -q "no pixel finite in both" out.txt || fail "an empty comparison not said: $(cat out.txt)"
# A layered render keeps the sky seen directly in its 'background' layer: inspect measures RGB
# plus that layer, the whole picture, as the same render without layers holds it (RGB alone left
# the sky out of the mean and made fireflies of the faint pixels at the horizon).
"$S" render "$SCENES/small_lit.toml" -o plain.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --plugin-path "$PLUGINS" || fail "render"
"$S" render "$SCENES/small_lit.toml" -o layered.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --layers --plugin-path "$PLUGINS" || fail "render --layers"
"$S" inspect plain.exr > plain.txt || fail "inspect plain.exr"
"$S" inspect layered.exr > layered.txt || fail "inspect layered.exr"
grep -q "^measured: RGB plus its 'background' layer" layered.txt || fail "no word of the sky: $(cat layered.txt)"
[ "$(grep '^mean luminance' plain.txt | cut -c1-22)" = "$(grep '^mean luminance' layered.txt | cut -c1-22)" ] ||
    fail "the layered render's mean is not the plain one's: $(grep '^mean' plain.txt layered.txt)"
# A crop against the whole frame is compared over the crop's window (it was refused for its
# size); against a crop of another place it is refused (compared pixel by pixel before).
"$S" render "$SCENES/small_lit.toml" -o crop.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --crop 20,8,44,30 --plugin-path "$PLUGINS" || fail "crop render"
"$S" render "$SCENES/small_lit.toml" -o crop0.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --crop 0,0,24,22 --plugin-path "$PLUGINS" || fail "crop render"
"$S" inspect crop.exr --against plain.exr > out.txt 2>&1 || fail "crop against the whole: $(cat out.txt)"
grep -q "^compared: pixels (20, 8) to (44, 30) of a 48x32 frame of the reference" out.txt ||
    fail "the crop's window was not said: $(cat out.txt)"
grep -q "^relMSE against plain.exr: 0$" out.txt || fail "a crop differs from its window of the whole: $(grep relMSE out.txt)"
"$S" inspect crop.exr --against crop0.exr > out.txt 2>&1 && fail "crops of two places were compared"
grep -q "the reference must hold the image's pixels" out.txt || fail "no reason for crops of two places: $(cat out.txt)"
# Renders of one scene in two working spaces are refused, not compared value by value (relMSE
# 0.019 where converted they match).
sed "s|\.\./\.\./assets/|$SCENES/../../assets/|" "$SCENES/small_lit.toml" > lit.toml
sed -i 's/^\[render\]/[render]\nworking_space = "lin_rec709"/' lit.toml
"$S" render lit.toml -o rec709.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --plugin-path "$PLUGINS" || fail "rec709 render"
sed -i 's/^working_space = "lin_rec709"/working_space = "ACEScg"/' lit.toml
"$S" render lit.toml -o acescg.exr --size 48x32 --spp 4 -q --threads 2 --float \
    --plugin-path "$PLUGINS" || fail "ACEScg render"
"$S" inspect rec709.exr --against acescg.exr > out.txt 2>&1 && fail "two working spaces were compared"
grep -q "are in different colour spaces ('lin_rec709': primaries" out.txt ||
    fail "no reason for two working spaces: $(cat out.txt)"
"$S" inspect acescg.exr --against acescg.exr > out.txt 2>&1 || fail "one space refused: $(cat out.txt)"
# Glints kept: a reference with three sparkles in its glints layer (1 on 0.1 around them), an
# image that lost one, and a crop window holding one of them.
G="--fill:color=1,1,1,1,0.9,0.9,0.9"
oiiotool --pattern constant:color=0.1,0.1,0.1,1,0.02,0.02,0.02 24x16 7 \
    --chnames R,G,B,A,glints.R,glints.G,glints.B -d float $G 1x1+5+5 $G 1x1+12+8 $G 1x1+19+11 \
    -o gref.exr || fail "the glint reference was not made"
oiiotool gref.exr --fill:color=0.1,0.1,0.1,1,0.02,0.02,0.02 1x1+12+8 -o glost.exr ||
    fail "the image without a glint was not made"
oiiotool gref.exr --crop 12x10+6+3 -o gcrop.exr || fail "the crop was not made"
"$S" inspect gref.exr --against gref.exr > out.txt 2>&1 || fail "glints: $(cat out.txt)"
grep -q "^glints of the reference (as \`spangle flicker\` finds them): 3; 3 measured" out.txt ||
    fail "the reference's glints were not found: $(cat out.txt)"
grep -q "^glints kept (.*): 3 of 3 (100.0%), median contrast 1.00" out.txt ||
    fail "an image did not keep its own glints: $(cat out.txt)"
"$S" inspect glost.exr --against gref.exr > out.txt 2>&1 || fail "glints: $(cat out.txt)"
grep -q "^glints kept (.*): 2 of 3 (66.7%)" out.txt || fail "a lost glint was kept: $(cat out.txt)"
"$S" inspect gcrop.exr --against gref.exr > out.txt 2>&1 || fail "glints: $(cat out.txt)"
grep -q "^glints kept (.*): 1 of 1 (100.0%)" out.txt || fail "a crop's glints: $(cat out.txt)"
# Two references (two seeds of one frame): the image against their mean, on the glints both find.
# The second lacks the sparkle at 19,11, has one at 3,12 that the first lacks, and its sparkle at
# 5,5 is dimmer in RGB: two are measured, the image lost one of them, and the first reference
# keeps both of the second's where the second keeps one of the first's.
B="--fill:color=0.1,0.1,0.1,1,0.02,0.02,0.02"
oiiotool gref.exr $B 1x1+19+11 $G 1x1+3+12 --fill:color=0.3,0.3,0.3,1,0.9,0.9,0.9 1x1+5+5 \
    -o gref2.exr || fail "the second reference was not made"
"$S" inspect glost.exr --against gref.exr --against gref2.exr > out.txt 2>&1 ||
    fail "two references: $(cat out.txt)"
grep -q "^relMSE against the mean of gref.exr and gref2.exr: " out.txt ||
    fail "the mean of two references was not compared: $(cat out.txt)"
grep -q "^the references against each other: relMSE [0-9]" out.txt ||
    fail "the references' own difference was not said: $(cat out.txt)"
grep -q "^glints of the reference (as \`spangle flicker\` finds them, in both references): 2; 2 measured" out.txt ||
    fail "the glints of both references were not those found in both: $(cat out.txt)"
grep -q "^glints kept (.*): 1 of 2 (50.0%)" out.txt || fail "two references, a lost glint: $(cat out.txt)"
grep -q "^the references on these glints (.*): 'gref.exr' against 'gref2.exr' keeps 2 of 2 (100.0%), 'gref2.exr' against 'gref.exr' keeps 1 of 2 (50.0%)$" out.txt ||
    fail "how the references agree: $(cat out.txt)"
# The mean is theirs: an image that is it matches it exactly.
oiiotool gref.exr gref2.exr --add --mulc 0.5 -o gmean.exr || fail "the mean was not made"
"$S" inspect gmean.exr --against gref.exr --against gref2.exr > out.txt 2>&1 || fail "the mean: $(cat out.txt)"
grep -q "^relMSE against the mean of gref.exr and gref2.exr: 0$" out.txt ||
    fail "the mean of the references is not what was compared: $(cat out.txt)"
# A crop against both (their window of it), and a second reference without glint layers.
"$S" inspect gcrop.exr --against gref.exr --against gref2.exr > out.txt 2>&1 || fail "a crop, two references: $(cat out.txt)"
grep -q "^glints kept (.*): 1 of 1 (100.0%)" out.txt || fail "a crop's glints, two references: $(cat out.txt)"
oiiotool gref2.exr --ch R,G,B,A -o grgba.exr || fail "the reference without glints was not made"
"$S" inspect glost.exr --against gref.exr --against grgba.exr > out.txt 2>&1 || fail "glints: $(cat out.txt)"
grep -q "^glints kept: not measured ('grgba.exr' lacks glints.R, G, B or A" out.txt ||
    fail "a second reference without glints was not said: $(cat out.txt)"
"$S" inspect glost.exr --against gref.exr --against gcrop.exr > out.txt 2>&1 &&
    fail "references of two windows were taken: $(cat out.txt)"
grep -q "hold different pixels" out.txt || fail "no reason for references of two windows: $(cat out.txt)"
"$S" inspect glost.exr --against gref.exr --against gref2.exr --against gref.exr > out.txt 2>&1 &&
    fail "three references were taken: $(cat out.txt)"
grep -q "takes one reference, or two renders of it" out.txt || fail "no reason for three references: $(cat out.txt)"
oiiotool gref.exr --ch R,G,B -o grgb.exr || fail "the reference without layers was not made"
"$S" inspect gref.exr --against grgb.exr > out.txt 2>&1 || fail "glints: $(cat out.txt)"
grep -q "^glints kept: not measured ('grgb.exr' lacks glints.R, G, B or A" out.txt ||
    fail "a reference without glints was not said: $(cat out.txt)"
# A folder is not an image.
"$S" inspect . > out.txt 2>&1 && fail "inspect of a folder succeeded"
grep -q "is a folder, not an image" out.txt || fail "no reason for the folder: $(cat out.txt)"
echo ok
