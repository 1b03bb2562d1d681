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

# A window outside --size is a bad command line (exit 2); outside the size the scene sets, a
# problem with the input said at the scene's width (exit 1).
"$S" render "$SCENE" -o "$T/bad.exr" "${ARGS[@]}" --crop 80,0,100,10 2> "$T/err.txt"; rc=$?
[ $rc -eq 2 ] || fail "a crop outside --size exited $rc, not 2"
grep -q "crop 80,0,100,10 is not inside --size 90x50" "$T/err.txt" || fail "no reason for the bad crop"
[ ! -e "$T/bad.exr" ] || fail "an output was written for a bad crop"
"$S" render "$SCENE" -o "$T/bad.exr" --spp 1 -q --crop 600,0,700,10 2> "$T/err.txt"; rc=$?
[ $rc -eq 1 ] || fail "a crop outside the scene's image exited $rc, not 1"
grep -q "demo.toml:7:[0-9]*: error: --crop 600,0,700,10 is not inside the scene's 640x360 image" "$T/err.txt" ||
    fail "the crop outside the scene's image is not said at its width"
[ ! -e "$T/bad.exr" ] || fail "an output was written for a crop outside the scene's image"
"$S" render "$SCENE" -o "$T/bad.exr" --crop 5,5,5,9 2> "$T/err.txt"; [ $? -eq 2 ] || fail "an empty crop is not a usage error"
"$S" merge "$T/left.exr" -o "$T/holes.exr" 2> "$T/err.txt" && fail "a frame with a hole was merged"
grep -q "uncovered" "$T/err.txt" || fail "no reason for the hole"
[ ! -e "$T/holes.exr" ] || fail "a partial merge was written"
echo PASS

# --spp-range parts of a crop window (half floats): their sums add up to the window's whole render.
"$S" render "$SCENE" -o "$T/win.exr" --size 90x50 --spp 6 -q --no-preview --crop 10,5,70,45 2> "$T/err.txt" || fail "window render"
"$S" render "$SCENE" -o "$T/s1.exr" --size 90x50 --spp 6 -q --no-preview --crop 10,5,70,45 --spp-range 2..6 2> "$T/err.txt" || fail "samples 2..6"
"$S" render "$SCENE" -o "$T/s0.exr" --size 90x50 --spp 6 -q --no-preview --crop 10,5,70,45 --spp-range 0..2 2> "$T/err.txt" || fail "samples 0..2"
"$S" merge "$T/s1.exr" "$T/s0.exr" -o "$T/smerged.exr" > "$T/out.txt" 2> "$T/err.txt" || fail "sample-range merge"
grep -q "added 2 sample ranges into .*smerged.exr (90x50 frame)" "$T/out.txt" || fail "merge did not report: $(cat "$T/out.txt")"
oiiotool "$T/win.exr" "$T/smerged.exr" --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
    { cat "$T/diff.txt"; fail "the merged sample ranges differ from the whole render"; }
"$S" merge "$T/s1.exr" -o "$T/short.exr" 2> "$T/err.txt" && fail "a merge missing samples 0..2 was written"
grep -q "samples 0..2 of the frame's 6 are in no part (render them with --spp-range 0..2)" "$T/err.txt" || fail "no reason for the missing samples"
[ ! -e "$T/short.exr" ] || fail "a merge missing samples was written"
"$S" render "$SCENE" -o "$T/bad.exr" --spp 6 --spp-range 4..9 2> "$T/err.txt"; rc=$?
[ $rc -eq 2 ] || fail "a range beyond --spp exited $rc, not 2"
grep -q "spp-range 4..9 is not inside --spp 6" "$T/err.txt" || fail "no reason for the bad range"
"$S" render "$SCENE" -o "$T/bad.exr" --size 90x50 --spp-range 4..40 2> "$T/err.txt"; rc=$?
[ $rc -eq 1 ] || fail "a range beyond the scene's spp exited $rc, not 1"
grep -q "demo.toml:9:[0-9]*: error: --spp-range 4..40 is not inside the scene's 32 samples per pixel" "$T/err.txt" ||
    fail "the range beyond the scene's spp is not said at its spp"
