#!/usr/bin/env bash
# spangle render --crop and spangle merge from the command line: two crop windows of the demo
# (half floats, layers) merge into exactly the whole render; bad crops and merges are refused
# with the reason, writing nothing.
#   crop_merge.sh SPANGLE REPO_DIR
set -u
S=$1 REPO=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; cat "$T/err.txt" 2>/dev/null; exit 1; }
SCENE="$REPO/assets/scenes/demo.toml"
ARGS=(--size 90x50 --spp 4 -q --layers --no-preview)

"$S" render "$SCENE" -o "$T/whole.exr" "${ARGS[@]}" 2> "$T/err.txt" || fail "whole render"
"$S" render "$SCENE" -o "$T/left.exr" "${ARGS[@]}" --crop 0,0,41,50 2> "$T/err.txt" || fail "left crop"
"$S" render "$SCENE" -o "$T/right.exr" "${ARGS[@]}" --crop 41,0,90,50 2> "$T/err.txt" || fail "right crop"
oiiotool --info -v "$T/left.exr" | grep -q "41 x   50" || fail "the left part is not 41x50"
oiiotool --info -v "$T/left.exr" | grep -q "full/display size: 90 x 50" || fail "the left part does not sit in a 90x50 frame"
"$S" merge "$T/left.exr" "$T/right.exr" -o "$T/merged.exr" > "$T/out.txt" 2> "$T/err.txt" || fail "merge"
grep -q "merged 2 parts into .*merged.exr (90x50)" "$T/out.txt" || fail "merge did not report: $(cat "$T/out.txt")"
oiiotool "$T/whole.exr" --ch R,G,B,A,Z,glints.R "$T/merged.exr" --ch R,G,B,A,Z,glints.R --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
    { cat "$T/diff.txt"; fail "the merged frame differs from the whole render"; }

"$S" render "$SCENE" -o "$T/bad.exr" "${ARGS[@]}" --crop 80,0,100,10 2> "$T/err.txt" && fail "a crop outside the image rendered"
grep -q "crop window 80,0,100,10 is not inside the 90x50 image" "$T/err.txt" || fail "no reason for the bad crop"
[ ! -e "$T/bad.exr" ] || fail "an output was written for a bad crop"
"$S" render "$SCENE" -o "$T/bad.exr" --crop 5,5,5,9 2> "$T/err.txt"; [ $? -eq 2 ] || fail "an empty crop is not a usage error"
"$S" merge "$T/left.exr" -o "$T/holes.exr" 2> "$T/err.txt" && fail "a frame with a hole was merged"
grep -q "uncovered" "$T/err.txt" || fail "no reason for the hole"
[ ! -e "$T/holes.exr" ] || fail "a partial merge was written"
echo PASS
