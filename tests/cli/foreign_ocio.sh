#!/usr/bin/env bash
# A foreign OpenColorIO config in $OCIO (a DCC's, without Spangle's colour space names): scenes
# render, with the config's roles and common names standing in for Spangle's names, each stand-in
# warned about at its file:line; a space the config lacks is an error that says to unset $OCIO or
# pass --ocio. Before: every demo failed with "unknown colour space 'ACEScg'" at a line where no
# such key was written.
#   foreign_ocio.sh SPANGLE REPO_DIR
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/err.txt"; exit 1; }
export OCIO="$REPO/tests/ocio/foreign.ocio"

"$S" render "$REPO/tests/scenes/small_lit.toml" -o "$T/a.exr" -q 2> "$T/err.txt" || fail "small_lit did not render"
grep -q "small_lit.toml:3:1: default (no key written) colour space 'lin_rec709' is not in the OCIO config" "$T/err.txt" ||
    fail "no warning for the stand-in of the default colour space"
oiiotool --info -v "$T/a.exr" | grep -q 'colorSpace: "Linear Rec.709"' || fail "EXR not in the config's scene_linear space"
# No XYZ role to measure the working space through, but "Linear Rec.709" is lin_rec709 by name:
# the EXR still carries its chromaticities.
oiiotool --info -v "$T/a.exr" | grep -q 'chromaticities: 0.64, 0.33, 0.3, 0.6, 0.15, 0.06, 0.3127, 0.329' ||
    fail "no chromaticities derived for the foreign working space"
# A working space known by no name and no way to measure it: a clear warning, no attribute.
sed 's/Linear Rec.709/Studio Linear/g' "$OCIO" > "$T/odd.ocio"
OCIO="$T/odd.ocio" "$S" render "$REPO/tests/scenes/small_lit.toml" -o "$T/odd.exr" -q 2> "$T/err.txt" ||
    fail "small_lit did not render with an unknown working space"
grep -q "warning: the EXR carries no chromaticities attribute: the working space 'Studio Linear'" "$T/err.txt" ||
    fail "no warning about the missing chromaticities"
oiiotool --info -v "$T/odd.exr" | grep -q chromaticities && fail "chromaticities made up for an unknown space"

"$S" render "$REPO/assets/scenes/demo.toml" -o "$T/b.exr" --size 32x18 --spp 1 -q 2> "$T/err.txt" || fail "demo did not render"
grep -q "demo.toml:12:17: colour space 'ACEScg' is not in the OCIO config .*; using its scene_linear role, 'Linear Rec.709'" "$T/err.txt" ||
    fail "no warning for the ACEScg stand-in"
[ -s "$T/b.png" ] || fail "no preview through the foreign config's display"

printf '[render]\nwidth = 8\nheight = 8\ncolor_space = "ACES2065-1"\n[camera]\nposition = [0, 0, 4]\nlook_at = [0, 0, 0]\n' > "$T/aces.toml"
"$S" render "$T/aces.toml" -o "$T/c.exr" -q 2> "$T/err.txt" && fail "an unknown space rendered"
grep -q "aces.toml:4:15: error: unknown colour space 'ACES2065-1' (known: Linear Rec.709, sRGB, Non-Color); the OpenColorIO config comes from \$OCIO" "$T/err.txt" ||
    fail "the error does not locate the key or name \$OCIO"
grep -q "unset OCIO (or pass --ocio)" "$T/err.txt" || fail "the error does not say how to fix it"
[ ! -e "$T/c.exr" ] || fail "an output was written"

# --ocio wins over $OCIO: Spangle's own config, no stand-ins.
"$S" render "$REPO/assets/scenes/demo.toml" -o "$T/d.exr" --size 32x18 --spp 1 -q \
    --ocio "$REPO/assets/ocio/config.ocio" 2> "$T/err.txt" || fail "demo with --ocio did not render"
[ ! -s "$T/err.txt" ] || fail "warnings with Spangle's own config"

# A config whose view LUT is missing fails before rendering, with no output (the EXR was written
# after the whole render, then the PNG's transform failed).
mkdir "$T/lutless" && cp "$REPO/assets/ocio/config.ocio" "$T/lutless/"
"$S" render "$REPO/tests/scenes/small_lit.toml" -o "$T/e.exr" --ocio "$T/lutless/config.ocio" \
    2> "$T/err.txt" && fail "rendered without the view's LUT"
grep -q "sparkle_view.spi3d' could not be located" "$T/err.txt" || fail "no word of the LUT: $(cat "$T/err.txt")"
[ ! -e "$T/e.exr" ] || fail "an EXR was written though the preview could not be"
echo PASS