[ ! -e "$T/bad.exr" ] || fail "an output was written for a bad range"
"$S" render "$SCENE" -o "$T/bad.exr" --spp-range 4..4 2> "$T/err.txt"; [ $? -eq 2 ] || fail "an empty range is not a usage error"
# Parts of another estimator (--strategy) have other noise in every pixel: refused.
"$S" render "$SCENE" -o "$T/nee.exr" --size 90x50 --spp 6 -q --no-preview --crop 10,5,70,45 --spp-range 2..6 --strategy nee 2> "$T/err.txt" || fail "samples 2..6, nee"
"$S" merge "$T/s0.exr" "$T/nee.exr" -o "$T/mixed.exr" 2> "$T/err.txt" && fail "parts of MIS and NEE merged"
grep -q "was rendered with --strategy nee, .* with mis" "$T/err.txt" || fail "the differing strategy is not named"
[ ! -e "$T/mixed.exr" ] || fail "parts of different estimators were merged"
# A pass image (--pass-output) of a range render holds samples of its range, without the sums:
# it says so and merge refuses it (it read as a render of the frame's first samples).
"$S" render "$SCENE" -o "$T/pass.exr" --size 90x50 --spp 65536 --no-preview --pass-output --spp-range 32..65536 > /dev/null 2> "$T/err.txt" &
job=$!
for _ in $(seq 1 400); do [ -e "$T/pass.exr" ] && break; sleep 0.05; done
kill -9 "$job" 2> /dev/null; wait "$job" 2> /dev/null
[ -e "$T/pass.exr" ] || fail "no pass image in 20 s"
iinfo -v "$T/pass.exr" | grep -Eq 'spangle:spp_range: "32\.\.[0-9]+"' ||
    fail "a range render's pass image does not name its samples: $(iinfo -v "$T/pass.exr" | grep spangle)"
