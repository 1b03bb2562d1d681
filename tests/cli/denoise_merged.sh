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
