#!/usr/bin/env bash
# `spangle denoise`: a frame merged from crop windows, denoised, equals the whole frame rendered
# with --denoise, bit for bit (crop parts cannot be denoised apart, and merge refuses denoised
# parts: there was no way to a denoised farm frame). A file without the guide layers, or one
# denoised already, is refused with what to do.
#   denoise_merged.sh SPANGLE SCENE
set -u
S=$1 SCENE=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
# Tiled parts (other tools write them) merge into a readable scanline file: the tiled part's
# header was copied whole, and the file said "tiles" over scanline data (exit status 0).
"$S" render "$SCENE" --size 48x32 --spp 2 --layers -q --no-preview --threads 2 --crop 0,0,20,32 \
    -o "$T/c1.exr" || fail "crop"
"$S" render "$SCENE" --size 48x32 --spp 2 --layers -q --no-preview --threads 2 --crop 20,0,48,32 \
    -o "$T/c2.exr" || fail "crop"
oiiotool "$T/c1.exr" --tile 16 16 -o "$T/t1.exr" && oiiotool "$T/c2.exr" --tile 16 16 -o "$T/t2.exr"
"$S" merge "$T/t1.exr" "$T/t2.exr" -o "$T/tiled_merge.exr" > /dev/null || fail "tiled merge"
"$S" inspect "$T/tiled_merge.exr" > /dev/null || fail "the merge of tiled parts is unreadable"
if ! { [ -f /opt/spangle/oidn/lib/libOpenImageDenoise.so.2 ] || [ -n "${SPANGLE_OIDN:-}" ]; }; then
    [ -n "${SPANGLE_REQUIRE_OIDN:-}" ] && fail "no Open Image Denoise, and SPANGLE_REQUIRE_OIDN is set"
    echo "ok (skipped: no Open Image Denoise here)"
    exit 0
fi
common=(--size 48x32 --spp 8 --layers --float -q --no-preview --threads 2)
"$S" render "$SCENE" "${common[@]}" --denoise -o "$T/whole.exr" || fail "whole render"
"$S" render "$SCENE" "${common[@]}" --crop 0,0,30,32 -o "$T/left.exr" || fail "left crop"
"$S" render "$SCENE" "${common[@]}" --crop 30,0,48,32 -o "$T/right.exr" || fail "right crop"
"$S" merge "$T/left.exr" "$T/right.exr" -o "$T/merged.exr" > /dev/null || fail "merge"
"$S" denoise "$T/merged.exr" -o "$T/denoised.exr" > "$T/out.txt" || fail "denoise: $(cat "$T/out.txt")"
oiiotool "$T/whole.exr" "$T/denoised.exr" --diff --fail 0 --warn 0 > "$T/diff.txt" 2>&1 ||
    fail "the merged frame denoised differs from the whole render denoised: $(tail -3 "$T/diff.txt")"
oiiotool --info -v "$T/denoised.exr" | grep -q 'spangle:denoised: "keep"' || fail "not marked"
# Half-float frames (render's default) and tiled ones denoise too (a half one failed with an
# OpenEXR frame-buffer error naming a hidden file; a tiled one was written unreadable).
"$S" denoise "$T/tiled_merge.exr" -o "$T/half_dn.exr" -q || fail "half denoise"
"$S" inspect "$T/half_dn.exr" | grep -q "denoised: keep" || fail "half denoise not marked"
oiiotool "$T/tiled_merge.exr" --tile 16 16 -o "$T/tiled.exr"
"$S" denoise "$T/tiled.exr" -o "$T/tiled_dn.exr" -q || fail "tiled denoise"
"$S" inspect "$T/tiled_dn.exr" > /dev/null || fail "the denoised tiled frame is unreadable"
"$S" denoise "$T/denoised.exr" -o "$T/again.exr" 2> "$T/err.txt" && fail "denoised twice"
grep -q "is denoised already" "$T/err.txt" || fail "$(cat "$T/err.txt")"
"$S" render "$SCENE" --size 48x32 --spp 2 -q --no-preview -o "$T/plain.exr" || fail "plain render"
"$S" denoise "$T/plain.exr" -o "$T/x.exr" 2> "$T/err.txt" && fail "denoised without guides"
grep -q "lacks the channels the denoiser is guided by .*with --layers" "$T/err.txt" ||
    fail "$(cat "$T/err.txt")"
[ -e "$T/x.exr" ] && fail "an output was written"
# A stop signal while denoising: the image as rendered, said, exit 130 (it was ignored until the
# denoise ended, then the image written as whole). A 1920x1080 denoise takes 10-15 s on two
# cores; the signal comes as its progress line shows (after its first second).
"$S" render "$SCENE" --size 1920x1080 --spp 1 --denoise --threads 2 --no-preview \
    -o "$T/stopped.exr" > /dev/null 2> "$T/err.txt" &
PID=$!
for _ in $(seq 1 600); do
    grep -q "denoising" "$T/err.txt" 2> /dev/null && break
    sleep 0.05
done
kill -INT $PID
wait $PID
RC=$?
grep -q "stopped by a signal (SIGINT) while denoising: wrote .* as rendered, not denoised" \
    "$T/err.txt" || fail "SIGINT while denoising not said: $(tr '\r' '\n' < "$T/err.txt" | tail -3)"
[ $RC -eq 130 ] || fail "SIGINT while denoising: exit $RC, expected 130"
oiiotool --info -v "$T/stopped.exr" | grep -q "noisy.R" && fail "stopped, yet denoised"
echo ok