"$S" merge "$T/pass.exr" -o "$T/passm.exr" 2> "$T/err.txt" && fail "a pass image of a range render was merged"
grep -q "lacks the exact sums .*a pass image (--pass-output) of a --spp-range render" "$T/err.txt" || fail "no reason for refusing the pass image"
# Overlapping crops written with a lossy compression differ where they overlap (each part's
# DCT blocks start at its own corner: 0 and 37 are not on one 8-pixel grid): the refusal names
# the compression. A part holding NaN (changed by another program) is merged and said.
"$S" render "$SCENE" -o "$T/l0.exr" --size 90x50 --spp 2 -q --no-preview --crop 0,0,50,50 --compression dwaa 2> "$T/err.txt" || fail "dwaa crop"
"$S" render "$SCENE" -o "$T/l1.exr" --size 90x50 --spp 2 -q --no-preview --crop 37,3,90,50 --compression dwaa 2> "$T/err.txt" || fail "dwaa crop"
"$S" merge "$T/l0.exr" "$T/l1.exr" -o "$T/lm.exr" 2> "$T/err.txt" && fail "lossy crops that differ where they overlap were merged"
grep -q "lossy compression (dwaa)" "$T/err.txt" || fail "the lossy compression was not named"
"$S" render "$SCENE" -o "$T/h0.exr" --size 90x50 --spp 2 -q --no-preview --crop 0,0,45,50 2> "$T/err.txt" || fail "crop"
"$S" render "$SCENE" -o "$T/h1.exr" --size 90x50 --spp 2 -q --no-preview --crop 45,0,90,50 2> "$T/err.txt" || fail "crop"
oiiotool "$T/h1.exr" --subc 5 --powc 0.5 -o "$T/h1nan.exr"
"$S" merge "$T/h0.exr" "$T/h1nan.exr" -o "$T/hm.exr" > /dev/null 2> "$T/err.txt" || fail "merge of a part with NaN"
grep -q "values of R, G and B in .*hm.exr are NaN" "$T/err.txt" || fail "NaN in a part was not said"
# Parts of other renders that the scene's files do not tell apart: another --camera at the same
# place with another lens (a glTF of two cameras), --env naming the map the scene already reads
# (its intensity and rotation dropped), and a part whose header another tool dropped.
python3 - "$T/two.gltf" <<'PY'
import base64, json, struct, sys
b = b"".join(struct.pack("<3f", *p) for p in [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
b += struct.pack("<6H", 0, 1, 2, 0, 2, 3)
json.dump({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
           "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 3]},
                     {"camera": 1, "translation": [0, 0, 3]}],
           "cameras": [{"name": "wide", "type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.01}},
                       {"name": "tele", "type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
           "buffers": [{"uri": "data:application/octet-stream;base64," + base64.b64encode(b).decode(),
                        "byteLength": len(b)}],
           "bufferViews": [{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [-1, -1, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]},
          open(sys.argv[1], "w"))
PY
G=(--size 40x24 --spp 2 -q --no-preview)
"$S" render "$T/two.gltf" -o "$T/wa.exr" "${G[@]}" --camera wide --crop 0,0,20,24 2> "$T/err.txt" || fail "wide crop"
"$S" render "$T/two.gltf" -o "$T/tb.exr" "${G[@]}" --camera tele --crop 20,0,40,24 2> "$T/err.txt" || fail "tele crop"
"$S" merge "$T/wa.exr" "$T/tb.exr" -o "$T/wt.exr" 2> "$T/err.txt" && fail "parts of two cameras at one place were merged"
grep -q "different cameras" "$T/err.txt" || fail "no reason for refusing parts of two cameras"
# --camera naming the camera the file looks through anyway (its first) is the same render as none.
"$S" render "$T/two.gltf" -o "$T/wb.exr" "${G[@]}" --crop 20,0,40,24 2> "$T/err.txt" || fail "crop without --camera"
"$S" merge "$T/wa.exr" "$T/wb.exr" -o "$T/ww.exr" 2> "$T/err.txt" || fail "--camera wide and no --camera (wide) were refused: $(cat "$T/err.txt")"
"$S" render "$T/two.gltf" -o "$T/wwhole.exr" "${G[@]}" 2> "$T/err.txt" || fail "whole render of two.gltf"
oiiotool "$T/ww.exr" "$T/wwhole.exr" --diff --fail 0 --failpercent 0 > /dev/null || fail "the merged --camera wide and default parts differ from the whole"
MAP="$REPO/assets/env/studio_hdri.exr"  # the map beetle.toml (which demo.toml imports) reads
grep -q '^map = "../env/studio_hdri.exr"' "$REPO/assets/scenes/beetle.toml" || fail "the beetle no longer reads $MAP"
"$S" render "$SCENE" -o "$T/e0.exr" --size 90x50 --spp 2 -q --no-preview --crop 0,0,45,50 2> "$T/err.txt" || fail "crop"
"$S" render "$SCENE" -o "$T/e1.exr" --size 90x50 --spp 2 -q --no-preview --crop 45,0,90,50 --env "$MAP" 2> "$T/err.txt" || fail "crop with --env"
"$S" merge "$T/e0.exr" "$T/e1.exr" -o "$T/em.exr" 2> "$T/err.txt" && fail "a part with --env (the scene's own map) was merged"
grep -q "another --camera or --env" "$T/err.txt" || fail "no reason for refusing the --env part"
oiiotool "$T/e0.exr" --eraseattrib "spangle:sceneHash" -o "$T/e0bare.exr"
"$S" render "$SCENE" -o "$T/e2.exr" --size 90x50 --spp 2 -q --no-preview --crop 45,0,90,50 2> "$T/err.txt" || fail "crop"
"$S" merge "$T/e0bare.exr" "$T/e2.exr" -o "$T/em.exr" 2> "$T/err.txt" && fail "a part without spangle:sceneHash was merged unchecked"
grep -q "has no 'spangle:sceneHash' in its header" "$T/err.txt" || fail "no reason for refusing the stripped part"
"$S" merge "$T/e0.exr" "$T/e2.exr" -o "$T/em.exr" 2> "$T/err.txt" || fail "parts of one render were refused"
# A part without a render time: the merged frame's time is unknown, not the first part's.
oiiotool "$T/e2.exr" --eraseattrib renderTimeSeconds -o "$T/e2untimed.exr"
"$S" merge "$T/e0.exr" "$T/e2untimed.exr" -o "$T/eu.exr" 2> "$T/err.txt" || fail "merge of an untimed part"
iinfo -v "$T/eu.exr" | grep -q renderTimeSeconds && fail "the merged frame claims the first part's render time"
echo "crop_merge: OK"
