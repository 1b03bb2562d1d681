#!/usr/bin/env bash
# An EXR that cannot be written (a full disk; here a file-size limit) leaves the old EXR and PNG
# pair as it was: the new PNG preview, written beside the EXR on another thread, was renamed into
# place anyway, so the folder held a new preview beside an old image (or beside none).
#   output_pair.sh SPANGLE PLUGIN_DIR SCENE_DIR
set -u
S=$1 PLUGINS=$2 SCENES=$3
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
cp "$SCENES/flake_uvless.toml" "$SCENES/uvless_ball.obj" "$T/"
cd "$T"
fail() { echo "FAIL: $*"; exit 1; }
echo "old exr" > out.exr
echo "old png" > out.png
# 64 KiB per file: the PNG (about 40 KiB) fits, the float EXR with layers (over 1 MiB) does not.
( ulimit -f 64; "$S" render flake_uvless.toml -o out.exr --size 320x200 --spp 2 --float --layers \
    --threads 2 -q --plugin-path "$PLUGINS" 2> err.txt )
status=$?
[ "$status" = 1 ] || fail "exit $status, expected 1; stderr: $(cat err.txt)"
grep -q "cannot write 'out.exr'" err.txt || fail "no message: $(cat err.txt)"
[ "$(cat out.exr)" = "old exr" ] || fail "the old EXR changed"
[ "$(cat out.png)" = "old png" ] || fail "the PNG was replaced although the EXR was not written"
ls -a | grep -q '\.tmp' && fail "temporary file left: $(ls -a)"
# Without the limit both are written.
"$S" render flake_uvless.toml -o out.exr --size 320x200 --spp 2 --float --layers --threads 2 -q \
    --plugin-path "$PLUGINS" || fail "the render without a limit failed"
[ "$(head -c 4 out.png | tail -c 3)" = "PNG" ] || fail "no new PNG"
echo ok
